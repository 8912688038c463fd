"""Shared fixtures of the python test tier: where the built tools live; a small labelled
dataset, written once per run for the tests that read it (test_dataset, test_baselines,
test_leaderboard)."""
import os
import subprocess
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# pd_campaign is imported as the workspace installs it (devel or install space: source its
# setup.bash), never from src/. The tests' shared helpers (test/) and the developer scripts some
# tests check (scripts/dev/) are no package: on the path here, once for every test file.
sys.path[:0] = [os.path.join(ROOT, 'test'), os.path.join(ROOT, 'scripts', 'dev')]


@pytest.fixture(scope='session')
def bin_dir():
    path = os.environ.get('PEDICLE_DRILLING_BIN_DIR',
                          os.path.join(ROOT, 'catkin_ws', 'devel', 'lib', 'pedicle_drilling'))
    assert os.path.isdir(path), 'build the workspace first (make build): %s' % path
    return path


@pytest.fixture(scope='session')
def small_dataset(tmp_path_factory):
    """`campaign_dataset` at 12000 rpm: 4 calibration trials per case (train 9, validation 3)
    and 1 evaluation trial per case (test 3). Read it, never write into it."""
    out = tmp_path_factory.mktemp('small_dataset')
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign_dataset', '--out', str(out), '--trials', '4',
         '--test-trials', '1', '--rpm', '12000', '--jobs', '2'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    return out
