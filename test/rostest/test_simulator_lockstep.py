#!/usr/bin/python3
"""Scenario: the simulator's lockstep and its hold at the trial's start.

A participant of this test answers simulator/step, then stops answering: sim time stands at the
unanswered step; after ~lockstep_timeout_s the simulator drops it (GroundTruth
lockstep_timeouts) and steps on. A reset with hold_at_trial_start holds sim time at the trial's
start (pre_trial_s after the reset, plus a breath phase drawn from the seed) until
simulator/resume."""
import sys
import time
import unittest

import rospy
import rostest
from std_srvs.srv import Trigger

from pedicle_drilling.srv import ResetSimulation
from simulator_events import StepParticipant


class LockstepTest(StepParticipant, unittest.TestCase):
    WAIT_BOUND_S = 60.0

    def setUp(self):
        self.participate('/test_participant')

    def test_lockstep_waits_drops_and_holds(self):
        self.join_lockstep()
        # Silent: sim time stands at the step we did not answer.
        with self.cond:
            self.answering = False
        time.sleep(0.3)  # the answers in transit arrive; then one step is left unanswered
        with self.cond:
            stalled = self.last_step.to_sec()
        time.sleep(1.0)  # 4 s of sim time at the real-time factor, were it not waiting
        with self.cond:
            self.assertEqual(self.last_step.to_sec(), stalled,
                             'sim time stepped past a step the participant did not answer')
        # After ~lockstep_timeout_s (3 s) the simulator drops us and steps on, counted.
        self.wait_for(lambda: self.last_step.to_sec() > stalled + 0.05, 'stepping on without us')
        self.wait_for(lambda: self.truth.header.stamp.to_sec() > stalled and
                      self.truth.lockstep_timeouts >= 1, 'the timeout counted')
        # The hold at the trial's start (we stay silent: dropped, we do not hold it up).
        rospy.wait_for_service('/simulator/reset', 10.0)
        reset = rospy.ServiceProxy('/simulator/reset', ResetSimulation)
        resume = rospy.ServiceProxy('/simulator/resume', Trigger)
        reply = reset(seed=7, moving_bone=True, hold_at_trial_start=True, pre_trial_s=0.5)
        self.assertTrue(reply.success, reply.message)
        start = reply.trial_start.to_sec()
        since_reset = start - reply.reset_time.to_sec()
        breath_s = 60.0 / reply.ventilator_rate_bpm
        self.assertGreaterEqual(since_reset, 0.5 - 1e-6)
        self.assertLessEqual(since_reset, 0.5 + breath_s + 1e-6)
        self.assertGreater(reply.reset_time.to_sec(), stalled, 'sim time went back at the reset')
        self.wait_for(lambda: self.clock is not None and self.clock >= start - 0.011,
                      'sim time at the trial start')
        time.sleep(1.0)  # 4 s of sim time, were it not held
        with self.cond:
            # The hold is the first step at or after the drawn start (1 ms steps).
            self.assertLessEqual(self.last_step.to_sec(), start + 0.001 + 1e-6,
                                 'sim time ran past the hold')
            self.assertGreaterEqual(self.last_step.to_sec(), start - 1e-6)
        answer = resume()
        self.assertTrue(answer.success, answer.message)
        self.wait_for(lambda: self.last_step.to_sec() > start + 0.1, 'sim time after resume')


if __name__ == '__main__':
    rospy.init_node('test_simulator_lockstep')
    rostest.rosrun('pedicle_drilling', 'simulator_lockstep', LockstepTest, sys.argv)
