#!/usr/bin/python3
"""The trial as the drill_trial action (trial_action.test): rejection with the planner's reason,
a compensated trial with feedback and result, one goal at a time, and a cancel that stops the
drill with retreat. Every wait is on an event (the action's state, a message), bounded only
against a broken run."""
import threading
import unittest

import actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus

from pedicle_drilling.msg import DrillTrialAction, DrillTrialGoal, StopCommand

BOUND_S = 150.0  # wall seconds: a broken run, not a schedule


def goal(mode='compensated'):
    return DrillTrialGoal(mode=mode, spindle_rpm=12000.0, feed_rate_mm_s=0.5, max_duration_s=60.0)


class TrialActionTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.stops = []
        rospy.Subscriber('/drill/stop', StopCommand, self.on_stop, queue_size=10)
        self.client = actionlib.SimpleActionClient('/drill_trial', DrillTrialAction)
        self.assertTrue(self.client.wait_for_server(rospy.Duration(60.0)), 'no drill_trial server')

    def on_stop(self, msg):
        with self.lock:
            self.stops.append(msg)

    def start(self, feedback_cb=None):
        """Sends a compensated goal until one is accepted: the planner refuses the moving modes
        until it knows the ventilator's breath phase (rejected goals, its reason each)."""
        for _ in range(100):
            self.client.send_goal(goal(), feedback_cb=feedback_cb)
            self.client.wait_for_result(rospy.Duration(0.5))
            if self.client.get_state() != GoalStatus.REJECTED:
                return
            rospy.sleep(0.2)
        self.fail('every goal rejected: %s' % self.client.get_goal_status_text())

    def test_trial_as_action(self):
        # A request the planner refuses: rejected, naming what is wrong.
        self.client.send_goal(goal(mode='sideways'))
        self.assertTrue(self.client.wait_for_result(rospy.Duration(BOUND_S)))
        self.assertEqual(self.client.get_state(), GoalStatus.REJECTED)
        self.assertIn('mode', self.client.get_result().message)

        # A compensated trial: feedback of its phases, succeeded once the drill is retracted.
        phases = []
        self.start(lambda f: phases.append(f.phase_name))
        # One goal at a time: a second client's goal is rejected while this one runs.
        other = actionlib.SimpleActionClient('/drill_trial', DrillTrialAction)
        self.assertTrue(other.wait_for_server(rospy.Duration(10.0)))
        other.send_goal(goal())
        self.assertTrue(other.wait_for_result(rospy.Duration(BOUND_S)))
        self.assertEqual(other.get_state(), GoalStatus.REJECTED)
        self.assertIn('a trial is running', other.get_result().message)
        self.assertTrue(self.client.wait_for_result(rospy.Duration(BOUND_S)), 'no result')
        result = self.client.get_result()
        self.assertEqual(self.client.get_state(), GoalStatus.SUCCEEDED, result.message)
        self.assertTrue(result.done)
        self.assertEqual(result.final_phase, 'done')
        self.assertGreaterEqual(result.stops, 1)
        self.assertNotEqual(result.stop_source, '')
        for phase in ('moving_to_pose', 'registering', 'drilling', 'retreating'):
            self.assertIn(phase, phases)

        # Canceled while drilling: a stop with retreat from trial_action, the trial done.
        drilling = threading.Event()
        self.start(lambda f: f.phase_name == 'drilling' and drilling.set())
        self.assertTrue(drilling.wait(BOUND_S), 'the trial never drilled')
        self.client.cancel_goal()
        self.assertTrue(self.client.wait_for_result(rospy.Duration(BOUND_S)), 'no result')
        result = self.client.get_result()
        self.assertEqual(self.client.get_state(), GoalStatus.PREEMPTED, result.message)
        self.assertEqual(result.final_phase, 'done')
        with self.lock:
            ours = [s for s in self.stops if s.source.endswith('trial_action')]
        self.assertEqual(len(ours), 1)
        self.assertTrue(ours[0].retreat)
        self.assertIn('canceled', ours[0].reason)


if __name__ == '__main__':
    rospy.init_node('test_trial_action')
    rostest.rosrun('pedicle_drilling', 'drill_trial_client', TrialActionTest)
