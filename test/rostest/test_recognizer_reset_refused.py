#!/usr/bin/python3
"""Scenario: nothing on the ROS graph switches the recognizer off while the drill is in bone.
The planner's start_trial resets the StateRecognizer (trial_start_services) and the trial starts;
while the status is `drilling`, /state_recognizer/reset answers success false naming the phase,
and the recognizer keeps its state: the trial ends with the recognizer's own stop, done, the
canal intact. Once the trial is done the reset works again."""
import sys
import threading
import unittest

import rospy
import rostest
from std_srvs.srv import Trigger

from pedicle_drilling.msg import GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial


class RecognizerResetRefusedTest(unittest.TestCase):
    def test_reset_is_refused_while_drilling(self):
        lock = threading.Lock()
        stops, status, truth = [], [], []

        def keep(store):
            def cb(msg):
                with lock:
                    store.append(msg)
            return cb

        rospy.Subscriber('/drill/stop', StopCommand, keep(stops), queue_size=100)
        rospy.Subscriber('/compensation/status', TrialStatus, keep(status), queue_size=100)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(truth), queue_size=1000)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        rospy.wait_for_service('/state_recognizer/reset', 60.0)
        reset = rospy.ServiceProxy('/state_recognizer/reset', Trigger)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, mode='stationary', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)  # its own reset of the recognizer worked
        refused = None
        while not rospy.is_shutdown():  # event: the drilling phase, then the trial's end
            with lock:
                phase = status[-1].phase_name if status else ''
            if phase == 'drilling' and refused is None:
                refused = reset()
            if phase in ('done', 'failed'):
                break
            rospy.sleep(0.05)
        self.assertIsNotNone(refused, 'no drilling phase seen')
        self.assertFalse(refused.success, refused.message)
        self.assertIn('reset refused', refused.message)
        self.assertIn('drilling', refused.message)
        with lock:
            names = [s.phase_name for s in status]
            sources = [s.source for s in stops]
            final = truth[-1] if truth else None
        self.assertEqual(names[-1], 'done', names)
        self.assertTrue(sources and sources[0].endswith('state_recognizer'), sources)
        self.assertIsNotNone(final)
        self.assertFalse(final.breakthrough)
        answer = reset()
        self.assertTrue(answer.success, answer.message)


if __name__ == '__main__':
    rospy.init_node('test_recognizer_reset_refused')
    rostest.rosrun('pedicle_drilling', 'recognizer_reset_refused', RecognizerResetRefusedTest,
                   sys.argv)
