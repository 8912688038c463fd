#!/usr/bin/python3
"""The Ventilator nodelet on sim time: the test publishes /clock (real-time pace, wall-clock
sleeps), checks that the stream follows it, then jumps the clock back and checks that a new
breath starts at the new time with a valid time in breath and volume."""
import sys
import threading
import time
import unittest

import rospy
import rostest
from rosgraph_msgs.msg import Clock

from pedicle_drilling.msg import TidalVolume

INSPIRATORY_TIME = 5.0 / 3.0


class VentilatorSimTimeTest(unittest.TestCase):
    def test_stream_follows_the_clock_and_survives_a_jump_back(self):
        lock = threading.Lock()
        samples = []

        def keep(msg):
            with lock:
                samples.append(msg)

        clock = rospy.Publisher('/clock', Clock, queue_size=10)
        rospy.Subscriber('/tidal_volume', TidalVolume, keep, queue_size=1000)

        def run_clock(start, seconds):
            t = start
            while t < start + seconds:
                clock.publish(Clock(clock=rospy.Time.from_sec(t)))
                t += 0.005
                time.sleep(0.005)

        run_clock(100.0, 2.0)  # let the nodelet and the subscriptions come up
        with lock:
            del samples[:]
        run_clock(102.0, 6.0)
        with lock:
            before = list(samples)
            del samples[:]
        self.assertGreater(len(before), 100, 'no stream on sim time')
        self.assertTrue(all(102.0 - 0.05 <= m.header.stamp.to_sec() <= 108.0 for m in before))
        span = before[-1].header.stamp.to_sec() - before[0].header.stamp.to_sec()
        self.assertAlmostEqual((len(before) - 1) / span, 64.0, delta=6.0)
        last_index = before[-1].breath_index

        run_clock(50.0, 4.0)  # time jumps back by 58 s
        with lock:
            after = [m for m in samples if m.header.stamp.to_sec() < 60.0]
        self.assertGreater(len(after), 100, 'no stream after the jump back')
        self.assertGreater(after[0].breath_index, last_index)
        for msg in after:
            tau = msg.time_in_breath_s
            self.assertGreaterEqual(tau, 0.0)
            self.assertLess(tau, 5.0 + 1e-6)
            if tau < INSPIRATORY_TIME - 1e-6:
                self.assertAlmostEqual(msg.volume_ml, 300.0 * tau, delta=1e-3)
        # The new breath starts at the first sample after the jump.
        self.assertLess(after[0].time_in_breath_s, 0.05)


if __name__ == '__main__':
    rospy.init_node('test_ventilator_sim_time')
    rostest.rosrun('pedicle_drilling', 'ventilator_sim_time', VentilatorSimTimeTest, sys.argv)
