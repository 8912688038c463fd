"""The package is catkin_lint clean at the default warning level (errors and warnings)."""
import os
import subprocess

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def test_catkin_lint_clean():
    package = os.path.join(ROOT, 'catkin_ws', 'src', 'pedicle_drilling')
    out = subprocess.run(['catkin_lint', '-W1', package], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert 'found 0 problems' in out.stdout + out.stderr, out.stdout + out.stderr
