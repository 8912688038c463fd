#!/usr/bin/python3
"""Scenario: the Simulator drills a stationary specimen through its ROS interfaces only.

Moves the arm from home to the drilling pose (config/drilling_pose.yaml) through
arm_controller/command, runs the spindle at 12000 rpm, feeds at 0.5 mm/s with the feed joint and
checks, from the ft_sensor/wrench stream (at the declared DAQ rate) averaged over 50 samples (paper Sec. V-E), that
the outer and inner cortical peaks fall in the calibrated ranges (calibration.md: outer 2.5-4.0 N,
inner 2.2-3.8 N) with a lower cancellous level between them, and that simulator/ground_truth
reports the depth reached."""
import math
import os
import sys
import threading
import unittest

import rospkg

import rospy
import rostest
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from pedicle_drilling.msg import GroundTruth
from pedicle_drilling.srv import ResetSimulation

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path('pedicle_drilling'), 'test'))
from shipped_docs import declared_default  # noqa: E402

JOINTS = ['rsssii_joint%d' % i for i in range(1, 7)] + ['feed_joint']
DRILLING_POSE = [0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0, 0.0]  # config/drilling_pose.yaml
SEED = 3
FEED_RATE = 0.5e-3  # m/s


class StationaryDrillingTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.wrenches = []
        self.truth = []
        self.joints = None
        rospy.Subscriber('/ft_sensor/wrench', WrenchStamped, self.on_wrench, queue_size=100000,
                         tcp_nodelay=True)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.on_truth, queue_size=10000)
        rospy.Subscriber('/joint_states', JointState, self.on_joints, queue_size=10)
        # One stream per controller, as the simulator's default layout (and a lab) takes them.
        self.command = rospy.Publisher('/arm_controller/command', JointTrajectory, queue_size=10,
                                       latch=True)
        self.feed_command = rospy.Publisher('/feed_controller/command', JointTrajectory,
                                            queue_size=10, latch=True)
        self.spindle = rospy.Publisher('/spindle/command', Float64, queue_size=10, latch=True)

    def on_wrench(self, msg):
        with self.lock:
            self.wrenches.append((msg.header.stamp.to_sec(), msg.wrench.force.z))

    def on_truth(self, msg):
        with self.lock:
            self.truth.append(msg)

    def on_joints(self, msg):
        with self.lock:
            self.joints = dict(zip(msg.name, msg.position))

    def send(self, names, points):
        """Each controller gets the columns of its own joints (arm: 6, feed: feed_joint)."""
        for publisher, own in ((self.command, JOINTS[:6]), (self.feed_command, ['feed_joint'])):
            columns = [i for i, name in enumerate(names) if name in own]
            if not columns:
                continue
            traj = JointTrajectory()
            traj.joint_names = [names[i] for i in columns]
            for t, q in points:
                p = JointTrajectoryPoint()
                p.positions = [q[i] for i in columns]
                p.time_from_start = rospy.Duration(t)
                traj.points.append(p)
            publisher.publish(traj)

    def latest_truth(self):
        with self.lock:
            return self.truth[-1] if self.truth else None

    def test_two_cortical_peaks_and_ground_truth_depth(self):
        rospy.wait_for_service('/simulator/reset', timeout=30.0)
        reset = rospy.ServiceProxy('/simulator/reset', ResetSimulation)
        res = reset(seed=SEED, moving_bone=False)
        self.assertTrue(res.success, res.message)
        bone = (res.outer_cortical_thickness_m + res.cancellous_thickness_m +
                res.inner_cortical_thickness_m)
        self.assertGreater(bone, 3e-3)

        # Home -> drilling pose in 2 s through the trajectory interface.
        self.send(JOINTS, [(2.0, DRILLING_POSE)])
        rospy.sleep(3.0)
        with self.lock:
            joints = dict(self.joints)
        for name, q in zip(JOINTS, DRILLING_POSE):
            self.assertAlmostEqual(joints[name], q, delta=2e-3, msg=name)
        truth = self.latest_truth()
        gap = -truth.tip_depth_m
        self.assertAlmostEqual(gap, 5e-3, delta=0.2e-3)  # 5 mm above the bone (drilling pose)
        self.assertEqual(truth.specimen_layer, 'air')

        self.spindle.publish(Float64(12000.0 * math.pi / 30.0))  # rad/s (REP 103)
        rospy.sleep(0.5)
        # Approach to 1 mm above the bone in 1 s, then 0.5 mm/s until 1 mm past the canal wall.
        approach = gap - 1e-3
        end = gap + bone + 1e-3
        drill_time = (end - approach) / FEED_RATE
        with self.lock:
            self.wrenches = []
        t_start = rospy.Time.now()
        self.send(['feed_joint'], [(1.0, [approach]), (1.0 + drill_time, [end])])
        rospy.sleep(1.0 + drill_time + 0.5)
        with self.lock:
            samples = sorted(self.wrenches)
            truths = list(self.truth)
        span = samples[-1][0] - samples[0][0]
        rate = declared_default('pedicle_drilling/Simulator', 'force_sensor_rate_hz')
        self.assertGreater(len(samples), 0.95 * span * rate,
                           'wrench stream not at %.1f Hz: %d samples over %.2f s'
                           % (rate, len(samples), span))
        self.assertLess(len(samples), 1.05 * span * rate + 1)

        # Layer at each ground-truth time, to label the 50-sample blocks.
        truths = [g for g in truths if g.header.stamp >= t_start]
        self.assertTrue(truths)
        means = {'outer_cortical': [], 'cancellous': [], 'inner_cortical': []}
        gi = 0
        for b in range(0, len(samples) - 49, 50):
            block = samples[b:b + 50]
            t_end = block[-1][0]
            while gi + 1 < len(truths) and truths[gi + 1].header.stamp.to_sec() <= t_end:
                gi += 1
            layer = truths[gi].specimen_layer
            if layer in means:
                means[layer].append(sum(f for _, f in block) / 50.0)
        outer = max(means['outer_cortical'])
        inner = max(means['inner_cortical'])
        canc = means['cancellous']
        canc_level = sorted(canc)[len(canc) // 2]
        rospy.loginfo('outer peak %.3f N, inner peak %.3f N, cancellous median %.3f N',
                      outer, inner, canc_level)
        self.assertGreaterEqual(outer, 2.5)
        self.assertLessEqual(outer, 4.0)
        self.assertGreaterEqual(inner, 2.2)
        self.assertLessEqual(inner, 3.8)
        self.assertLess(canc_level, 0.6 * min(outer, inner))

        final = self.latest_truth()
        self.assertTrue(final.breakthrough)
        self.assertEqual(final.specimen_layer, 'canal')
        self.assertAlmostEqual(final.max_depth_cut_m, end - gap, delta=0.1e-3)
        self.assertAlmostEqual(final.inner_cortical_end_m, bone, delta=1e-9)
        self.assertEqual(final.residual_inner_cortical_m, 0.0)


if __name__ == '__main__':
    rospy.init_node('test_simulator_stationary_drilling')
    rostest.rosrun('pedicle_drilling', 'simulator_stationary_drilling', StationaryDrillingTest,
                   sys.argv)
