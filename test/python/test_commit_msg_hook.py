"""scripts/dev/commit-msg, the hook `make hooks` installs: it passes a well-formed message and
refuses a subject longer than 72 characters, a body without the blank line before it and a
work-item number, naming the problem; git's comment lines and the part below `git commit -v`'s
scissors line are not the message. `make hooks` installs it where git runs it. The work-item
references are built here so that this file holds none (test_no_issue_numbers.py)."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
HOOK = os.path.join(ROOT, 'scripts', 'dev', 'commit-msg')
ITEM = 'issue %d'
SCISSORS = '# ------------------------ >8 ------------------------'

GOOD = {
    'subject only': 'Sequencer tests register the marker through one helper\n',
    'subject and body': 'Sequencer tests register the marker through one helper\n\n'
                        'The two depth-limit tests wrote the loop out again; registerAt\n'
                        'now serves all three.\n',
    'subject of 72 characters': 'x' * 72 + '\n',
    'comments and trailing blank lines': '# Please enter the commit message\n'
                                         'Docs name the capability\n\nWhy.\n\n\n'
                                         '# On branch main\n# (%s would be a comment)\n' % (
                                             ITEM % 17),
    'below the scissors line': 'Docs name the capability\n\nWhy.\n' + SCISSORS + '\n'
                               '# Do not modify or remove the line above.\n'
                               'diff --git a/x b/x\n+' + 'y' * 90 + ' (%s)\n' % (ITEM % 17),
    'a citation of another project': 'Cite the UR driver delay\n\n'
                                     'Universal_Robots_ROS2_Driver %s measured 35 ms;\n'
                                     'see also ros/ros_comm#%d.\n' % (ITEM % 1311, 1832),
    'windows line ends': 'Docs name the capability\r\n\r\nWhy.\r\n',
}

BAD = {
    'subject of 73 characters': ('x' * 73 + '\n', 'subject line has 73 characters'),
    'no blank line before the body': ('Docs name the capability\nWhy it matters.\n',
                                      'blank line'),
    'a reference in the subject': ('Fix the tare (%s)\n' % (ITEM % 30), 'work item'),
    'a reference in the body': ('Fix the tare\n\nAs Issues %d and 29 asked.\n' % 27, 'work item'),
    'a reference with a hash': ('Fix the tare\n\nCloses issue #%d.\n' % 31, 'work item'),
    'a reference across lines': ('Fix the tare\n\nThe run before issue\n%d.\n' % 27,
                                 'work item'),
}


def run_hook(tmp_path, message):
    path = tmp_path / 'COMMIT_EDITMSG'
    path.write_bytes(message.encode())
    return subprocess.run([HOOK, str(path)], capture_output=True, text=True, cwd=str(tmp_path))


def test_the_hook_is_executable():
    assert os.access(HOOK, os.X_OK), 'chmod +x scripts/dev/commit-msg'


@pytest.mark.parametrize('name', sorted(GOOD))
def test_a_good_message_passes(tmp_path, name):
    out = run_hook(tmp_path, GOOD[name])
    assert out.returncode == 0, out.stderr


@pytest.mark.parametrize('name', sorted(BAD))
def test_a_bad_message_is_refused_naming_the_problem(tmp_path, name):
    message, problem = BAD[name]
    out = run_hook(tmp_path, message)
    assert out.returncode == 1, out.stderr
    assert problem in out.stderr, out.stderr


def test_make_hooks_installs_the_hook_git_runs(tmp_path):
    """`make hooks` in a fresh repository with this Makefile: git then refuses a bad message
    and takes a good one."""
    if not shutil.which('make'):
        pytest.skip('make not installed')
    repo = tmp_path / 'repo'
    (repo / 'scripts' / 'dev').mkdir(parents=True)
    shutil.copy(os.path.join(ROOT, 'Makefile'), str(repo / 'Makefile'))
    shutil.copy(HOOK, str(repo / 'scripts' / 'dev' / 'commit-msg'))
    env = {k: v for k, v in os.environ.items() if not k.startswith('GIT_')}
    env.update(GIT_AUTHOR_NAME='t', GIT_AUTHOR_EMAIL='t@example.invalid',
               GIT_COMMITTER_NAME='t', GIT_COMMITTER_EMAIL='t@example.invalid',
               GIT_CONFIG_NOSYSTEM='1', HOME=str(tmp_path))

    def git(*args):
        return subprocess.run(['git'] + list(args), cwd=str(repo), env=env,
                              capture_output=True, text=True)

    assert git('init', '-q').returncode == 0
    out = subprocess.run(['make', 'hooks'], cwd=str(repo), env=env, capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    installed = repo / '.git' / 'hooks' / 'commit-msg'
    assert os.access(str(installed), os.X_OK)
    refused = git('commit', '-q', '--allow-empty', '-m', 'Fix the tare (%s)' % (ITEM % 30))
    assert refused.returncode != 0 and 'work item' in refused.stderr, refused.stderr
    taken = git('commit', '-q', '--allow-empty', '-m', 'Fix the tare', '-m', 'Why.')
    assert taken.returncode == 0, taken.stderr
