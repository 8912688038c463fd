#!/usr/bin/python3
"""Scenario check: the StateRecognizer declared at 1000/3 Hz (config/recognizer.yaml) is fed a
force stream stamped at 1 kHz, its block three times too short in time. ~scenario:

- refused: an ERROR on /diagnostics and in the log naming both rates, ~reset refused (the
  planner's trial with it) naming both; a stream at the declared rate then gives an OK status
  and ~reset succeeds.
- in_trial: while the planner's trial runs (compensation/status), the mismatch stops it once,
  with retreat, the reason naming both rates.

Every wait is for an event; the bounds only end a broken run."""
import sys
import threading
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from rosgraph_msgs.msg import Log
from std_srvs.srv import Trigger

from pedicle_drilling.msg import StopCommand, TrialStatus

STATUS = '/state_recognizer: sensor rate'
BOUND_S = 60.0


class RecognizerRateTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.statuses = []
        self.errors = []
        self.stops = []
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diagnostics, queue_size=100)
        rospy.Subscriber('/rosout_agg', Log, self.on_log, queue_size=100)
        rospy.Subscriber('/rosout', Log, self.on_log, queue_size=100)
        rospy.Subscriber('/drill/stop', StopCommand, self.on_stop, queue_size=10)
        self.pub = rospy.Publisher('/ft_sensor/wrench', WrenchStamped, queue_size=2000)
        self.status_pub = rospy.Publisher('/compensation/status', TrialStatus, queue_size=1,
                                          latch=True)
        self.wait_for(lambda: self.pub.get_num_connections() > 0, 'the recognizer subscribed')
        self.t = 1000.0  # stamps [s]

    def on_diagnostics(self, msg):
        with self.lock:
            self.statuses.extend(s for s in msg.status if s.name == STATUS)

    def on_log(self, msg):
        if msg.level >= Log.ERROR and 'sensor rate' in msg.msg:
            with self.lock:
                self.errors.append(msg.msg)

    def on_stop(self, msg):
        with self.lock:
            self.stops.append(msg)

    def wait_for(self, condition, what):
        deadline = rospy.Time.now() + rospy.Duration(BOUND_S)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            with self.lock:
                if condition():
                    return
            rospy.sleep(0.05)
        self.fail('no event: %s' % what)

    def stream(self, rate_hz, seconds):
        """Samples stamped at rate_hz for `seconds` of stamps, after a pause of 0.2 s (a new
        window), sent in bursts of 10 every 10 ms (the nodelet's queue keeps up)."""
        self.t += 0.2
        pace = rospy.Rate(100)
        for i in range(int(seconds * rate_hz)):
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(self.t)
            msg.header.frame_id = 'ft_sensor'
            self.pub.publish(msg)
            self.t += 1.0 / rate_hz
            if i % 10 == 9:
                pace.sleep()

    def latest(self):
        return self.statuses[-1] if self.statuses else None

    def test_mismatch(self):
        scenario = rospy.get_param('~scenario')
        if scenario == 'in_trial':
            self.in_trial()
        else:
            self.refused()

    def refused(self):
        self.stream(1000.0, 1.2)
        self.wait_for(lambda: self.latest() is not None, 'a sensor-rate status')
        with self.lock:
            status = self.latest()
        self.assertEqual(status.level, DiagnosticStatus.ERROR, status.message)
        for words in ('measured 1000 Hz', 'declared 333.333 Hz',
                      'block of 50 samples lasts 0.05 s'):
            self.assertIn(words, status.message)
        values = {kv.key: kv.value for kv in status.values}
        self.assertAlmostEqual(float(values['measured_rate_hz']), 1000.0, delta=1.0)
        self.assertEqual(values['block_samples'], '50')
        self.assertAlmostEqual(float(values['sensor_rate_hz']), 1000.0 / 3.0, delta=1e-3)
        self.wait_for(lambda: any('measured 1000 Hz' in e and 'declared 333.333 Hz' in e
                                  for e in self.errors), 'an ERROR log line naming both rates')
        rospy.wait_for_service('/state_recognizer/reset', BOUND_S)
        reset = rospy.ServiceProxy('/state_recognizer/reset', Trigger)
        answer = reset()
        self.assertFalse(answer.success, answer.message)
        self.assertIn('sensor rate mismatch', answer.message)
        self.assertIn('measured 1000 Hz', answer.message)
        self.assertIn('declared 333.333 Hz', answer.message)
        # The stream at the declared rate: the next status is OK, and the reset succeeds.
        with self.lock:
            seen = len(self.statuses)
        self.stream(1000.0 / 3.0, 1.1)
        self.wait_for(lambda: len(self.statuses) > seen, 'the status of the matching stream')
        with self.lock:
            status = self.latest()
        self.assertEqual(status.level, DiagnosticStatus.OK, status.message)
        answer = reset()
        self.assertTrue(answer.success, answer.message)
        self.assertEqual(self.stops, [], 'no trial ran: no stop')

    def in_trial(self):
        running = TrialStatus(phase=TrialStatus.DRILLING, phase_name='drilling', running=True)
        running.header.stamp = rospy.Time.from_sec(self.t)
        self.status_pub.publish(running)
        # Two windows: one stop for the trial, not one per window.
        self.stream(1000.0, 2.2)
        self.wait_for(lambda: len(self.statuses) >= 2, 'two sensor-rate statuses')
        self.wait_for(lambda: self.stops, 'a stop')
        with self.lock:
            stops = list(self.stops)
            levels = {s.level for s in self.statuses}
        self.assertEqual(levels, {DiagnosticStatus.ERROR})
        self.assertEqual(len(stops), 1, [s.reason for s in stops])
        stop = stops[0]
        self.assertTrue(stop.retreat)
        self.assertEqual(stop.source, '/state_recognizer')
        self.assertIn('sensor rate mismatch', stop.reason)
        self.assertIn('measured 1000 Hz', stop.reason)
        self.assertIn('declared 333.333 Hz', stop.reason)


if __name__ == '__main__':
    rospy.init_node('test_recognizer_rate')
    rostest.rosrun('pedicle_drilling', 'recognizer_rate', RecognizerRateTest, sys.argv)
