"""No absolute path of one machine's checkout anywhere in the tree (code, tests, docs): resources
are found through the package (catkin_find, $(find pedicle_drilling), a path the build passes)."""
import os
import re
import subprocess

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# The checkout this runs in, and any checkout under the folders where checkouts live (work
# folders, home folders, root's home other than its ROS log folder).
PATTERNS = [re.escape(ROOT), r'/work/[A-Za-z0-9_.-]+', r'/home/[A-Za-z0-9_.-]+/',
            r'/root/(?!\.ros\b)']


def tracked_files():
    out = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, check=True,
                         stdout=subprocess.PIPE).stdout.decode()
    return [f for f in out.split('\0') if f]


def test_no_checkout_path_in_the_tree():
    pattern = re.compile('|'.join('(?:%s)' % p for p in PATTERNS))
    hits = []
    for name in tracked_files():
        if name == 'test/python/test_no_machine_paths.py':
            continue  # its patterns and planted examples
        path = os.path.join(ROOT, name)
        if not os.path.isfile(path) or os.path.islink(path):
            continue
        with open(path, 'rb') as handle:
            data = handle.read()
        if b'\0' in data:
            continue  # binary (images)
        for number, line in enumerate(data.decode('utf-8', 'replace').splitlines(), 1):
            if pattern.search(line):
                hits.append('%s:%d: %s' % (name, number, line.strip()[:120]))
    assert not hits, 'absolute paths of one machine:\n' + '\n'.join(hits)


def test_the_check_sees_a_planted_path(tmp_path):
    """The pattern catches what it is meant to (so that the test above can fail)."""
    pattern = re.compile('|'.join('(?:%s)' % p for p in PATTERNS))
    assert pattern.search('#define DIR "/work/checkout"')
    assert pattern.search('bin = "%s/catkin_ws/devel"' % ROOT)
    assert pattern.search('path: /home/alice/catkin_ws/src')
    assert not pattern.search('$(find pedicle_drilling)/config/simulator.yaml')
