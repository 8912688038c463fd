"""Shared fixtures of the python test tier: where the built tools live."""
import os

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


@pytest.fixture(scope='session')
def bin_dir():
    path = os.environ.get('PEDICLE_DRILLING_BIN_DIR',
                          os.path.join(ROOT, 'catkin_ws', 'devel', 'lib', 'pedicle_drilling'))
    assert os.path.isdir(path), 'build the workspace first (make build): %s' % path
    return path
