#!/usr/bin/python3
"""Scenario: bad commands to the Simulator are never integrated, and every body has a tf frame.

A JointTrajectory with a NaN position, one naming an unknown joint and a NaN spindle speed are
rejected with a warning; the arm keeps its position and the spindle stays off. A valid command
sent afterwards does move the arm (so the interface works). The tf tree holds world, the RSSSII
links, ft_sensor, drill_tip, spms_platform, bone, tracker_camera and tracker_marker."""
import math
import sys
import threading
import unittest

import rospy
import rostest
import tf2_ros
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from pedicle_drilling.msg import GroundTruth

FRAMES = ['rsssii_base'] + ['rsssii_link%d' % i for i in range(1, 7)] + [
    'ft_sensor', 'drill_tip', 'spms_platform', 'bone', 'tracker_camera', 'tracker_marker']


class NanCommandTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.joints = None
        self.warnings = []
        self.truth = None
        rospy.Subscriber('/joint_states', JointState, self.on_joints, queue_size=10)
        self.log_sub = rospy.Subscriber('/rosout', Log, self.on_log, queue_size=100)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.on_truth, queue_size=10)
        self.command = rospy.Publisher('/arm_controller/command', JointTrajectory, queue_size=10)
        self.spindle = rospy.Publisher('/spindle/command', Float64, queue_size=10)

    def on_joints(self, msg):
        with self.lock:
            self.joints = dict(zip(msg.name, msg.position))

    def on_log(self, msg):
        if msg.level >= Log.WARN:
            with self.lock:
                self.warnings.append(msg.msg)

    def on_truth(self, msg):
        with self.lock:
            self.truth = msg

    def wait_connected(self):
        deadline = rospy.Time.now() + rospy.Duration(20.0)
        while rospy.Time.now() < deadline and (
                self.command.get_num_connections() == 0 or
                self.spindle.get_num_connections() == 0 or
                self.log_sub.get_num_connections() == 0 or self.joints is None):
            rospy.sleep(0.1)
        self.assertIsNotNone(self.joints, 'no joint_states from the simulator')

    def trajectory(self, names, positions, t=1.0):
        traj = JointTrajectory()
        traj.joint_names = names
        p = JointTrajectoryPoint()
        p.positions = positions
        p.time_from_start = rospy.Duration(t)
        traj.points.append(p)
        return traj

    def snapshot(self):
        with self.lock:
            return dict(self.joints)

    def test_nan_and_unknown_commands_are_rejected(self):
        self.wait_connected()
        before = self.snapshot()
        self.command.publish(self.trajectory(['rsssii_joint2', 'feed_joint'],
                                             [float('nan'), 0.01]))
        rospy.sleep(1.5)  # warnings are throttled to one per second (sim time)
        self.command.publish(self.trajectory(['rsssii_joint2', 'no_such_joint'], [0.5, 0.01]))
        self.spindle.publish(Float64(float('nan')))
        rospy.sleep(2.0)
        after = self.snapshot()
        for name in ['rsssii_joint%d' % i for i in range(1, 7)] + ['feed_joint']:
            self.assertAlmostEqual(after[name], before[name], delta=1e-4, msg=name)
            self.assertTrue(math.isfinite(after[name]), name)
        self.assertAlmostEqual(after['spindle_joint'], before['spindle_joint'], delta=1e-3)
        with self.lock:
            warnings = list(self.warnings)
        self.assertTrue(any('rejected' in w and 'NaN' in w for w in warnings), warnings)
        self.assertTrue(any('no_such_joint' in w for w in warnings), warnings)
        self.assertTrue(any('spindle' in w and 'rejected' in w for w in warnings), warnings)

        # A valid command moves the feed joint (the interface is alive).
        self.command.publish(self.trajectory(['feed_joint'], [0.01], t=1.0))
        rospy.sleep(2.0)
        self.assertAlmostEqual(self.snapshot()['feed_joint'], 0.01, delta=0.2e-3)

    def test_tf_frames_present(self):
        buffer = tf2_ros.Buffer()
        tf2_ros.TransformListener(buffer)
        deadline = rospy.Time.now() + rospy.Duration(10.0)
        missing = FRAMES
        while rospy.Time.now() < deadline and missing:
            missing = [f for f in FRAMES
                       if not buffer.can_transform('world', f, rospy.Time(0))]
            rospy.sleep(0.2)
        self.assertEqual(missing, [], 'frames missing from tf: %r' % missing)
        # tf agrees with the ground truth: the bone frame is the bone's top surface.
        bone = buffer.lookup_transform('world', 'bone', rospy.Time(0))
        self.assertAlmostEqual(bone.transform.translation.x, 0.6, delta=1e-3)
        self.assertAlmostEqual(bone.transform.translation.z, 0.27103, delta=8e-3)


if __name__ == '__main__':
    rospy.init_node('test_simulator_nan_command')
    rostest.rosrun('pedicle_drilling', 'simulator_nan_command', NanCommandTest, sys.argv)
