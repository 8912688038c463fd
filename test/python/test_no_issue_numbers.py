"""No work-item or session numbers in the tree: documents and comments describe the current state
and name a capability or a document section, never the work item that brought it (the word
"issue" or "issues", in any case, before a number, with or without "#") nor the working session
a measurement was made in (the word "session" or "sessions", in any case, before a number): a
reader has neither. A measurement carries its date instead. The history is CHANGELOG.md's, and
it has none either (it is checked like every other file). A citation of another project's issue
tracker is a source and stays: the line names that project (CITATION below).
scripts/dev/commit-msg applies the work-item rule to commit messages."""
import os
import re
import subprocess

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# The word, singular or plural, in any case, then a number with or without "#"; also when a line
# break (and a comment leader) falls between the two.
REFERENCE = re.compile(r'\bissues?(?:[ \t]+|[ \t]*\n[ \t]*(?:#+|//+|\*|;+)?[ \t]*)#?\d',
                       re.IGNORECASE)
# The word "session", singular or plural, in any case, then a number with or without "#"; also
# across a line break and a comment leader, as above. No citation is exempt.
SESSION = re.compile(r'\bsessions?(?:[ \t]+|[ \t]*\n[ \t]*(?:#+|//+|\*|;+)?[ \t]*)#?\d',
                     re.IGNORECASE)
# A line that cites another project's tracker: a web address, owner/repository#N, or one of the
# projects the documents cite by name.
CITATION = re.compile(r'https?://|github\.com|[\w.-]+/[\w.-]+#\d|Universal_Robots|ros_comm|'
                      r'yaml-cpp')
# Files not checked (none: the whole tree is).
PENDING_CLEANUP = []


def tracked_files():
    out = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, check=True,
                         stdout=subprocess.PIPE).stdout.decode()
    return [f for f in out.split('\0') if f]


def references(text):
    """(line number, line) of every work-item reference in text that is not a citation."""
    lines = text.splitlines()
    found = []
    for match in REFERENCE.finditer(text):
        number = text.count('\n', 0, match.start()) + 1
        line = lines[number - 1]
        if not CITATION.search(line):
            found.append((number, line))
    return found


def session_references(text):
    """(line number, line) of every session number in text."""
    lines = text.splitlines()
    return [(text.count('\n', 0, m.start()) + 1, lines[text.count('\n', 0, m.start())])
            for m in SESSION.finditer(text)]


def text_of(name):
    """The tracked file's text, or None for a link, a folder or a binary file."""
    path = os.path.join(ROOT, name)
    if not os.path.isfile(path) or os.path.islink(path):
        return None
    with open(path, 'rb') as handle:
        data = handle.read()
    if b'\0' in data:
        return None  # binary (images, fuzz corpora)
    return data.decode('utf-8', 'replace')


def test_no_work_item_number_in_the_tree():
    hits = []
    for name in tracked_files():
        if name in PENDING_CLEANUP:
            continue
        text = text_of(name)
        if text is None:
            continue
        for number, line in references(text):
            hits.append('%s:%d: %s' % (name, number, line.strip()[:120]))
    assert not hits, ('work-item numbers (name the capability or the document section '
                      'instead):\n' + '\n'.join(hits))


def test_no_session_number_in_the_tree():
    """Every tracked file, CHANGELOG.md included: a measurement names its date, not the session
    it was made in."""
    hits = []
    for name in tracked_files():
        text = text_of(name)
        if text is None:
            continue
        for number, line in session_references(text):
            hits.append('%s:%d: %s' % (name, number, line.strip()[:120]))
    assert not hits, ('session numbers (give the date of the run instead):\n' + '\n'.join(hits))


def test_pending_cleanup_names_tracked_files():
    """Every entry of PENDING_CLEANUP is a tracked file (a renamed or deleted one leaves it)."""
    tracked = set(tracked_files())
    gone = [name for name in PENDING_CLEANUP if name not in tracked]
    assert not gone, 'not tracked, remove from PENDING_CLEANUP: %s' % ', '.join(gone)


def test_the_check_sees_a_planted_reference():
    """The pattern catches what it is meant to (so that the test above can fail), and lets a
    citation of another project through. The examples are built here so that this file itself
    holds none."""
    for form in ('issue %d', 'issues %d and 29', 'Issue %d', 'issue #%d', 'ISSUES %d'):
        text = '// The recognizer of each trial (%s): empty = the paper\'s.' % (form % 17)
        assert references(text) == [(1, text)], form
    wrapped = '# the run before issue\n# %d\'s fast retreat' % 27
    assert references(wrapped) == [(1, '# the run before issue')]
    for citation in ('(Universal_Robots_ROS2_Driver issue #%d)' % 1311,
                     'see https://github.com/ros/ros_comm/issues/%d' % 1832,
                     'a known bug (ros/ros_comm#%d, issue %d there)' % (1832, 1832),
                     'jbeder/yaml-cpp issue %d' % 1040):
        assert references(citation) == [], citation
    for clean in ('The recognizer of each trial: empty = the paper\'s.',
                  'tissue 3 mm deep', 'an issue with 2 threads', 'issues: none'):
        assert references(clean) == [], clean


def test_the_check_sees_a_planted_session_number():
    """The session pattern catches the word with a capital, the plural, "#" and a number carried
    over a comment's line break ("session", then "# 5" on the next line), and lets a session
    without a number through. The examples are built
    here so that this file itself holds none."""
    for form in ('Session %d', 'session %d', 'sessions %d and 5', 'SESSION #%d', 'session\t%d'):
        text = '(measured in %s, one run, 2 cores)' % (form % 4)
        assert session_references(text) == [(1, text)], form
    for leader in ('#', '//', '*', ';', ''):
        wrapped = 'the run of the session\n%s %d, 2 cores' % (leader, 5)
        assert session_references(wrapped) == [(1, 'the run of the session')], leader
    for clean in ('one session, 2 cores', 'the session\'s machine is faster',
                  'a rosbag session: 3 topics', 'sessions: none', 'session4'):
        assert session_references(clean) == [], clean
