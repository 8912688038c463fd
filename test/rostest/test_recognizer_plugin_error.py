#!/usr/bin/python3
"""Scenario: the recognizer class throws mid-drill (test_plugins/ThrowInBone). The StateRecognizer
nodelet publishes one drill/stop whose reason names the class's error, its drilling_state says
`stopped`; the planner retreats and the trial ends done with the canal intact; the nodelet
manager still lists every nodelet, and the recognizer's ~reset clears the error once the trial
is over."""
import sys
import threading
import unittest

import rospy
import rostest
from nodelet.srv import NodeletList
from std_srvs.srv import Trigger

from pedicle_drilling.msg import DrillingState, GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial

ERROR = 'test plugin ThrowInBone: a bug after 300 samples in bone'
MANAGER = '/pedicle_drilling_manager'


class RecognizerPluginErrorTest(unittest.TestCase):
    def test_an_exception_of_the_class_is_a_stop_naming_it(self):
        lock = threading.Lock()
        stops, status, truth, states = [], [], [], []

        def keep(store):
            def cb(msg):
                with lock:
                    store.append(msg)
            return cb

        rospy.Subscriber('/drill/stop', StopCommand, keep(stops), queue_size=100)
        rospy.Subscriber('/compensation/status', TrialStatus, keep(status), queue_size=100)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(truth), queue_size=1000)
        rospy.Subscriber('/drilling_state', DrillingState, keep(states), queue_size=1000)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        before = rospy.ServiceProxy(MANAGER + '/list', NodeletList)().nodelets
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, mode='stationary', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        while not rospy.is_shutdown():  # event: the trial's end
            with lock:
                if status and status[-1].phase_name in ('done', 'failed'):
                    break
            rospy.sleep(0.1)
        with lock:
            names = [s.phase_name for s in status]
            reasons = [(s.source, s.reason) for s in stops]
            final = truth[-1] if truth else None
            stopped = [s for s in states if s.stop]
        self.assertEqual(names[-1], 'done', names)
        self.assertIn('retreating', names)
        recognizer_stops = [r for source, r in reasons if source.endswith('state_recognizer')]
        self.assertEqual(len(recognizer_stops), 1, reasons)
        self.assertIn('recognizer error', recognizer_stops[0])
        self.assertIn(ERROR, recognizer_stops[0])
        self.assertTrue(stopped and stopped[0].state_name == 'stopped')
        self.assertIsNotNone(final)
        self.assertFalse(final.breakthrough)
        # The manager and every nodelet in it are alive.
        after = rospy.ServiceProxy(MANAGER + '/list', NodeletList)().nodelets
        self.assertEqual(sorted(set(before) - set(after)), [])
        for name in ('/state_recognizer', '/compensation_planner'):
            self.assertIn(name, after)
        answer = rospy.ServiceProxy('/state_recognizer/reset', Trigger)()
        self.assertTrue(answer.success, answer.message)


if __name__ == '__main__':
    rospy.init_node('test_recognizer_plugin_error')
    rostest.rosrun('pedicle_drilling', 'recognizer_plugin_error', RecognizerPluginErrorTest,
                   sys.argv)
