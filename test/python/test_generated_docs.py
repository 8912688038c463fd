"""The documents' generated blocks against the archived results (doc/results/): every table
between `<!-- generated: NAME -->` and `<!-- end generated -->` is what scripts/dev/make_docs.py
makes of the archive, so a number changed by hand, or data archived without `make docs`, fails
here."""
import glob
import os
import shutil

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))

import make_docs  # noqa: E402


def test_every_generated_block_is_the_archived_data():
    assert make_docs.main(['--check']) == 0


def test_every_block_is_used_and_known():
    used = set()
    for document in make_docs.DOCUMENTS:
        with open(os.path.join(ROOT, document)) as handle:
            used |= {m.group(2) for m in make_docs.BLOCK.finditer(handle.read())}
    assert used == set(make_docs.BLOCKS)


def documents_with(name):
    """The documents that hold the generated block `name`."""
    found = []
    for document in make_docs.DOCUMENTS:
        with open(os.path.join(ROOT, document)) as handle:
            if any(m.group(2) == name for m in make_docs.BLOCK.finditer(handle.read())):
                found.append(document)
    return found


def test_every_block_is_in_one_document():
    """A block lives in one place; the README links to it."""
    for name in make_docs.BLOCKS:
        assert len(documents_with(name)) == 1, (name, documents_with(name))


def test_the_documents_include_every_page_of_doc():
    """A block moved to another page of doc/ is still checked and rebuilt."""
    pages = sorted(os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(ROOT, 'doc', '*.md')))
    assert set(pages) <= set(make_docs.DOCUMENTS)
    assert 'README.md' in make_docs.DOCUMENTS


def test_a_number_changed_by_hand_is_rebuilt_from_the_archive():
    document, = documents_with('adaptive')
    with open(os.path.join(ROOT, document)) as handle:
        text = handle.read()
    block = next(m for m in make_docs.BLOCK.finditer(text) if m.group(2) == 'adaptive')
    tampered = text.replace(block.group(3), block.group(3).replace('| 198 / 58 |', '| 199 / 58 |'))
    assert tampered != text
    rebuilt, names = make_docs.regenerate(tampered, make_docs.ARCHIVE)
    assert rebuilt == text
    assert 'adaptive' in names


def files_in(folder):
    return sorted(os.path.relpath(os.path.join(d, f), folder)
                  for d, _, names in os.walk(folder) for f in names)


def test_archiving_the_archive_gives_the_archive(tmp_path, monkeypatch):
    """doc/results/ is laid out as a make run output: archiving it again (the nested class
    folders, the summary-only fault campaign, the trimmed columns and stop reasons included)
    changes no file."""
    results = tmp_path / 'results'
    shutil.copytree(make_docs.ARCHIVE, str(results))
    target = tmp_path / 'archive'
    monkeypatch.setattr(make_docs, 'ARCHIVE', str(target))
    make_docs.archive_results(str(results))
    archived = files_in(make_docs.ARCHIVE)
    assert archived == files_in(str(target))
    assert any(path.startswith('depth_limit_faults' + os.sep) for path in archived)
    for path in archived:
        with open(os.path.join(make_docs.ARCHIVE, path), 'rb') as a, \
                open(os.path.join(str(target), path), 'rb') as b:
            assert a.read() == b.read(), path


def test_an_incomplete_output_is_not_archived(tmp_path, monkeypatch):
    results = tmp_path / 'results'
    shutil.copytree(make_docs.ARCHIVE, str(results))
    shutil.rmtree(str(results / 'depth_limit_amplitude'))
    monkeypatch.setattr(make_docs, 'ARCHIVE', str(tmp_path / 'archive'))
    with pytest.raises(SystemExit) as stop:
        make_docs.archive_results(str(results))
    assert 'depth_limit_amplitude' in str(stop.value)
    assert not (tmp_path / 'archive').exists()
