#!/usr/bin/python3
"""Fault scenario on the ROS pipeline (issue 15): drilling_pipeline.launch sim:=true
fault_injection:=true runs one compensated trial; once the drill is 1 mm into the bone (the
simulator's ground truth), the test injects the fault ~fault through /fault_injector/inject, as
the core engine's fault campaign does. The trial must end safely: a stop after the fault (from
the source and with the reason ~expect names, when given), a retreat, the phase 'done', and no
breakthrough of the inner cortical layer. Reports the time from the fault to the stop and the
residual at the stop, to stdout and the test artifacts directory. With ~unload instead of
~fault, the fault is that nodelet unloaded from the manager (~manager) mid-trial. The breathing
faults (breathing_amplitude, breathing_rate_up / _down) go through the simulator's
set_patient_amplitude and set_ventilator_settings services and take effect at the next breath."""
import os
import sys
import threading
import unittest

import rospy
import rostest

from nodelet.srv import NodeletUnload

from pedicle_drilling.msg import (GroundTruth, RetareCheck, StopCommand, TrialStatus,
                                  VentilatorSettings)
from pedicle_drilling.srv import (InjectFault, SetPatientAmplitude, SetVentilatorSettings,
                                  StartTrial)
from simulator_events import start_trial

# The breathing faults are the patient's: the simulator's services, with the core engine's sizes
# (core::FaultParams: amplitude x 1.3, rate +-4 /min).
AMPLITUDE_FACTOR = 1.3
RATE_CHANGE_BPM = 4.0

INJECT_DEPTH_M = 1.0e-3  # the deepest cut when the fault is injected: in the outer cortex


class FaultInjectionTest(unittest.TestCase):
    def test_fault(self):
        unload = rospy.get_param('~unload', '')  # a nodelet's name, e.g. /state_recognizer
        fault = rospy.get_param('~fault', '') or 'unloaded_' + unload.strip('/')
        expect = rospy.get_param('~expect', '')  # substring of the first stop's reason
        lock = threading.Lock()
        truth, stops, status = [], [], []
        injected = threading.Event()
        deep_enough = threading.Event()

        def keep(store):
            def cb(msg):
                with lock:
                    store.append((rospy.Time.now().to_sec(), msg))
                if isinstance(msg, GroundTruth) and msg.max_depth_cut_m >= INJECT_DEPTH_M:
                    deep_enough.set()
            return cb

        rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(truth), queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, keep(stops), queue_size=10)
        retare = []

        def on_retare(msg):
            with lock:
                retare.append(msg)
        rospy.Subscriber('/safety_monitor/retare_check', RetareCheck, on_retare, queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, keep(status), queue_size=100)
        settings = []
        rospy.Subscriber('/ventilator/settings', VentilatorSettings, settings.append,
                         queue_size=10)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        if unload:
            manager = rospy.get_param('~manager', '/pedicle_drilling_manager')
            rospy.wait_for_service(manager + '/unload_nodelet', 60.0)
            unloader = rospy.ServiceProxy(manager + '/unload_nodelet', NodeletUnload)
        elif fault.startswith('breathing_'):
            rospy.wait_for_service('/simulator/set_patient_amplitude', 60.0)
            amplitude = rospy.ServiceProxy('/simulator/set_patient_amplitude',
                                           SetPatientAmplitude)
            ventilator = rospy.ServiceProxy('/simulator/set_ventilator_settings',
                                            SetVentilatorSettings)
        else:
            rospy.wait_for_service('/fault_injector/inject', 60.0)
            inject = rospy.ServiceProxy('/fault_injector/inject', InjectFault)
        res = start_trial(start, mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        # Event: the drill is INJECT_DEPTH_M into the bone (no stop may have come before).
        self.assertTrue(deep_enough.wait(120.0), 'the drill never reached %.1f mm' %
                        (INJECT_DEPTH_M * 1e3))
        with lock:
            self.assertEqual(stops, [], 'a stop before the fault')
        if unload:
            self.assertTrue(unloader(name=unload).success, 'could not unload ' + unload)
        elif fault == 'breathing_amplitude':
            answer = amplitude(factor=AMPLITUDE_FACTOR)
            self.assertTrue(answer.success, answer.message)
        elif fault.startswith('breathing_rate_'):
            self.assertTrue(settings, 'no ventilator/settings heard')  # latched
            new = settings[-1]
            new.rate_bpm += RATE_CHANGE_BPM if fault.endswith('_up') else -RATE_CHANGE_BPM
            answer = ventilator(settings=new)
            self.assertTrue(answer.success, answer.message)
        else:
            answer = inject(fault=fault)
            self.assertTrue(answer.success, answer.message)
        t_fault = rospy.Time.now().to_sec()
        injected.set()
        while not rospy.is_shutdown():
            with lock:
                names = [s.phase_name for _, s in status]
                if names and names[-1] in ('done', 'failed'):
                    break
            rospy.sleep(0.05)
        with lock:
            names = [s.phase_name for _, s in status]
            stops_seen = list(stops)
            truth_seen = list(truth)
        self.assertTrue(stops_seen, 'no stop after %s' % fault)
        t_stop, first = stops_seen[0]
        at_stop = [g for t, g in truth_seen if t <= t_stop][-1]
        final = truth_seen[-1][1]
        report = ('%s: first stop %.3f s after the fault (sim time) from %s: %s; left to the '
                  'canal wall at the stop %.3f mm; phases %s; breakthrough %s\n' %
                  (fault, t_stop - t_fault, first.source, first.reason,
                   at_stop.residual_inner_cortical_m * 1e3, names[-3:], final.breakthrough))
        sys.stdout.write(report)
        artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
        if artifacts:
            os.makedirs(artifacts, exist_ok=True)
            with open(os.path.join(artifacts, 'fault_%s.txt' % fault), 'w') as handle:
                handle.write(report)
        self.assertEqual(names[-1], 'done', report)
        self.assertIn('retreating', names, report)
        self.assertFalse(final.breakthrough, report)
        self.assertGreater(at_stop.residual_inner_cortical_m, 0.0, report)
        if expect:
            self.assertIn(expect, first.reason, report)
        # The monitor's re-tare check when the retreat ended (~expect_drift: it finds one).
        if rospy.get_param('~expect_drift', False):
            deadline = rospy.Time.now() + rospy.Duration(30.0)  # bounds a broken run only
            found = []
            while not rospy.is_shutdown() and rospy.Time.now() < deadline:
                with lock:
                    found = [c for c in retare if c.drift]
                if found:
                    break
                rospy.sleep(0.05)
            self.assertTrue(found, 'the re-tare check found no drift: %r %s' % (retare, report))
            self.assertGreater(found[0].offset_n, found[0].limit_n)
            self.assertTrue(found[0].message.startswith('force_offset: '), found[0].message)
            with lock:
                self.assertFalse([s for _, s in stops if 'force_offset' in s.reason],
                                 'the re-tare check is not a stop')

if __name__ == '__main__':
    rospy.init_node('test_fault_injection')
    rostest.rosrun('pedicle_drilling', 'fault_injection', FaultInjectionTest, sys.argv)
