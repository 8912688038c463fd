"""Formatting: every C++ source and header of the tree (git ls-files) is as clang-format-14 with
the repository's .clang-format writes it. Fix with:
  git ls-files '*.cpp' '*.hpp' '*.h' | xargs clang-format-14 -i"""
import os
import shutil
import subprocess

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..')


def test_cpp_sources_follow_clang_format():
    tool = shutil.which('clang-format-14')
    assert tool, 'clang-format-14 not found (make deps installs it)'
    files = subprocess.run(['git', 'ls-files', '*.cpp', '*.hpp', '*.h'], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split()
    assert len(files) > 50, files
    bad = []
    for name in files:
        check = subprocess.run([tool, '--dry-run', '--Werror', name], cwd=ROOT,
                               capture_output=True, text=True)
        if check.returncode != 0:
            bad.append(name)
    assert bad == [], 'not formatted (clang-format-14 -i FILE): %s' % ' '.join(bad)
