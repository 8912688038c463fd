#!/usr/bin/python3
"""A virtual volunteer's rosbag played (sim time) into MotionIdentification: ~identify refuses
a file outside its ~model_folder and an empty window without writing, then recovers the volunteer's true AP/SI slopes within 5 % and
agrees with the identify CLI on the CSV of the same volunteer.

Private parameters: volunteer_id (int), cli_rel_tolerance (relative slope agreement with the
CLI, all three axes), expect_all_samples (bool: the node must have used every 8 Hz sample),
play_rate (rosbag play -r), denoise_tv (must match the node's ~denoise_tv).
"""
import os
import re
import shutil
import subprocess
import tempfile
import time
import unittest

import rospy
import rostest
import yaml

from pedicle_drilling.msg import MotionModel
from pedicle_drilling.srv import IdentifyMotion

SERVICE = '/motion_identification/identify'


def tool(name):
    bin_dir = os.environ.get('PEDICLE_DRILLING_BIN_DIR')
    if bin_dir and os.path.exists(os.path.join(bin_dir, name)):
        return [os.path.join(bin_dir, name)]
    return ['rosrun', 'pedicle_drilling', name]


def model_folder():
    """The nodelet's ~model_folder, or its default $ROS_HOME/pedicle_drilling/models."""
    folder = rospy.get_param('/motion_identification/model_folder', '')
    if folder:
        return folder
    ros_home = os.environ.get('ROS_HOME') or os.path.join(os.path.expanduser('~'), '.ros')
    return os.path.join(ros_home, 'pedicle_drilling', 'models')


def axes_of(model_yaml):
    with open(model_yaml) as f:
        return yaml.safe_load(f)['axes']


class MotionIdentificationFromBag(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_motion_identification_bag')
        cls.vid = int(rospy.get_param('~volunteer_id', 2))
        cls.cli_tol = float(rospy.get_param('~cli_rel_tolerance', 0.03))
        cls.expect_all = bool(rospy.get_param('~expect_all_samples', False))
        cls.rate = str(rospy.get_param('~play_rate', 4.0))
        cls.denoise_tv = bool(rospy.get_param('~denoise_tv', True))
        os.makedirs(model_folder(), exist_ok=True)
        cls.tmp = tempfile.mkdtemp(prefix='motion_id_bag_', dir=model_folder())  # written there
        out = subprocess.run(['/usr/bin/python3', os.path.join(
            os.path.dirname(os.path.realpath(__file__)), '..', '..', 'scripts',
            'volunteers_to_bag.py'), '--out', cls.tmp, '--ids', str(cls.vid)],
            capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stdout + out.stderr
        cls.stem = os.path.join(cls.tmp, 'volunteer_%d' % cls.vid)
        rospy.wait_for_service(SERVICE, timeout=30.0)
        cls.identify = rospy.ServiceProxy(SERVICE, IdentifyMotion)
        cls.latched = []
        rospy.Subscriber('/motion_model', MotionModel, cls.latched.append)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_bag_identification(self):
        # 0. A file outside ~model_folder (absolute, or by '..'): refused naming it, not written.
        outside = tempfile.mkdtemp(prefix='motion_id_outside_')
        try:
            for path in (os.path.join(outside, 'model.yaml'),
                         os.path.join(self.tmp, '..', '..', 'escape_%d.yaml' % os.getpid())):
                r = self.identify(model='', method='', output_path=path)
                self.assertFalse(r.success)
                self.assertIn('outside the model folder', r.message)
                self.assertIn(path, r.message)
                self.assertFalse(os.path.exists(path))
        finally:
            shutil.rmtree(outside, ignore_errors=True)
        # 1. Nothing recorded yet: refused with a message, nothing written, nothing published.
        early = os.path.join(self.tmp, 'early.yaml')
        r = self.identify(model='', method='', output_path=early)
        self.assertFalse(r.success)
        self.assertRegex(r.message, 'no tidal volume|too few marker samples')
        self.assertFalse(os.path.exists(early))
        self.assertEqual(os.listdir(self.tmp).count('early.yaml'), 0)
        time.sleep(0.5)
        self.assertEqual(self.latched, [])

        # 2. The CLI on the CSV of the same volunteer.
        cli_yaml = os.path.join(self.tmp, 'cli.yaml')
        cmd = tool('identify') + ['--input', self.stem + '.csv', '--output', cli_yaml]
        if self.denoise_tv:
            cmd.append('--denoise-tv')
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        self.assertEqual(out.returncode, 0, out.stderr)
        cli = axes_of(cli_yaml)
        truth = axes_of(self.stem + '_truth.yaml')

        # 3. Play the bag into the nodelet on sim time.
        play = subprocess.run(['rosbag', 'play', '--clock', '-q', '-d', '1', '-r', self.rate,
                               self.stem + '.bag'], capture_output=True, text=True, timeout=120)
        self.assertEqual(play.returncode, 0, play.stderr)
        time.sleep(0.5)

        node_yaml = os.path.join(self.tmp, 'node.yaml')
        r = self.identify(model='', method='', output_path=node_yaml)
        self.assertTrue(r.success, r.message)
        self.assertTrue(os.path.exists(node_yaml))
        leftovers = [f for f in os.listdir(self.tmp) if f.startswith('node.yaml') and
                     f != 'node.yaml']
        self.assertEqual(leftovers, [])
        n_marker = int(re.search(r'from (\d+) marker samples', r.message).group(1))
        breaths = int(re.search(r'(\d+) breaths', r.message).group(1))
        self.assertGreaterEqual(breaths, 2)
        if self.expect_all:
            self.assertEqual(n_marker, 240, r.message)
        else:
            self.assertGreaterEqual(n_marker, 220, r.message)

        # The response, the latched message and the file agree.
        deadline = time.time() + 5.0  # wall time: sim time stops with the bag
        while not self.latched and time.time() < deadline:
            time.sleep(0.1)
        self.assertEqual(len(self.latched), 1)
        msg = self.latched[0]
        self.assertEqual([a.axis for a in msg.axes], ['AP', 'SI', 'LR'])
        self.assertEqual(msg.yaml_path, node_yaml)
        node = axes_of(node_yaml)
        for a in msg.axes:
            self.assertAlmostEqual(a.q1_mm_per_ml, node[a.axis.lower()]['q1'], places=12)
            self.assertGreater(a.r2, 0.5)
            self.assertTrue(a.wavelet)
        # Equivalent disc stiffness from the slopes and Table I (Eq. 8, 9): AP
        # EI V0/(p0 b_w) = (5 m^4/24 + l m^3/6) / q1, SI E A V0/(2 p0 S L) = 1 / q1, with q1 in
        # mm/mm^3; the same value in the message and the file, none for LR.
        m, l = 0.5 * (5.31 + 5.67), 23.10
        expected = {'AP': (5 * m ** 4 / 24 + l * m ** 3 / 6), 'SI': 1.0, 'LR': None}
        for a in msg.axes:
            if expected[a.axis] is None:
                self.assertEqual(a.equivalent_stiffness, 0.0)
                self.assertNotIn('equivalent_stiffness', node[a.axis.lower()])
                continue
            self.assertAlmostEqual(a.equivalent_stiffness * a.q1_mm_per_ml / 1000.0,
                                   expected[a.axis], delta=1e-9 * expected[a.axis])
            self.assertAlmostEqual(node[a.axis.lower()]['equivalent_stiffness'],
                                   a.equivalent_stiffness, delta=1e-9 * a.equivalent_stiffness)

        for axis in ('ap', 'si'):
            q1, q1_true = node[axis]['q1'], truth[axis]['q1']
            self.assertLess(abs(q1 / q1_true - 1.0), 0.05,
                            '%s slope %.6g vs truth %.6g' % (axis, q1, q1_true))
        for axis in ('ap', 'si', 'lr'):
            q1, q1_cli = node[axis]['q1'], cli[axis]['q1']
            self.assertLess(abs(q1 / q1_cli - 1.0), self.cli_tol,
                            '%s slope node %.8g vs CLI %.8g' % (axis, q1, q1_cli))
        # Axis mapping: the bag puts the marker 1 m along +z (AP) of the tracker, so the node's
        # AP intercept is the CLI's + 1000 mm and SI / LR intercepts match the CLI's.
        self.assertAlmostEqual(node['ap']['q0'] - 1000.0, cli['ap']['q0'], delta=0.3)
        self.assertAlmostEqual(node['si']['q0'], cli['si']['q0'], delta=0.3)
        self.assertAlmostEqual(node['lr']['q0'], cli['lr']['q0'], delta=0.3)


if __name__ == '__main__':
    rostest.rosrun('pedicle_drilling', 'motion_identification_from_bag',
                   MotionIdentificationFromBag)
