#!/usr/bin/python3
"""Closed-loop scenario on the Simulator: the whole pipeline (Ventilator, StateRecognizer,
SafetyMonitor, CompensationPlanner, Simulator) runs one trial of the case ~mode. Stationary and
compensated trials must drill, stop and leave the canal intact (the exact verdict, residual in
(0, 2 mm], is the core engine's: test_closed_loop_engine); the compensated tip must follow the
bone; the uncompensated trial must only end safely (drill retracted, spindle off). Reports the tracking
error: AP motion of the drill tip relative to the bone, minus the commanded feed, while drilling
(RMS and max; the paper's safety bound is 1.2 mm), to stdout and the test artifacts directory."""
import math
import os
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial

FEED_RATE = 0.5e-3


class ClosedLoopTest(unittest.TestCase):
    def test_trial(self):
        mode = rospy.get_param('~mode')
        lock = threading.Lock()
        truth = []
        stops = []
        status = []

        def keep(store):
            def cb(msg):
                with lock:
                    store.append((rospy.Time.now().to_sec(), msg))
            return cb

        rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(truth), queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, keep(stops), queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, keep(status), queue_size=100)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, mode=mode, spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        t_drill = None
        t_end = None
        while not rospy.is_shutdown():
            with lock:
                names = [s.phase_name for _, s in status]
                if t_drill is None and 'drilling' in names:
                    t_drill = next(t for t, s in status if s.phase == TrialStatus.DRILLING)
                if names and names[-1] in ('done', 'failed'):
                    t_end = status[-1][0]
                    break
            rospy.sleep(0.1)
        with lock:
            names = [s.phase_name for _, s in status]
            stops_seen = list(stops)
            truth_seen = list(truth)
        self.assertNotIn('failed', names)
        self.assertIsNotNone(t_drill, 'never drilled: %r' % names)
        recognizer = [(t, s) for t, s in stops_seen if not s.retreat]
        safety = [(t, s) for t, s in stops_seen if s.retreat]
        t_stop = stops_seen[0][0] if stops_seen else t_end
        # Tracking error while drilling (until the first stop).
        rel = [(t, g.relative_ap_m) for t, g in truth_seen if t_drill + 1.0 <= t <= t_stop]
        self.assertGreater(len(rel), 10)
        t0, r0 = rel[0]
        errors = [r - r0 + FEED_RATE * (t - t0) for t, r in rel]
        mean = sum(errors) / len(errors)
        rms = math.sqrt(sum((e - mean) ** 2 for e in errors) / len(errors))
        peak = max(abs(e - mean) for e in errors)
        # The bone's own AP motion over the same window: what the tip would see uncompensated.
        bone = [g.bone_displacement_m.z for t, g in truth_seen if t_drill + 1.0 <= t <= t_stop]
        bone_mean = sum(bone) / len(bone)
        bone_rms = math.sqrt(sum((b - bone_mean) ** 2 for b in bone) / len(bone))
        final = truth_seen[-1][1]
        at_stop = [g for t, g in truth_seen if t <= t_stop][-1]
        report = ('%s: stops %r; residual inner cortical at stop %.3f mm, breakthrough %s; '
                  'relative AP tip-bone minus feed while drilling: RMS %.3f mm, max %.3f mm; '
                  'bone AP motion RMS %.3f mm\n' %
                  (mode, [(s.source, s.reason) for _, s in stops_seen],
                   at_stop.residual_inner_cortical_m * 1e3, final.breakthrough, rms * 1e3,
                   peak * 1e3, bone_rms * 1e3))
        sys.stdout.write(report)
        artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
        if artifacts:
            os.makedirs(artifacts, exist_ok=True)
            with open(os.path.join(artifacts, 'closed_loop_%s.txt' % mode), 'w') as handle:
                handle.write(report)
        self.assertEqual(names[-1], 'done')
        if mode != 'stationary':
            self.assertGreater(bone_rms, 0.2e-3, 'the bone does not move: %s' % report)
        if mode == 'uncompensated':
            # Nothing follows the bone: the tip sees the bone's motion. Whatever the stop, the
            # trial must only end safely (checked above).
            self.assertGreater(rms, 0.5 * bone_rms, report)
            return
        if mode == 'compensated':
            # The compensation removes at least three quarters of the relative motion.
            self.assertLess(rms, 0.25 * bone_rms, report)
        # What the pipeline guarantees whatever the scheduling: it drilled, a stop came (the
        # recognizer's or the monitor's) and the canal is intact. Whether this one trial stops
        # within 2 mm of the canal depends on where in the breath and force bumps the messages
        # fall, which the ROS pipeline leaves to the scheduler; the core engine gives that
        # verdict exactly for the same seed (test_closed_loop_engine), and the engines'
        # agreement is measured trial by trial (test_engine_agreement, make run).
        self.assertTrue(recognizer or safety, 'no stop: %s' % report)
        self.assertGreater(final.max_depth_cut_m, 0.0, report)
        self.assertFalse(final.breakthrough, report)
        if mode == 'compensated':
            self.assertLess(peak, 1.2e-3, report)


if __name__ == '__main__':
    rospy.init_node('test_closed_loop')
    rostest.rosrun('pedicle_drilling', 'closed_loop', ClosedLoopTest, sys.argv)
