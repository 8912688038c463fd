"""The tests import pd_campaign as the workspace installs it, as a user's code does, never from
src/: no test file edits sys.path (conftest.py puts test/ and scripts/dev/ on it once)."""
import glob
import os
import re
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def test_pd_campaign_comes_from_the_workspace_not_from_src():
    """In a fresh interpreter with the tests' path (this process may have imported it through a
    developer script, which puts src/ first for `make docs` on an unsourced shell)."""
    code = ('import sys; sys.path[:0] = %r; import pd_campaign; print(pd_campaign.__file__)'
            % [os.path.join(ROOT, 'test'), os.path.join(ROOT, 'scripts', 'dev')])
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    assert not os.path.realpath(result.stdout.strip()).startswith(
        os.path.realpath(os.path.join(ROOT, 'src')) + os.sep), result.stdout


def test_no_test_file_edits_the_import_path():
    offenders = []
    for path in glob.glob(os.path.join(ROOT, 'test', 'python', 'test_*.py')):
        with open(path) as handle:
            for number, line in enumerate(handle, 1):
                # A script run under an audit hook in a child interpreter is not this process.
                if re.search(r'sys\.path\.(insert|append)', line) and 'realpath(script)' not in line:
                    offenders.append('%s:%d' % (os.path.relpath(path, ROOT), number))
    assert not offenders, offenders
