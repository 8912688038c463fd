#!/usr/bin/python3
"""Scenario: the CompensationPlanner nodelet runs the compensator class its
~compensator names. With pedicle_drilling/TrackedMarkerCompensator (hold the last tracker
sample), the pose the planner predicts for the safety monitor at each tracker stamp is the
previous tracker sample, to rounding: a prediction made before the sample was heard. The paper's
compensator would predict the bone from the ventilator instead. The compensated trial must end
'done' (whatever stopped it) with the canal intact."""
import sys
import threading
import unittest

import rospy
import rostest

from geometry_msgs.msg import PoseStamped

from pedicle_drilling.msg import GroundTruth, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial


def position(msg):
    p = msg.pose.position
    return (p.x, p.y, p.z)


class CompensatorClassTest(unittest.TestCase):
    def test_tracked_marker_class_drives_the_planner(self):
        lock = threading.Lock()
        tracked, predicted, status, truth = [], [], [], []

        def keep(store):
            def cb(msg):
                with lock:
                    store.append(msg)
            return cb

        rospy.Subscriber('/tracker/marker_pose', PoseStamped, keep(tracked), queue_size=1000)
        rospy.Subscriber('/compensation/predicted_marker_pose', PoseStamped, keep(predicted),
                         queue_size=1000)
        rospy.Subscriber('/compensation/status', TrialStatus, keep(status), queue_size=100)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(truth), queue_size=1000)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        while not rospy.is_shutdown():
            with lock:
                if status and status[-1].phase_name in ('done', 'failed'):
                    break
            rospy.sleep(0.1)
        with lock:
            names = [s.phase_name for s in status]
            by_stamp = {m.header.stamp.to_nsec(): position(m) for m in tracked}
            stamps = sorted(by_stamp)
            predictions = list(predicted)
            final = truth[-1] if truth else None
        self.assertEqual(names[-1], 'done', names)
        self.assertGreater(len(predictions), 20)
        checked, moved = 0, 0
        for m in predictions:
            stamp = m.header.stamp.to_nsec()
            if stamp not in by_stamp:
                continue  # the subscriber missed that tracker sample
            i = stamps.index(stamp)
            if i == 0:
                continue
            previous = by_stamp[stamps[i - 1]]
            got = position(m)
            self.assertTrue(all(abs(a - b) < 1e-9 for a, b in zip(got, previous)),
                            'predicted %r at %d is not the previous sample %r' %
                            (got, stamp, previous))
            if max(abs(a - b) for a, b in zip(got, by_stamp[stamp])) > 1e-6:
                moved += 1
            checked += 1
        self.assertGreater(checked, 20)
        self.assertGreater(moved, checked // 2, 'the bone did not move between samples')
        self.assertIsNotNone(final)
        self.assertFalse(final.breakthrough)


if __name__ == '__main__':
    rospy.init_node('test_compensator_class')
    rostest.rosrun('pedicle_drilling', 'compensator_class', CompensatorClassTest, sys.argv)
