"""The documents' generated blocks against the archived results (doc/results/): every table
between `<!-- generated: NAME -->` and `<!-- end generated -->` is what scripts/dev/make_docs.py
makes of the archive, so a number changed by hand, or data archived without `make docs`, fails
here."""
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'scripts', 'dev'))

import make_docs  # noqa: E402


def test_every_generated_block_is_the_archived_data():
    assert make_docs.main(['--check']) == 0


def test_every_block_is_used_and_known():
    used = set()
    for document in make_docs.DOCUMENTS:
        with open(os.path.join(ROOT, document)) as handle:
            used |= {m.group(2) for m in make_docs.BLOCK.finditer(handle.read())}
    assert used == set(make_docs.BLOCKS)


def test_a_number_changed_by_hand_is_rebuilt_from_the_archive():
    with open(os.path.join(ROOT, 'README.md')) as handle:
        text = handle.read()
    block = next(m for m in make_docs.BLOCK.finditer(text) if m.group(2) == 'adaptive')
    tampered = text.replace(block.group(3), block.group(3).replace('| 198 / 58 |', '| 199 / 58 |'))
    assert tampered != text
    rebuilt, names = make_docs.regenerate(tampered, make_docs.ARCHIVE)
    assert rebuilt == text
    assert 'adaptive' in names
