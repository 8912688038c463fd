#!/usr/bin/python3
"""Scenario: an optical tracker on tf, relayed to tracker/marker_pose (TfPoseRelay).

The test is the tracker's driver: tracker_camera -> tracker_mount (static, 0.1 m along x) and
tracker_mount -> tracker_marker updates. Each update is relayed once at its own stamp, in
tracker_camera, with the two transforms composed; an update that repeats the last stamp and a
NaN update are not relayed (the next pose received is the next good update)."""
import math
import sys
import threading
import time
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseStamped, TransformStamped
from tf2_msgs.msg import TFMessage

WAIT_S = 20.0  # bound that only ends a broken run; the test waits on events


def transform(parent, child, stamp, x, y, z):
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x = x
    t.transform.translation.y = y
    t.transform.translation.z = z
    t.transform.rotation.w = 1.0
    return t


class TfPoseRelayTest(unittest.TestCase):
    def setUp(self):
        self.cond = threading.Condition()
        self.poses = []
        rospy.Subscriber('/tracker/marker_pose', PoseStamped, self.on_pose, queue_size=100)
        self.tf_pub = rospy.Publisher('/tf', TFMessage, queue_size=100)
        self.static = tf2_ros.StaticTransformBroadcaster()

    def on_pose(self, msg):
        with self.cond:
            self.poses.append(msg)
            self.cond.notify_all()

    def wait_for(self, predicate, what):
        deadline = time.monotonic() + WAIT_S
        with self.cond:
            while not predicate():
                left = deadline - time.monotonic()
                if left <= 0:
                    self.fail('%s: not reached (poses: %r)' % (
                        what, [p.header.stamp.to_sec() for p in self.poses]))
                self.cond.wait(min(left, 0.2))

    def send(self, stamp, z):
        self.tf_pub.publish(TFMessage([transform('tracker_mount', 'tracker_marker', stamp,
                                                 0.0, 0.02, z)]))

    def test_each_update_relayed_once_at_its_stamp(self):
        self.static.sendTransform(transform('tracker_camera', 'tracker_mount', rospy.Time(0),
                                            0.1, 0.0, 0.0))
        deadline = time.monotonic() + WAIT_S
        while self.tf_pub.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        self.assertGreater(self.tf_pub.get_num_connections(), 0, 'the relay does not listen')
        # Until the relay has the static transform (latched, on its own connection) an update
        # cannot be resolved: send updates with new stamps until one comes back, then wait for
        # the last one sent (the relay handles /tf in order).
        first = rospy.Time.now()
        while True:
            first = first + rospy.Duration(0.001)
            self.send(first, 0.30)
            with self.cond:
                self.cond.wait(0.2)
                if self.poses or time.monotonic() > deadline:
                    break
        self.wait_for(lambda: self.poses and self.poses[-1].header.stamp == first,
                      'the first pose')
        with self.cond:
            got = self.poses[-1]
        self.assertEqual(got.header.frame_id, 'tracker_camera')
        self.assertAlmostEqual(got.pose.position.x, 0.1, places=9)  # composed through the mount
        self.assertAlmostEqual(got.pose.position.y, 0.02, places=9)
        self.assertAlmostEqual(got.pose.position.z, 0.30, places=9)
        count = len(self.poses)
        stamps = [first + rospy.Duration(0.125 * k) for k in range(1, 5)]
        self.send(stamps[0], 0.31)  # relayed
        self.wait_for(lambda: len(self.poses) >= count + 1, 'the second pose')
        self.send(stamps[0], 0.32)  # the same stamp again: not relayed
        nan = transform('tracker_mount', 'tracker_marker', stamps[1], 0.0, 0.02, float('nan'))
        self.tf_pub.publish(TFMessage([nan]))  # not relayed
        self.send(stamps[2], 0.33)  # relayed: the next pose after the second must be this one
        self.wait_for(lambda: len(self.poses) >= count + 2, 'the pose after the skipped ones')
        with self.cond:
            second, third = self.poses[count], self.poses[count + 1]
        self.assertEqual(second.header.stamp, stamps[0])
        self.assertAlmostEqual(second.pose.position.z, 0.31, places=9)
        self.assertEqual(third.header.stamp, stamps[2])
        self.assertAlmostEqual(third.pose.position.z, 0.33, places=9)
        for pose in self.poses:
            self.assertTrue(all(math.isfinite(v) for v in (
                pose.pose.position.x, pose.pose.position.y, pose.pose.position.z)))


if __name__ == '__main__':
    rospy.init_node('test_tf_pose_relay')
    rostest.rosrun('pedicle_drilling', 'tf_pose_relay_from_tf', TfPoseRelayTest, sys.argv)
