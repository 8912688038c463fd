"""The README is the front door: at most 300 lines (what the project is, the two commands, the
picture, the headline results, where to go next; the reference lives in doc/), and it names the
commands a reader types, the one CI runs (`.ci/run`) among them."""
import os
import re

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
README = os.path.join(ROOT, 'README.md')
MAX_LINES = 300


def read(path):
    with open(path, encoding='utf-8') as handle:
        return handle.read()


def line_count(text):
    return len(text.splitlines())


def shell_commands(text):
    """The commands of a markdown text's ```sh blocks, each without its trailing comment."""
    commands = []
    for block in re.findall(r'^```sh\n(.*?)^```', text, re.S | re.M):
        for line in block.splitlines():
            command = line.split('#', 1)[0].strip()
            if command:
                commands.append(' '.join(command.split()))
    return commands


def make_commands(script):
    """The `make ...` lines of a shell script (comments left out)."""
    return [' '.join(line.split()) for line in script.splitlines()
            if line.strip().startswith('make ') or line.strip() == 'make']


def test_the_readme_is_at_most_300_lines():
    count = line_count(read(README))
    assert count <= MAX_LINES, 'README.md has %d lines, at most %d: move the detail to doc/' % (
        count, MAX_LINES)


def test_the_length_check_counts_lines():
    assert line_count('a\n' * MAX_LINES) == MAX_LINES
    assert line_count('a\n' * (MAX_LINES + 1)) > MAX_LINES


def test_the_readme_names_the_two_commands_and_the_fast_loop():
    assert {'make run', 'make test', 'make test-fast'} <= set(shell_commands(read(README)))


def test_ci_runs_the_readme_test_command():
    """.ci/run calls `make test`, the README's test command; a command CI runs that the README
    does not name, or a README without it, fails here."""
    ci = make_commands(read(os.path.join(ROOT, '.ci', 'run')))
    assert ci == ['make test'], ci
    assert set(ci) <= set(shell_commands(read(README)))


def test_the_commands_are_read_from_sh_blocks_only():
    text = 'make run\n```sh\nmake run   # builds\n  make  test\n```\n```\nmake bench\n```\n'
    assert shell_commands(text) == ['make run', 'make test']
    assert make_commands('#!/bin/bash\n# make lint\ncd x\nmake test\n') == ['make test']


def test_the_readme_shows_the_picture():
    assert '](doc/images/rviz_drilling.png)' in read(README)
