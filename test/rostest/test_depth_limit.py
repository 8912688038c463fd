#!/usr/bin/python3
"""Scenario (depth_limit_cancellous_forever.test): a recognizer that reports `cancellous` from the
first contact on and never stops, the planner's cancellous bound off, one compensated trial on the
simulated pipeline. The simulator's drilling plan reaches the planner (drilling_plan, latched), and
the planner's depth limit alone ends the trial: its first drill/stop is the planner's own, reason
`depth_limit: ...`, with retreat; the trial ends `done` after `retreating`; the simulator's ground
truth shows no breakthrough, the inner cortical layer not cut through (residual > 0 at the end)
and the deepest cut past the inner layer's start (the limit let the drill reach the plan).
Waits on events (the planner's phases); the wall bound only ends a broken run. Reports the stop
and the ground truth at the end, to stdout and the test artifacts directory."""
import os
import sys
import threading
import time
import unittest

import rospy
import rostest

from pedicle_drilling.msg import DrillingPlan, DrillingState, GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial

PLANNER = '/compensation_planner'
WAIT_BOUND_S = 200.0  # wall seconds: bounds a broken run only


class DepthLimitTest(unittest.TestCase):
    def setUp(self):
        self.cond = threading.Condition()
        self.truth, self.stops, self.status, self.plans, self.states = [], [], [], [], []
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.keep(self.truth),
                         queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, self.keep(self.stops), queue_size=100)
        rospy.Subscriber('/compensation/status', TrialStatus, self.keep(self.status),
                         queue_size=100)
        rospy.Subscriber('/drilling_plan', DrillingPlan, self.keep(self.plans), queue_size=10)
        rospy.Subscriber('/drilling_state', DrillingState, self.keep(self.states),
                         queue_size=1000)

    def keep(self, store):
        def cb(msg):
            with self.cond:
                store.append(msg)
                self.cond.notify_all()
        return cb

    def wait_for(self, predicate, what):
        """Waits on the subscribers' events until predicate() holds (under self.cond)."""
        deadline = time.monotonic() + WAIT_BOUND_S
        with self.cond:
            while not predicate():
                left = deadline - time.monotonic()
                if left <= 0 or rospy.is_shutdown():
                    self.fail('%s: not reached; phases %r' %
                              (what, [s.phase_name for s in self.status]))
                self.cond.wait(min(left, 0.5))

    def ended(self):
        return bool(self.status) and self.status[-1].phase_name in ('done', 'failed')

    def test_only_the_depth_limit_stops_a_recognizer_that_never_does(self):
        # The simulator's plan of the mounted specimen, latched: what the planner drills to.
        self.wait_for(lambda: bool(self.plans), 'the simulator\'s drilling_plan')
        rospy.wait_for_service(PLANNER + '/start_trial', 60.0)
        start = rospy.ServiceProxy(PLANNER + '/start_trial', StartTrial)
        res = start_trial(start, mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        self.wait_for(self.ended, 'the trial\'s end')
        with self.cond:
            names = [s.phase_name for s in self.status]
            stops = list(self.stops)
            truth = list(self.truth)
            plan = self.plans[-1]
            layers = {s.state_name for s in self.states}
            recognizer_stops = [s for s in self.states if s.stop]
        self.assertTrue(truth, 'no ground truth heard')
        final = truth[-1]
        report = ('depth limit: phases %r; stops %r; plan in %s, depth %.3f mm (tolerance '
                  '%.3f mm); deepest cut %.3f mm, inner layer %.3f-%.3f mm deep, residual '
                  'inner cortical at the end %.3f mm, breakthrough %s; recognizer states %r\n' %
                  (names, [(s.source, s.reason) for s in stops], plan.header.frame_id,
                   plan.depth_m * 1e3, plan.entry_tolerance_m * 1e3, final.max_depth_cut_m * 1e3,
                   final.inner_cortical_start_m * 1e3, final.inner_cortical_end_m * 1e3,
                   final.residual_inner_cortical_m * 1e3, final.breakthrough, sorted(layers)))
        sys.stdout.write(report)
        artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
        if artifacts:
            os.makedirs(artifacts, exist_ok=True)
            with open(os.path.join(artifacts, 'depth_limit_cancellous_forever.txt'), 'w') as f:
                f.write(report)
        # The recognizer class was the one in use: it saw the contact and never stopped.
        self.assertIn('cancellous', layers, report)
        self.assertEqual(recognizer_stops, [], report)
        # The first stop: the planner's own depth limit, with retreat.
        self.assertTrue(stops, 'no stop: ' + report)
        first = stops[0]
        self.assertIn('depth_limit', first.reason, report)
        self.assertEqual(first.source, PLANNER, report)
        self.assertTrue(first.retreat, report)
        # The trial retreated and ended done.
        self.assertEqual(names[-1], 'done', report)
        self.assertEqual(names[-2:], ['retreating', 'done'], report)
        # The canal intact, the inner layer reached: the limit let the drill go to the plan.
        self.assertFalse(any(g.breakthrough for g in truth), report)
        self.assertGreater(final.residual_inner_cortical_m, 0.0, report)
        self.assertGreater(final.max_depth_cut_m, final.inner_cortical_start_m, report)


if __name__ == '__main__':
    rospy.init_node('test_depth_limit')
    rostest.rosrun('pedicle_drilling', 'depth_limit_cancellous_forever', DepthLimitTest,
                   sys.argv)
