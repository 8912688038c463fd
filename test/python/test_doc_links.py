"""Every relative link of the documentation resolves: in README.md and doc/**/*.md,
each `[text](target)` and `![alt](target)` that is not a web address (http, https, mailto) or an
anchor of the same page (`#...`) names a file or folder that exists relative to the markdown
file; and every anchor, of the same page or of another markdown file (`file.md#section`), names
a heading there, as GitHub makes a heading's anchor (lower case, punctuation dropped, spaces to
hyphens, `-1`, `-2` for repeats). Fenced code blocks and inline code are not links."""
import glob
import os
import re

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))

# [text](target) or ![alt](target), the text possibly over several lines (no nested brackets),
# an optional title after the target: [text](target "title").
LINK = re.compile(r'!?\[([^\[\]]*)\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
FENCE = re.compile(r'^\s*(```|~~~)')
INLINE_CODE = re.compile(r'`[^`\n]*`')


def markdown_files():
    files = [os.path.join(ROOT, 'README.md')]
    files += sorted(glob.glob(os.path.join(ROOT, 'doc', '**', '*.md'), recursive=True))
    return files


def prose(text):
    """The text without fenced code blocks and inline code (replaced by blanks, so that line
    numbers stay)."""
    lines, fenced = [], False
    for line in text.split('\n'):
        if FENCE.match(line):
            fenced = not fenced
            lines.append('')
        elif fenced:
            lines.append('')
        else:
            lines.append(INLINE_CODE.sub(lambda m: ' ' * len(m.group(0)), line))
    return '\n'.join(lines)


def links(text):
    """[(line number, target)] of every link in the prose of a markdown text."""
    body = prose(text)
    return [(body.count('\n', 0, m.start()) + 1, m.group(2)) for m in LINK.finditer(body)]


def is_local(target):
    return not re.match(r'^(https?:|mailto:|#)', target)


def broken_links(path):
    with open(path, encoding='utf-8') as handle:
        text = handle.read()
    base = os.path.dirname(path)
    broken = []
    for line, target in links(text):
        if not is_local(target):
            continue
        if target.startswith('/'):
            broken.append((line, target, 'absolute path'))
            continue
        name = target.split('#', 1)[0].split('?', 1)[0]
        if not os.path.exists(os.path.normpath(os.path.join(base, name))):
            broken.append((line, target, 'no such file'))
    return broken


def heading_anchor(heading):
    """The anchor GitHub gives a markdown heading's text."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def anchors(path):
    """The anchors of a markdown file's headings (outside fenced code)."""
    seen, found, fenced = {}, set(), False
    with open(path, encoding='utf-8') as handle:
        for line in handle:
            if FENCE.match(line):
                fenced = not fenced
                continue
            heading = None if fenced else re.match(r'^#{1,6}\s+(.*)', line)
            if heading:
                anchor = heading_anchor(heading.group(1))
                count = seen.get(anchor, 0)
                found.add(anchor if count == 0 else '%s-%d' % (anchor, count))
                seen[anchor] = count + 1
    return found


def broken_anchors(path):
    """[(line, target)] of the links of a markdown file whose anchor names no heading of the
    markdown file it points to."""
    with open(path, encoding='utf-8') as handle:
        text = handle.read()
    broken = []
    for line, target in links(text):
        if re.match(r'^(https?:|mailto:)', target) or '#' not in target:
            continue
        name, anchor = target.split('#', 1)
        page = os.path.normpath(os.path.join(os.path.dirname(path), name)) if name else path
        if page.endswith('.md') and os.path.isfile(page) and anchor not in anchors(page):
            broken.append((line, target))
    return broken


def test_every_anchor_names_a_heading():
    hits = ['%s:%d: %s' % (os.path.relpath(path, ROOT), line, target)
            for path in markdown_files() for line, target in broken_anchors(path)]
    assert not hits, 'anchors that name no heading:\n' + '\n'.join(hits)


def test_the_check_sees_a_broken_anchor(tmp_path):
    (tmp_path / 'other.md').write_text('# Other\n\n## The paper\'s bench (`make run`)\n## Same\n'
                                       '## Same\n```\n# not a heading\n```\n')
    page = tmp_path / 'page.md'
    page.write_text('# Page: one, two\n\n[a](#page-one-two) [b](other.md#the-papers-bench-make-run)'
                    ' [c](other.md#same-1) [d](#nowhere) [e](other.md#not-a-heading)'
                    ' [f](other.md#same-2) [web](https://example.org/#x)\n')
    assert broken_anchors(str(page)) == [(3, '#nowhere'), (3, 'other.md#not-a-heading'),
                                         (3, 'other.md#same-2')]


def test_every_relative_link_resolves():
    hits = []
    for path in markdown_files():
        for line, target, why in broken_links(path):
            hits.append('%s:%d: %s (%s)' % (os.path.relpath(path, ROOT), line, target, why))
    assert not hits, 'broken links:\n' + '\n'.join(hits)


def test_the_docs_link_to_each_other():
    """README links every page of doc/, and no page of doc/ is an orphan."""
    with open(os.path.join(ROOT, 'README.md'), encoding='utf-8') as handle:
        targets = {t.split('#', 1)[0] for _, t in links(handle.read())}
    pages = [os.path.relpath(p, ROOT) for p in markdown_files()[1:]]
    assert pages, 'no doc/*.md'
    assert [p for p in pages if p not in targets] == []


def test_the_check_sees_a_broken_link(tmp_path):
    """The checker catches what it is meant to (so that the test above can fail), and ignores
    web addresses, same-page anchors and code."""
    (tmp_path / 'images').mkdir()
    (tmp_path / 'images' / 'a.png').write_bytes(b'')
    (tmp_path / 'other.md').write_text('x')
    page = tmp_path / 'page.md'
    page.write_text('\n'.join([
        '[ok](other.md) [ok](other.md#part) ![ok, two\nlines](images/a.png)',
        '[web](https://example.org/x) [anchor](#here) `[code](missing.md)`',
        '```', '[fenced](missing_too.md)', '```',
        '[bad](missing.md#part)', '![bad](images/b.png)', '[abs](/etc/passwd)']))
    assert [(line, target) for line, target, _ in broken_links(str(page))] == [
        (7, 'missing.md#part'), (8, 'images/b.png'), (9, '/etc/passwd')]
