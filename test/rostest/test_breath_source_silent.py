#!/usr/bin/python3
"""The lab's flow sensor silent (breath_source_silent.test).

hardware.launch's Ventilator with breath_source:=flow, no sensor: the planner refuses a
compensated trial naming the flow topic. The test then plays the sensor: three breaths of a
square flow, stamped over the last 15 s (each breath's start is the first sample above the
trigger after an expiration), so that the last start is 4 s old; the Ventilator becomes ready and
its tidal_volume carries that start. Then the sensor is silent: once the last start is older than
breath_timeout_periods (2 x 5 s), the Ventilator reports the source not ready naming the topic and
stops publishing, and the planner refuses the trial again, naming it."""
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import AirwayFlow, BreathSourceStatus, TidalVolume
from pedicle_drilling.srv import StartTrial

TOPIC = '/breath_sensor/flow'


class BreathSourceSilentTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.sources = []
        self.tidal = []
        self.ready = threading.Event()
        self.not_ready_again = threading.Event()
        self.phase_seen = threading.Event()
        self.expected_start = None
        rospy.Subscriber('/ventilator/breath_source_status', BreathSourceStatus, self.on_source,
                         queue_size=10)
        rospy.Subscriber('/tidal_volume', TidalVolume, self.on_tidal_volume, queue_size=1000)

    def on_source(self, msg):
        with self.lock:
            self.sources.append(msg)
        if msg.ready:
            self.ready.set()
        elif self.ready.is_set():
            self.not_ready_again.set()

    def on_tidal_volume(self, msg):
        start = msg.header.stamp.to_sec() - msg.time_in_breath_s
        with self.lock:
            self.tidal.append(msg)
            if self.expected_start is not None and abs(start - self.expected_start) < 1e-3:
                self.phase_seen.set()

    def refusal(self, start, must_contain):
        """The planner's answer, once it names @p must_contain (it may not have heard the
        Ventilator's latched status yet)."""
        res = None
        for _ in range(100):
            res = start(mode='compensated', spindle_rpm=0.0, feed_rate_mm_s=0.0,
                        max_duration_s=0.0)
            self.assertFalse(res.success, res.message)
            if must_contain in res.message:
                break
            rospy.sleep(0.1)
        return res.message

    def test_a_silent_flow_source_refuses_the_trial_naming_it(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        # No sensor yet: refused, naming the topic.
        message = self.refusal(start, TOPIC)
        sys.stdout.write('breath_source_silent: before any flow: %s\n' % message)
        self.assertIn(TOPIC, message)
        self.assertIn('no flow sample yet', message)
        # The sensor: 15 s of a square flow up to now, breaths starting at 1, 6 and 11 s.
        pub = rospy.Publisher(TOPIC, AirwayFlow, queue_size=100)
        while pub.get_num_connections() == 0 and not rospy.is_shutdown():
            rospy.sleep(0.05)
        t0 = rospy.Time.now().to_sec() - 15.0
        samples = []
        for k in range(3):
            begin = t0 + 1.0 + 5.0 * k
            samples += [(begin - 0.5, -200.0), (begin - 1.0 / 64.0, -50.0), (begin, 300.0),
                        (begin + 1.0, 300.0), (begin + 2.0, -300.0)]
        with self.lock:
            self.expected_start = t0 + 11.0
        for t, flow in samples:
            msg = AirwayFlow(flow_ml_s=flow)
            msg.header.stamp = rospy.Time.from_sec(t)
            pub.publish(msg)
        # Wall-time bounds of a broken run only; each wait ends on its event.
        self.assertTrue(self.ready.wait(20.0), 'the Ventilator never became ready')
        self.assertTrue(self.phase_seen.wait(20.0),
                        'no tidal_volume with the last detected breath start')
        # Silent: 10 s after the last start the source is not ready, naming the topic.
        self.assertTrue(self.not_ready_again.wait(30.0), 'the silent source stayed ready')
        with self.lock:
            silent = self.sources[-1]
        sys.stdout.write('breath_source_silent: %s\n' % silent.message)
        self.assertEqual(silent.source, 'flow')
        self.assertIn(TOPIC, silent.message)
        self.assertIn('no breath start for', silent.message)
        self.assertAlmostEqual(silent.timeout_s, 10.0, places=6)
        message = self.refusal(start, 'no breath start for')
        sys.stdout.write('breath_source_silent: silent: %s\n' % message)
        self.assertIn(TOPIC, message)
        self.assertIn('no breath start for', message)
        # Nothing the planner could use after the source fell silent.
        with self.lock:
            late = [m for m in self.tidal if m.header.stamp > silent.header.stamp]
        self.assertEqual(late, [])


if __name__ == '__main__':
    rospy.init_node('test_breath_source_silent')
    rostest.rosrun('pedicle_drilling', 'breath_source_silent', BreathSourceSilentTest, sys.argv)
