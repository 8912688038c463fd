#!/usr/bin/python3
"""The breath phase from the lab's flow sensor, end to end (breath_phase_from_flow.test).

hardware.launch's Ventilator (breath_source:=flow) detects each breath's start on the flow the
Simulator's breath sensor samples; the planner drills one compensated trial on that phase. The
trial must stop inside the inner cortex without a breakthrough, and every breath start the
Ventilator published (tidal_volume: stamp - time_in_breath, one per breath_index) must lie
within 50 ms of the simulated ventilator's own start (simulator/ground_truth.breath_start)."""
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import (AirwayFlow, BreathSourceStatus, GroundTruth, StopCommand,
                                  TidalVolume, TrialStatus)
from pedicle_drilling.srv import StartTrial

TOLERANCE_S = 0.05


class BreathPhaseFromFlowTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.truth = []
        self.stops = []
        self.status = []
        self.ventilator_starts = {}  # breath_index -> start (s), the Ventilator's
        self.truth_starts = set()    # the simulated ventilator's starts (s)
        self.flow_samples = 0
        self.sources = []
        self.done = threading.Event()
        self.drives_enabled = threading.Event()
        self.breaths_detected = threading.Event()
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.on_truth, queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, self.keep(self.stops), queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, self.on_status, queue_size=100)
        rospy.Subscriber('/tidal_volume', TidalVolume, self.on_tidal_volume, queue_size=1000)
        rospy.Subscriber('/breath_sensor/flow', AirwayFlow, self.on_flow, queue_size=1000)
        rospy.Subscriber('/ventilator/breath_source_status', BreathSourceStatus,
                         self.keep(self.sources), queue_size=10)

    def keep(self, store):
        def callback(msg):
            with self.lock:
                store.append(msg)
        return callback

    def on_truth(self, msg):
        with self.lock:
            self.truth.append(msg)
            self.truth_starts.add(round(msg.breath_start.to_sec(), 6))
        if not msg.drives_halted:
            self.drives_enabled.set()

    def on_status(self, msg):
        with self.lock:
            self.status.append(msg)
        if msg.phase_name in ('done', 'failed'):
            self.done.set()

    def on_tidal_volume(self, msg):
        start = msg.header.stamp.to_sec() - msg.time_in_breath_s
        with self.lock:
            # The latest message of a breath: a detected start may move the breath the schedule
            # began on its own (FlowPhasedSchedule), the index kept.
            self.ventilator_starts[msg.breath_index] = start
            if len(self.ventilator_starts) >= 3:
                self.breaths_detected.set()

    def on_flow(self, msg):
        with self.lock:
            self.flow_samples += 1

    def test_a_compensated_trial_on_the_detected_breath_phase(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        # Wall-time bounds of a broken run only; each wait ends on its event.
        self.assertTrue(self.drives_enabled.wait(60.0), 'the drivers never heard the drill guard')
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        refusals = []
        res = None
        for _ in range(300):
            res = start(mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                        max_duration_s=60.0)
            if res.success:
                break
            refusals.append(res.message)
            rospy.sleep(0.2)
        self.assertTrue(res.success, res.message)
        # Before the first detected breath (breath 0 is not one: the detector joins the stream
        # at an unknown phase), the refusals named the flow topic.
        self.assertTrue(refusals, 'a trial was accepted before any breath start was detected')
        self.assertTrue(any('/breath_sensor/flow' in r for r in refusals), refusals[:3])
        self.assertTrue(self.done.wait(240.0), 'the trial did not end')
        self.assertTrue(self.breaths_detected.wait(60.0), 'fewer than 3 breaths detected')
        with self.lock:
            names = [s.phase_name for s in self.status]
            stops = list(self.stops)
            final = self.truth[-1]
            detected = sorted(self.ventilator_starts.items())
            truth_starts = sorted(self.truth_starts)
            flow_samples = self.flow_samples
            sources = list(self.sources)
        errors = []
        for index, t in detected:
            nearest = min(truth_starts, key=lambda s: abs(s - t))
            errors.append((index, t - nearest))
        report = ('phases %r; stops %r; breakthrough %s, residual inner cortical %.3f mm, '
                  'cut %.3f mm (inner cortex %.3f-%.3f mm); %d flow samples; breath start '
                  'error vs truth (ms): %s' % (
                      names, [(s.source, s.reason) for s in stops], final.breakthrough,
                      final.residual_inner_cortical_m * 1e3, final.max_depth_cut_m * 1e3,
                      final.inner_cortical_start_m * 1e3, final.inner_cortical_end_m * 1e3,
                      flow_samples, ', '.join('%d: %+.1f' % (i, e * 1e3) for i, e in errors)))
        sys.stdout.write('breath_phase_from_flow: %s\n' % report)
        self.assertTrue(sources and sources[0].source == 'flow', report)
        self.assertIn('/breath_sensor/flow', sources[0].topic, report)
        self.assertTrue(sources[-1].ready, report)
        # The trial: drilled, stopped inside the inner cortex, the canal intact.
        self.assertEqual(names[-1], 'done', report)
        self.assertIn('drilling', names, report)
        self.assertTrue(stops, report)
        self.assertFalse(final.breakthrough, report)
        self.assertGreater(final.max_depth_cut_m, final.inner_cortical_start_m, report)
        self.assertLess(final.max_depth_cut_m, final.inner_cortical_end_m, report)
        # The breath phase: every start within 50 ms of the truth's.
        self.assertGreaterEqual(len(errors), 3, report)
        for index, error in errors:
            self.assertLess(abs(error), TOLERANCE_S, 'breath %d: %s' % (index, report))


if __name__ == '__main__':
    rospy.init_node('test_breath_phase_from_flow')
    rostest.rosrun('pedicle_drilling', 'breath_phase_from_flow', BreathPhaseFromFlowTest,
                   sys.argv)
