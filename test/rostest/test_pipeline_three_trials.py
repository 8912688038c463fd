#!/usr/bin/python3
"""Three trials back to back on one running pipeline (drilling_pipeline.launch sim:=true), each
started with doc/running.md's call only:
  rosservice call /compensation_planner/start_trial "{mode: compensated, spindle_rpm: 0,
    feed_rate_mm_s: 0, max_duration_s: 0}"
and waited for until the planner reports done. For every trial: a stop command from the
StateRecognizer or the SafetyMonitor while it ran, the recognizer started afresh (idle after the
start, so its stop latch was cleared), and no breakthrough of the inner cortical layer in the
simulator's ground truth. A summary goes to stdout and the test artifacts directory."""
import os
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import DrillingState, GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial

TRIALS = 3


class PipelineThreeTrialsTest(unittest.TestCase):
    def setUp(self):
        self.cond = threading.Condition()
        self.events = []  # (kind, msg) in arrival order
        rospy.Subscriber('/compensation/status', TrialStatus, self.keep('status'), queue_size=100)
        rospy.Subscriber('/drill/stop', StopCommand, self.keep('stop'), queue_size=100)
        rospy.Subscriber('/drilling_state', DrillingState, self.keep('state'), queue_size=10000)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.keep('truth'),
                         queue_size=10000)

    def keep(self, kind):
        def callback(msg):
            with self.cond:
                self.events.append((kind, msg))
                self.cond.notify_all()
        return callback

    def wait_for(self, predicate, what, timeout_s):
        """Waits (on events; the timeout only bounds a broken run) until predicate() holds."""
        deadline = rospy.get_rostime() + rospy.Duration(timeout_s)
        with self.cond:
            while not predicate():
                if rospy.is_shutdown() or rospy.get_rostime() > deadline:
                    self.fail('%s: not reached; statuses %r' % (
                        what, [m.phase_name for k, m in self.events if k == 'status']))
                self.cond.wait(0.5)

    def test_three_trials_three_stops_no_breakthrough(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        # The compensated mode needs the ventilator's settings and phase (latched and streamed by
        # the simulator): wait for them, as a user would see them with rostopic.
        self.wait_for(lambda: any(k == 'truth' for k, _ in self.events), 'simulator running', 60.0)
        summary = []
        for trial in range(1, TRIALS + 1):
            with self.cond:
                first = len(self.events)
            # The first call may come before the ventilator's phase; any other refusal fails.
            res = start_trial(start, lambda r: 'needs the ventilator' not in r.message, 50,
                              mode='compensated', spindle_rpm=0.0, feed_rate_mm_s=0.0,
                              max_duration_s=0.0)
            self.assertTrue(res.success, 'trial %d: %s' % (trial, res.message))

            def finished():
                return any(k == 'status' and m.phase in (TrialStatus.DONE, TrialStatus.FAILED)
                           for k, m in self.events[first:])
            self.wait_for(finished, 'trial %d done' % trial, 300.0)
            with self.cond:
                events = list(self.events[first:])
            statuses = [m.phase_name for k, m in events if k == 'status']
            stops = [m for k, m in events if k == 'stop']
            # Ground truth from the trial's own start on (the remount of a drilled specimen
            # happens inside start_trial, before the first status of the trial).
            started_at = next(i for i, (k, m) in enumerate(events)
                              if k == 'status' and m.phase == TrialStatus.MOVING_TO_POSE)
            truth = [m for k, m in events[started_at:] if k == 'truth']
            sources = sorted({s.source.split('/')[-1] for s in stops})
            breakthrough = any(m.breakthrough for m in truth)
            residual = truth[-1].residual_inner_cortical_m * 1e3 if truth else float('nan')
            depth = max((m.max_depth_cut_m for m in truth), default=0.0) * 1e3
            summary.append('trial %d: statuses %s; stops from %s (%s); max depth %.2f mm, '
                           'residual %.2f mm, breakthrough %s' % (
                               trial, ' > '.join(statuses), ', '.join(sources) or 'nobody',
                               '; '.join(s.reason for s in stops), depth, residual,
                               breakthrough))
            self.assertIn('drilling', statuses, summary[-1])
            self.assertEqual(statuses[-1], 'done', summary[-1])
            self.assertTrue(stops, 'trial %d: no stop from the recognizer or the monitor: %s'
                            % (trial, summary[-1]))
            self.assertTrue(set(sources) <= {'state_recognizer', 'safety_monitor'}, summary[-1])
            self.assertFalse(breakthrough, summary[-1])
            # The recognizer started this trial afresh: before the drill fed, it reported idle
            # and no stop (its latch from the previous trial was cleared by start_trial).
            drilling_at = next(i for i, (k, m) in enumerate(events)
                               if k == 'status' and m.phase == TrialStatus.DRILLING)
            before = [m for k, m in events[:drilling_at] if k == 'state']
            self.assertTrue(before, summary[-1])
            self.assertFalse(before[-1].stop, summary[-1])
            self.assertEqual(before[-1].state, DrillingState.IDLE, summary[-1])
        text = '\n'.join(summary) + '\n'
        sys.stdout.write(text)
        out_dir = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
        if out_dir:
            os.makedirs(out_dir, exist_ok=True)
            with open(os.path.join(out_dir, 'pipeline_three_trials.txt'), 'w') as handle:
                handle.write(text)


if __name__ == '__main__':
    rospy.init_node('test_pipeline_three_trials')
    rostest.rosrun('pedicle_drilling', 'pipeline_three_trials', PipelineThreeTrialsTest,
                   sys.argv)
