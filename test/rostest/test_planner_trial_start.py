#!/usr/bin/python3
"""What ~start_trial owns: every component of the trial is started afresh there, or the trial is
refused with the reason and nothing moves; and the planner never feeds while the recognizer
reports a stop (latched from an earlier trial, or a drill/stop that never arrived)."""
import sys
import threading
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped
from std_srvs.srv import Trigger, TriggerResponse
from trajectory_msgs.msg import JointTrajectory

from pedicle_drilling.msg import DrillingState, TrialStatus
from pedicle_drilling.srv import StartTrial


class Namespace(object):
    """Status and commands of the planner in one namespace, and a synthetic tracker."""

    def __init__(self, ns):
        self.ns = ns
        self.cond = threading.Condition()
        self.status = []
        self.commands = []
        rospy.Subscriber('/%s/compensation/status' % ns, TrialStatus, self.keep(self.status),
                         queue_size=100)
        rospy.Subscriber('/%s/arm_controller/command' % ns, JointTrajectory,
                         self.keep(self.commands), queue_size=100)
        self.state_pub = rospy.Publisher('/%s/drilling_state' % ns, DrillingState, queue_size=10,
                                         latch=True)
        self.marker_pub = rospy.Publisher('/%s/tracker/marker_pose' % ns, PoseStamped,
                                          queue_size=10)
        rospy.Timer(rospy.Duration(0.125), self.publish_marker)
        name = '/%s/compensation_planner/start_trial' % ns
        rospy.wait_for_service(name, 30.0)
        self.start = rospy.ServiceProxy(name, StartTrial)

    def keep(self, store):
        def callback(msg):
            with self.cond:
                store.append(msg)
                self.cond.notify_all()
        return callback

    def publish_marker(self, _event):
        msg = PoseStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = 'world'
        msg.pose.position.x, msg.pose.position.z = 0.6, 0.27
        msg.pose.orientation.w = 1.0
        self.marker_pub.publish(msg)

    def recognizer_state(self, stop):
        msg = DrillingState()
        msg.header.stamp = rospy.Time.now()
        msg.state = DrillingState.STOPPED if stop else DrillingState.IDLE
        msg.state_name = 'stopped' if stop else 'idle'
        msg.last_key_point = 4 if stop else 0
        msg.stop = stop
        self.state_pub.publish(msg)

    def statuses(self):
        with self.cond:
            return [s.phase_name for s in self.status]

    def wait_status(self, wanted, after, what):
        """Waits for a status in `wanted` among those after index `after` (event driven; the
        bound only ends a broken run)."""
        deadline = rospy.Time.now() + rospy.Duration(30.0)
        with self.cond:
            while True:
                seen = [s.phase_name for s in self.status[after:]]
                hit = [s for s in seen if s in wanted]
                if hit:
                    return hit[0], seen
                if rospy.is_shutdown() or rospy.Time.now() > deadline:
                    raise AssertionError('%s: none of %r reached; seen %r' % (what, wanted, seen))
                self.cond.wait(0.2)

    def wait_first_status(self):
        deadline = rospy.Time.now() + rospy.Duration(30.0)
        with self.cond:
            while not self.status:
                if rospy.Time.now() > deadline:
                    raise AssertionError('no latched status from /%s' % self.ns)
                self.cond.wait(0.2)


def stationary(ns):
    return ns.start(mode='stationary', spindle_rpm=0.0, feed_rate_mm_s=0.0, max_duration_s=0.0)


class PlannerTrialStartTest(unittest.TestCase):
    def test_1_missing_or_refusing_component_refuses_the_trial(self):
        ns = Namespace('strict')
        ns.wait_first_status()
        # No recognizer loaded: refused, naming the service; nothing starts.
        res = stationary(ns)
        self.assertFalse(res.success)
        self.assertIn('/strict/state_recognizer/reset', res.message)
        self.assertIn('not available', res.message)
        # A component that refuses its reset refuses the trial with its own words.
        calls = []

        def recognizer_reset(_req):
            calls.append('recognizer')
            return TriggerResponse(success=True, message='recognizer reset')

        def refusing_monitor(_req):
            calls.append('monitor')
            return TriggerResponse(success=False, message='monitor refuses: sensor fault')

        s1 = rospy.Service('/strict/state_recognizer/reset', Trigger, recognizer_reset)
        s2 = rospy.Service('/strict/safety_monitor/reset', Trigger, refusing_monitor)
        res = stationary(ns)
        self.assertFalse(res.success)
        self.assertIn('monitor refuses: sensor fault', res.message)
        self.assertEqual(calls, ['recognizer', 'monitor'])
        s2.shutdown()

        def monitor_reset(_req):
            calls.append('monitor')
            return TriggerResponse(success=True, message='monitor reset')

        s2 = rospy.Service('/strict/safety_monitor/reset', Trigger, monitor_reset)
        # Every component resets: the trial starts. Had a refused call started anything, this
        # call would be refused as "a trial is running".
        before = len(ns.statuses())
        res = stationary(ns)
        self.assertTrue(res.success, res.message)
        self.assertEqual(calls, ['recognizer', 'monitor', 'recognizer', 'monitor'])
        status, _ = ns.wait_status(('moving_to_pose',), before, 'trial start')
        self.assertEqual(status, 'moving_to_pose')
        self.assertEqual(ns.statuses()[:before], ['idle'])
        s1.shutdown()
        s2.shutdown()

    def test_2_latched_recognizer_stop_refuses_to_feed(self):
        ns = Namespace('bare')
        ns.wait_first_status()
        # A recognizer whose stop survived from an earlier trial (nobody reset it).
        ns.recognizer_state(stop=True)
        before = len(ns.statuses())
        res = stationary(ns)
        self.assertTrue(res.success, res.message)
        status, seen = ns.wait_status(('failed', 'drilling'), before, 'latched stop')
        self.assertEqual(status, 'failed', seen)
        self.assertNotIn('drilling', seen)

    def test_3_recognizer_state_stop_while_drilling_stops_the_feed(self):
        ns = Namespace('bare')
        ns.wait_first_status()
        ns.recognizer_state(stop=False)
        before = len(ns.statuses())
        res = stationary(ns)
        self.assertTrue(res.success, res.message)
        status, seen = ns.wait_status(('drilling', 'failed'), before, 'drilling')
        self.assertEqual(status, 'drilling', seen)
        # The recognizer says stop, but its drill/stop never arrives: the planner stops anyway.
        ns.recognizer_state(stop=True)
        # stop_hold_s 0 (the default): the retreat at once, without a `stopped` hold.
        status, seen = ns.wait_status(('stopped', 'retreating', 'done', 'failed'), before, 'stop')
        self.assertEqual(status, 'retreating', seen)
        self.assertNotIn('stopped', seen)


if __name__ == '__main__':
    rospy.init_node('test_planner_trial_start')
    rostest.rosrun('pedicle_drilling', 'planner_trial_start', PlannerTrialStartTest, sys.argv)
