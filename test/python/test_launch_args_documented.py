"""Every argument of every shipped launch file is documented where roslaunch shows it: a `doc=`
string on each `<arg>` (an `<arg>` with a `value=` is a constant of the file, not an argument, and
is left out), so that `roslaunch pedicle_drilling hardware.launch --ros-args` documents every
argument. The entry point a lab types by hand, hardware.launch, has no argument that roslaunch
lists as required (its rule: an empty default), and demo.launch none but what it needs."""
import glob
import os
import subprocess
import xml.etree.ElementTree as ET

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
LAUNCH_FILES = sorted(glob.glob(os.path.join(ROOT, 'launch_scripts', '*.launch')))


def undocumented(path):
    """The names of the arguments of a launch file without a non-empty doc string."""
    root = ET.parse(path).getroot()
    return [arg.get('name') for arg in root.iter('arg')
            if arg.get('value') is None and not (arg.get('doc') or '').strip()]


def test_there_are_launch_files():
    assert len(LAUNCH_FILES) >= 10, LAUNCH_FILES


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_every_argument_has_a_doc_string(path):
    missing = undocumented(path)
    assert missing == [], '%s: <arg> without doc=: %s' % (os.path.basename(path),
                                                         ', '.join(missing))


def test_the_check_names_an_undocumented_argument(tmp_path):
    path = tmp_path / 'x.launch'
    path.write_text('<launch><arg name="a" default="1" doc="A."/><arg name="b" default="2"/>'
                    '<arg name="c" value="3"/><arg name="d" doc=" "/></launch>')
    assert undocumented(str(path)) == ['b', 'd']


def ros_args(name):
    out = subprocess.run(['roslaunch', 'pedicle_drilling', name, '--ros-args'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr + out.stdout
    return out.stdout


def test_hardware_launch_ros_args_documents_every_argument():
    out = ros_args('hardware.launch')
    lines = out.splitlines()
    assert 'Optional Arguments:' in lines, out
    assert [line for line in lines if 'undocumented' in line] == [], out
    # roslaunch lists an argument with an empty default as required: none here.
    assert 'Required Arguments:' not in lines, out
    for name in ('ft_zero_service', 'planner_config', 'recognizer_config', 'monitor_config',
                 'thrust_axis', 'force_rate_hz', 'drilling_pose', 'tare_relay'):
        assert any(line.strip().startswith(name + ' (default') for line in lines), name


def test_demo_launch_requires_nothing():
    out = ros_args('demo.launch')
    assert 'Required Arguments:' not in out.splitlines(), out
    assert 'segment_profile (default "rest_to_rest")' in out, out
