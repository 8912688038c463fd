"""Tier 3: every shipped launch, YAML, rviz and URDF file loads."""
import glob
import os
import subprocess
import xml.etree.ElementTree as ET

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from shipped_docs import required_launch_args  # noqa: E402


def files(pattern):
    found = sorted(glob.glob(os.path.join(ROOT, pattern), recursive=True))
    return [f for f in found if '/catkin_ws/' not in f]


@pytest.mark.parametrize('path', files('launch_scripts/*.launch') + files('test/rostest/*.test') +
                         files('test/rostest_gtest/*.test'))
def test_launch_file_parses_with_roslaunch(path):
    # `roslaunch --nodes` resolves every include, $(find) and arg and lists the nodes; an arg
    # without a default (replay.launch's bag) is given a placeholder.
    out = subprocess.run(['roslaunch', '--nodes', path] + required_launch_args(path),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr + out.stdout


@pytest.mark.parametrize('path', files('config/**/*.yaml') + files('test/config/*.yaml'))
def test_yaml_loads(path):
    with open(path) as handle:
        data = yaml.safe_load(handle)
    assert isinstance(data, dict) and data


@pytest.mark.parametrize('path', files('rviz/*.rviz'))
def test_rviz_config_loads(path):
    with open(path) as handle:
        data = yaml.safe_load(handle)
    manager = data['Visualization Manager']
    assert manager['Global Options']['Fixed Frame']
    for display in manager['Displays']:
        assert display['Class'] and display['Name']
    # Every display and panel class it names is declared by an rviz plugin (ours or rviz's own).
    # rviz's own panels are built into it, not plugins (rviz/visualization_frame.cpp).
    declared = rviz_classes() | {'rviz/Displays', 'rviz/Views', 'rviz/Selection',
                                 'rviz/Tool Properties', 'rviz/Time', 'rviz/Help'}
    named = [d['Class'] for d in manager['Displays']] + [p['Class'] for p in data['Panels']]
    missing = [c for c in named if c not in declared]
    assert not missing, '%s names undeclared rviz classes %s' % (path, missing)


def rviz_classes():
    """Every class name declared by the plugin XML files exported to rviz."""
    out = subprocess.run(['rospack', 'plugins', '--attrib=plugin', 'rviz'], capture_output=True,
                         text=True, timeout=60, check=True).stdout
    names = set()
    for line in out.splitlines():
        _, _, xml_path = line.partition(' ')
        for c in ET.parse(xml_path.strip()).getroot().iter('class'):
            names.add(c.get('name'))
    return names


@pytest.mark.parametrize('path', files('urdf/*.urdf'))
def test_urdf_is_wellformed_xml_with_links(path):
    root = ET.parse(path).getroot()
    assert root.tag == 'robot'
    assert root.findall('link')
    if subprocess.run(['which', 'check_urdf'], capture_output=True).returncode == 0:
        out = subprocess.run(['check_urdf', path], capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stdout + out.stderr


def test_the_hardware_urdf_is_the_workcell_without_the_trackers_frames():
    """urdf/workcell_hardware.urdf is what scripts/dev/make_hardware_urdf.py writes from
    workcell.urdf today (the two cannot drift apart), and it has every link of the workcell but
    the tracker's two, which a lab's tracker driver and registration publish."""
    from make_hardware_urdf import hardware_urdf  # noqa: E402
    with open(os.path.join(ROOT, 'urdf', 'workcell.urdf')) as handle:
        workcell = handle.read()
    with open(os.path.join(ROOT, 'urdf', 'workcell_hardware.urdf')) as handle:
        shipped = handle.read()
    assert shipped == hardware_urdf(workcell), 'run scripts/dev/make_hardware_urdf.py'

    def links(text):
        return {link.get('name') for link in ET.fromstring(text).findall('link')}
    assert links(workcell) - links(shipped) == {'tracker_marker', 'tracker_camera'}
    assert links(shipped) < links(workcell)


def test_nodelet_plugins_declared_and_exported():
    tree = ET.parse(os.path.join(ROOT, 'nodelet_plugins.xml'))
    names = [c.get('name') for c in tree.getroot().iter('class')]
    assert names and all(n.startswith('pedicle_drilling/') for n in names)
    package = ET.parse(os.path.join(ROOT, 'package.xml')).getroot()
    assert package.find('export/nodelet').get('plugin') == '${prefix}/nodelet_plugins.xml'


def test_make_test_runs_every_rostest_folder():
    """Every folder of .test files is one of the rostest runner's folders: the C++-node
    scenarios of test/rostest_gtest (the lockstep participant's own scenario among them) are
    run by `make test`, not only built."""
    import run_rostests
    folders = {os.path.relpath(os.path.dirname(f), ROOT) for f in files('test/**/*.test')}
    assert folders, 'no .test file found'
    for folder in sorted(folders):
        assert folder in run_rostests.SCENARIO_FOLDERS, folder
    with open(os.path.join(ROOT, 'scripts', 'dev', 'run_tests.sh')) as handle:
        assert 'run_rostests.py' in handle.read()


# control_msgs/JointTrajectoryControllerState's md5sum in ROS Noetic (Header header,
# string[] joint_names, trajectory_msgs/JointTrajectoryPoint desired, actual, error).
CONTROL_MSGS_STATE_MD5 = '10817c60c2486ef6b33e97dcd87f4474'


def test_controller_state_is_wire_compatible_with_control_msgs():
    """doc/hardware.md, "The arm and the feed axis": a ros_control controller's control_msgs state connects to the
    planner's <name>/state subscription directly (ROS 1 matches a connection by md5sum), which
    holds only while our message keeps control_msgs' fields."""
    out = subprocess.run(['rosmsg', 'md5', 'pedicle_drilling/JointTrajectoryControllerState'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == CONTROL_MSGS_STATE_MD5


# control_msgs' md5sums in ROS Noetic (control_msgs 1.5: FollowJointTrajectory.action with
# path_tolerance, goal_tolerance, goal_time_tolerance and the result's error_string;
# JointTolerance without effort), as its generated messages publish them.
CONTROL_MSGS_FOLLOW_JOINT_TRAJECTORY_MD5 = {
    'JointTolerance': 'f544fe9c16cf04547e135dd6063ff5be',
    'FollowJointTrajectoryAction': 'bc4f9b743838566551c0390c65f1a248',
    'FollowJointTrajectoryGoal': '69636787b6ecbde4d61d711979bc7ecb',
    'FollowJointTrajectoryActionGoal': 'cff5c1d533bf2f82dd0138d57f4304bb',
    'FollowJointTrajectoryResult': '493383b18409bfb604b4e26c676401d2',
    'FollowJointTrajectoryActionResult': 'c4fb3b000dc9da4fd99699380efcc5d9',
    'FollowJointTrajectoryFeedback': '10817c60c2486ef6b33e97dcd87f4474',
    'FollowJointTrajectoryActionFeedback': 'd8920dc4eae9fc107e00999cce4be641',
}


def test_follow_joint_trajectory_is_wire_compatible_with_control_msgs():
    """doc/hardware.md, "The arm and the feed axis": the planner's goals (~trajectory_interface
    action) reach a ros_control controller's control_msgs follow_joint_trajectory action server
    directly (ROS 1 matches a connection by md5sum): every message of the action (goal, result,
    feedback, their action wrappers) and JointTolerance keep control_msgs' fields."""
    for name, md5 in sorted(CONTROL_MSGS_FOLLOW_JOINT_TRAJECTORY_MD5.items()):
        out = subprocess.run(['rosmsg', 'md5', 'pedicle_drilling/' + name],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip() == md5, name


def test_wall_clock_scenarios_run_alone_after_the_others():
    """run_rostests.Scenarios: lockstep scenarios go to free lanes first; a wall-clock one
    starts only when no other scenario runs, and none starts beside it."""
    import threading
    import run_rostests
    jobs = run_rostests.Scenarios(['wall_a', 'wall_b'], ['step_a', 'step_b'])
    assert jobs.take() == ('step_a', False)
    assert jobs.take() == ('step_b', False)
    jobs.done(False)
    taken = []
    lane = threading.Thread(target=lambda: taken.append(jobs.take()))
    lane.start()
    lane.join(timeout=0.5)
    assert lane.is_alive() and not taken, 'a wall-clock scenario started beside step_b'
    jobs.done(False)
    lane.join(timeout=60.0)
    assert taken == [('wall_a', True)]
    waiting = threading.Thread(target=lambda: taken.append(jobs.take()))
    waiting.start()
    waiting.join(timeout=0.5)
    assert waiting.is_alive(), 'wall_b started beside wall_a'
    jobs.done(True)
    waiting.join(timeout=60.0)
    assert taken[-1] == ('wall_b', True)
    jobs.done(True)
    assert jobs.take() is None
