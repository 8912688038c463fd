#!/usr/bin/python3
"""The parameter walk: every parameter of every nodelet, as the node reference's parameter
tables (doc/nodes.md) declare it, given a value of the wrong type and a value out of range (and a required one
left out): the nodelet, started standalone with the parameters of its shipped launch file plus
that one bad value, must refuse to start (exit non-zero) with an error naming the parameter.

The parameters come from doc/nodes.md (one table per node, `| `~name` | type | default | range |`),
so a parameter documented there and not checked by the code, or renamed in one place only, fails
here; the nodes' good parameters come from roslaunch's own loader reading the shipped launch
files. A few parameters accept any value of their type by design; they are listed in
NOT_RANGED with the reason."""
import concurrent.futures
import os
import subprocess
import sys
import threading
import unittest

import rospkg
import rospy
import rostest
from roslaunch.config import ROSLaunchConfig
from roslaunch.xmlloader import XmlLoader

ROOT = rospkg.RosPack().get_path('pedicle_drilling')
sys.path.insert(0, os.path.join(ROOT, 'test'))
from shipped_docs import NODE_REFERENCE, parameter_tables  # noqa: E402

# node type -> (launch file, node name in it, extra launch args)
NODES = {
    'pedicle_drilling/Ventilator': ('ventilator.launch', 'ventilator', []),
    'pedicle_drilling/Simulator': ('simulator.launch', 'simulator', []),
    'pedicle_drilling/MotionIdentification': ('motion_identification.launch',
                                              'motion_identification', []),
    'pedicle_drilling/StateRecognizer': ('recognizer.launch', 'state_recognizer', []),
    'pedicle_drilling/SafetyMonitor': ('safety_monitor.launch', 'safety_monitor', []),
    'pedicle_drilling/CompensationPlanner': ('compensation_planner.launch',
                                             'compensation_planner', []),
    'pedicle_drilling/FaultInjector': ('fault_injector.launch', 'fault_injector', []),
    'pedicle_drilling/TfPoseRelay': ('tf_pose_relay.launch', 'tf_pose_relay', []),
    'pedicle_drilling/ForceTare': ('force_tare.launch', 'force_tare', []),
    'pedicle_drilling/TrialAction': ('trial_action.launch', 'trial_action', []),
}

# Parameters whose every value of the right type is valid (no range to leave), with the reason.
NOT_RANGED = {
    'publish_clock': 'bool', 'moving_bone': 'bool', 'use_pose_topic': 'bool', 'denoise': 'bool',
    'normalize_feature': 'bool', 'compensate_si_lr': 'bool', 'denoise_tv': 'bool',
    'bone_motion_model_path': 'a path, read (and checked) at every reset, "" allowed',
    'patient_frame': '"" allowed (the tracker frame)',
    'output_path': 'any non-empty path; checked when the model is written',
    'patient_id': 'any non-empty text', 'frame_id': 'any non-empty text',
    'tracker_frame': 'any frame name', 'marker_frame': 'any frame name',
    'world_frame': 'any frame name', 'arm_base_link': 'checked against the URDF',
    'arm_tip_link': 'checked against the URDF', 'feed_joint': 'checked against the URDF',
    'monitor_status_name': 'any DiagnosticStatus name',
    'urdf_path': 'a path; a missing file is its own rostest (simulator_bad_urdf)',
    'patient_model_path': 'a path; a broken file is its own rostest (planner_bad_model_file)',
    'trial_start_services': 'any service names',
    'start_service': 'any service name (a missing one rejects each goal, naming it)',
    'target_from_plan': 'bool',
}
# Parameters not walked one by one here, with the reason.
SKIPPED = {
    'ventilator/*': 'the Ventilator\'s own keys, walked on the Ventilator',
    'trial_distribution/specimen/*': 'walked by simulator_bad_trial_distribution',
    'population/*': 'the population\'s distributions (core::PopulationParams), in the same '
                    'ParamTable as the walked ones; each range refused naming it in '
                    'test_patient_population (BadParametersNameTheField)',
    'drilling_pose/<joint>': 'required: walked by the missing-parameter case below',
}


def documented_parameters():
    """{node type: [(name, type, range text)]} from the node reference's parameter tables."""
    return parameter_tables(os.path.join(ROOT, NODE_REFERENCE))


def launch_params(launch, node_name):
    """The private parameters of `node_name` as the shipped launch file sets them."""
    config = ROSLaunchConfig()
    XmlLoader().load(os.path.join(ROOT, 'launch_scripts', launch), config, verbose=False)
    prefix = '/%s/' % node_name
    params = {}
    for key, param in config.params.items():
        if key.startswith(prefix):
            params[key[len(prefix):]] = param.value
    return params


def bad_values(kind, name):
    """[(description, value)]: a wrong type, and for numbers a value out of range."""
    kind = kind.lower()
    if kind in ('double', 'int', ''):
        values = [('wrong type', 'not_a_number')]
        if name not in NOT_RANGED:
            values.append(('out of range', -1e9 if kind != 'int' else -1000000000))
        return values
    if kind == 'bool':
        return [('wrong type', 'maybe')]
    if kind in ('string', 'string list'):
        return [('wrong type', 42)]
    if kind == 'mapping':
        return [('wrong type', 42)]
    if kind == 'integers':
        return [('wrong type', 'three'), ('out of range', [0])]
    raise AssertionError('documented type %r of %s is unknown to the walk' % (kind, name))


PARAM_LOCK = threading.Lock()  # rospy's master proxy is one xmlrpc client: one call at a time
# The nodelet program, found once (rosrun would look it up for every case).
NODELET = subprocess.run(['catkin_find', '--first-only', '--libexec', 'nodelet', 'nodelet'],
                         capture_output=True, text=True).stdout.strip() or 'nodelet'
WORKERS = 2  # cases run two at a time, each nodelet under a name (and parameters) of its own


def run_standalone(node_type, node_name, good, name, value):
    """Starts the nodelet standalone with the good parameters and one bad value, under
    `node_name`; returns (exit code or None if it kept running, output)."""
    ns = '/' + node_name
    with PARAM_LOCK:
        if rospy.has_param(ns):
            rospy.delete_param(ns)
        for key, v in good.items():
            rospy.set_param(ns + '/' + key, v)
        if value is None:
            if rospy.has_param(ns + '/' + name):
                rospy.delete_param(ns + '/' + name)
        else:
            rospy.set_param(ns + '/' + name, value)
    process = subprocess.Popen(
        [NODELET, 'standalone', node_type, '__name:=' + node_name],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output, _ = process.communicate(timeout=30)
        return process.returncode, output
    except subprocess.TimeoutExpired:
        process.kill()
        output, _ = process.communicate()
        return None, output


def check_case(node_type, node_name, good, name, what, value):
    """One case: '' when the nodelet refused to start naming the parameter, else the failure."""
    code, output = run_standalone(node_type, node_name, good, name, value)
    label = '%s ~%s %s (%r)' % (node_type, name, what, value)
    if code is None:
        return label + ': accepted, the nodelet kept running'
    if code == 0:
        return label + ': exited 0'
    if name.split('/')[-1] not in output:
        return label + ': the error does not name it:\n' + output[-600:]
    return ''


class ParameterWalkTest(unittest.TestCase):
    def test_every_documented_parameter_is_checked(self):
        tables = documented_parameters()
        self.assertEqual(sorted(tables), sorted(NODES), 'doc/nodes.md parameter tables vs NODES')
        failures, cases = [], []
        for node_type, rows in sorted(tables.items()):
            launch, node_name, _ = NODES[node_type]
            good = launch_params(launch, node_name)
            for name, kind, _ in rows:
                if name in SKIPPED or '*' in name or '<' in name:
                    self.assertIn(name, SKIPPED, 'a wildcard parameter without a reason')
                    continue
                for what, value in bad_values(kind, name):
                    cases.append((node_type, node_name, good, name, what, value))
        with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
            futures = [pool.submit(check_case, c[0], '%s_case%d' % (c[1], i), *c[2:])
                       for i, c in enumerate(cases)]
            failures = [f.result() for f in futures if f.result()]
        cases = len(cases)
        # Required parameters left out: the planner's drilling pose.
        launch, node_name, _ = NODES['pedicle_drilling/CompensationPlanner']
        good = launch_params(launch, node_name)
        missing = 'drilling_pose/rsssii_joint3'
        self.assertIn(missing, good)
        code, output = run_standalone('pedicle_drilling/CompensationPlanner', node_name, good,
                                      missing, None)
        cases += 1
        if code in (None, 0) or 'rsssii_joint3' not in output:
            failures.append('CompensationPlanner without ~%s: %r\n%s' % (missing, code,
                                                                          output[-600:]))
        sys.stdout.write('parameter walk: %d cases, %d failures\n' % (cases, len(failures)))
        self.assertEqual(failures, [], '\n'.join(failures))


if __name__ == '__main__':
    rospy.init_node('test_parameter_walk')
    rostest.rosrun('pedicle_drilling', 'parameter_walk', ParameterWalkTest, sys.argv)
