"""The package is catkin_lint clean at the default warning level (errors and warnings): as the
workspace builds it (catkin_ws/src/pedicle_drilling, whose folders are links that catkin_lint
does not walk) and at the repository root, where it also sees every file (an executable script
that is not installed, for one)."""
import os
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


@pytest.mark.parametrize('folder', ['catkin_ws/src/pedicle_drilling', '.'])
def test_catkin_lint_clean(folder):
    package = os.path.normpath(os.path.join(ROOT, folder))
    out = subprocess.run(['catkin_lint', '-W1', package], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert 'found 0 problems' in out.stdout + out.stderr, out.stdout + out.stderr
