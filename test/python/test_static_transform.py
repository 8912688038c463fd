"""scripts/static_transform.py (hardware.launch's tracker registration): its arguments and its
rotation, against the workcell URDF's nominal camera pose."""
import importlib.util
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SPEC = importlib.util.spec_from_file_location(
    'static_transform', os.path.join(ROOT, 'scripts', 'static_transform.py'))
static_transform = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(static_transform)


def rotation(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def rpy_matrix(roll, pitch, yaw):
    """URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def test_the_default_registration_is_the_urdfs_camera_pose():
    """hardware.launch's default `registration` is workcell.urdf's tracker_camera_joint."""
    launch = ET.parse(os.path.join(ROOT, 'launch_scripts', 'hardware.launch')).getroot()
    default = next(a.get('default') for a in launch.iter('arg') if a.get('name') == 'registration')
    values, parent, child = static_transform.parse(default.split() + ['world', 'tracker_camera'])
    urdf = ET.parse(os.path.join(ROOT, 'urdf', 'workcell.urdf')).getroot()
    joint = next(j for j in urdf.iter('joint') if j.get('name') == 'tracker_camera_joint')
    xyz = [float(v) for v in joint.find('origin').get('xyz').split()]
    roll, pitch, yaw = [float(v) for v in joint.find('origin').get('rpy').split()]
    assert values[:3] == xyz
    q = static_transform.quaternion(*values[3:])
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    assert np.allclose(rotation(q), rpy_matrix(roll, pitch, yaw), atol=1e-12)
    assert (parent, child) == ('world', 'tracker_camera')


@pytest.mark.parametrize('argv, named', [
    (['1', '2', '3', '0', '0', '0', 'world'], '8 arguments'),
    (['1', 'two', '3', '0', '0', '0', 'world', 'cam'], 'y'),
    (['1', '2', '3', 'nan', '0', '0', 'world', 'cam'], 'yaw'),
    (['1', '2', '3', '0', '0', 'inf', 'world', 'cam'], 'roll'),
    (['1', '2', '3', '0', '0', '0', 'world', 'world'], 'differ'),
    (['1', '2', '3', '0', '0', '0', '', 'cam'], 'non-empty'),
])
def test_bad_arguments_are_refused_naming_them(argv, named):
    with pytest.raises(ValueError) as error:
        static_transform.parse(argv)
    assert named in str(error.value)
