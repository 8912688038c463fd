#!/usr/bin/python3
"""Reads the Ventilator nodelet's stream and checks rate, values and run-time settings."""
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import TidalVolume, VentilatorSettings
from pedicle_drilling.srv import SetVentilatorSettings

INSPIRATORY_TIME = 5.0 / 3.0


class VentilatorStreamTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.samples = []
        self.sub = rospy.Subscriber('/tidal_volume', TidalVolume, self.on_sample, queue_size=1000)

    def on_sample(self, msg):
        with self.lock:
            self.samples.append(msg)

    def collect(self, seconds):
        with self.lock:
            self.samples = []
        rospy.sleep(seconds)
        with self.lock:
            return list(self.samples)

    def test_rate_and_values(self):
        samples = self.collect(6.0)
        self.assertGreater(len(samples), 100, 'no tidal-volume stream on /tidal_volume')
        span = (samples[-1].header.stamp - samples[0].header.stamp).to_sec()
        rate = (len(samples) - 1) / span
        self.assertAlmostEqual(rate, 64.0, delta=3.0)
        for msg in samples:
            tau = msg.time_in_breath_s
            self.assertGreaterEqual(tau, 0.0)
            self.assertLess(tau, 5.0 + 1e-6)
            if tau < INSPIRATORY_TIME - 1e-6:
                self.assertAlmostEqual(msg.flow_ml_s, 300.0, places=3)
                self.assertAlmostEqual(msg.volume_ml, 300.0 * tau, delta=1e-3)
            else:
                self.assertLess(msg.flow_ml_s, 0.0)
                self.assertLessEqual(msg.volume_ml, 500.0 + 1e-6)
                self.assertGreaterEqual(msg.volume_ml, -1e-6)
        peak = max(m.volume_ml for m in samples)
        self.assertAlmostEqual(peak, 500.0, delta=300.0 / 64.0 + 0.5)

    def test_settings_change_at_next_breath(self):
        rospy.wait_for_service('/ventilator/set_settings', timeout=10.0)
        set_settings = rospy.ServiceProxy('/ventilator/set_settings', SetVentilatorSettings)
        bad = VentilatorSettings(tv_max_ml=500.0, rate_bpm=0.0, ie_inspiratory=1.0,
                                 ie_expiratory=2.0, waveform='square',
                                 expiratory_spec='peak_ratio', peak_flow_ratio=1.5,
                                 expiratory_tau_s=0.4)
        reply = set_settings(bad)
        self.assertFalse(reply.success)
        self.assertIn('rate_bpm', reply.message)

        # Different flow and period from the running breath, so a switch mid-breath shows.
        new = VentilatorSettings(tv_max_ml=600.0, rate_bpm=15.0, ie_inspiratory=1.0,
                                 ie_expiratory=2.0, waveform='square',
                                 expiratory_spec='peak_ratio', peak_flow_ratio=1.5,
                                 expiratory_tau_s=0.4, ramp_start_fraction=0.25,
                                 exponential_shape=0.5)
        with self.lock:
            self.samples = []
        reply = set_settings(new)
        self.assertTrue(reply.success, reply.message)
        rospy.sleep(10.5)  # at most 5 s to the next breath, then a whole breath of 4 s
        with self.lock:
            samples = list(self.samples)
        first_breath = samples[0].breath_index
        old = [m for m in samples if m.breath_index == first_breath]
        newer = [m for m in samples if m.breath_index >= first_breath + 1]
        self.assertTrue(newer, 'no new breath seen')
        # The breath in progress when the settings arrived runs to its end at 5 s, 300 ml/s.
        self.assertGreater(old[-1].time_in_breath_s, 5.0 - 2.0 / 64.0)
        for msg in old:
            if msg.time_in_breath_s < INSPIRATORY_TIME - 1e-6:
                self.assertAlmostEqual(msg.flow_ml_s, 300.0, places=3)
        # New breaths: T = 4 s, Ti = 4/3 s, flow 600 / (4/3) = 450 ml/s, peak volume 600 ml.
        self.assertLess(max(m.time_in_breath_s for m in newer), 4.0 + 1e-6)
        inspiring = [m for m in newer if m.time_in_breath_s < 4.0 / 3.0 - 1e-6]
        self.assertTrue(inspiring)
        for msg in inspiring:
            self.assertAlmostEqual(msg.flow_ml_s, 450.0, places=3)
        self.assertAlmostEqual(max(m.volume_ml for m in newer), 600.0, delta=450.0 / 64.0 + 0.5)
        # The latched ~settings carry every field of the new settings, shape ones included.
        latched = rospy.wait_for_message('/ventilator/settings', VentilatorSettings, timeout=5.0)
        self.assertAlmostEqual(latched.tv_max_ml, 600.0)
        self.assertAlmostEqual(latched.ramp_start_fraction, 0.25)
        self.assertAlmostEqual(latched.exponential_shape, 0.5)

if __name__ == '__main__':
    rospy.init_node('test_ventilator_stream')
    rostest.rosrun('pedicle_drilling', 'ventilator_stream', VentilatorStreamTest, sys.argv)
