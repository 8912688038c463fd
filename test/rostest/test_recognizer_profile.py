#!/usr/bin/python3
"""Scenario check: the StateRecognizer nodelet fed a synthetic two-layer thrust profile at 1 kHz
(optionally with NaN samples) publishes DrillingState on every averaged sample, recognises the key
points in order and sends exactly one StopCommand (retreat = false) between key points 4 and 6."""
import math
import random
import sys
import threading
import unittest

import rospy
import rostest
from geometry_msgs.msg import WrenchStamped
from rosgraph_msgs.msg import Log
from std_srvs.srv import Trigger

from pedicle_drilling.msg import DrillingState, StopCommand

# Layer boundaries of the synthetic profile (s): air, outer cortical hump (3 N), cancellous
# plateau (0.7 N), inner cortical hump (3 N), breakthrough.
INNER_CONTACT_S = 16.0
BREAKTHROUGH_S = 19.5
DURATION_S = 21.0


def clean_force(t):
    if t < 2.0:
        return 0.0
    if t < 4.0:
        return 1.5 * (t - 2.0)
    if t < 5.0:
        return 3.0
    if t < 6.0:
        return 3.0 - 2.3 * (t - 5.0)
    if t < INNER_CONTACT_S:
        return 0.7
    if t < 18.0:
        return 0.7 + 1.15 * (t - INNER_CONTACT_S)
    if t < BREAKTHROUGH_S:
        return 3.0
    return 0.1


class RecognizerProfileTest(unittest.TestCase):
    def test_key_points_in_order_and_one_stop(self):
        nan_every = rospy.get_param('~nan_every', 0)
        lock = threading.Lock()
        states = []
        stops = []
        warnings = []

        def on_state(msg):
            with lock:
                states.append(msg)

        def on_stop(msg):
            with lock:
                # Remember which states had been seen when the stop arrived.
                stops.append((msg, len(states)))

        def on_log(msg):
            if msg.level >= Log.WARN and 'non-finite' in msg.msg:
                with lock:
                    warnings.append(msg.msg)

        rospy.Subscriber('/drilling_state', DrillingState, on_state, queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, on_stop, queue_size=10)
        rospy.Subscriber('/rosout_agg', Log, on_log, queue_size=100)
        rospy.Subscriber('/rosout', Log, on_log, queue_size=100)
        pub = rospy.Publisher('/ft_sensor/wrench', WrenchStamped, queue_size=25000)
        deadline = rospy.Time.now() + rospy.Duration(20.0)
        while pub.get_num_connections() == 0 and rospy.Time.now() < deadline:
            rospy.sleep(0.1)
        self.assertGreater(pub.get_num_connections(), 0, 'recognizer not subscribed')
        rospy.sleep(0.5)

        rng = random.Random(5)
        n = int(DURATION_S * 1000)
        t0 = 1000.0
        sent = 0
        nan_sent = 0
        rate = rospy.Rate(100)  # bursts of 10 samples every 10 ms = 1 kHz
        for i in range(n):
            t = i * 1e-3
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(t0 + t)
            msg.header.frame_id = 'ft_sensor'
            msg.wrench.force.z = clean_force(t) + rng.gauss(0.0, 0.05)
            if nan_every and i % nan_every == nan_every - 1:
                msg.wrench.force.z = float('nan')
                nan_sent += 1
            pub.publish(msg)
            sent += 1
            if i % 10 == 9:
                rate.sleep()
        # Wait for the event, not for a time: every averaged sample's state has arrived (the
        # bound only ends a broken run).
        expected = (sent - nan_sent) // 50
        deadline = rospy.Time.now() + rospy.Duration(60.0)
        while rospy.Time.now() < deadline:
            with lock:
                if len(states) >= expected and stops:
                    break
            rospy.sleep(0.05)

        with lock:
            states_seen = list(states)
            stops_seen = list(stops)
        valid = sent - nan_sent
        # One DrillingState per averaged sample of 50 valid raw samples.
        self.assertGreaterEqual(len(states_seen), valid // 50 - 2)
        self.assertLessEqual(len(states_seen), valid // 50 + 1)
        # Key points in order: last_key_point never decreases and passes 2, 3, 4 (key point 1 is
        # recognised retrospectively together with 2); it freezes at the stop's key point.
        kps = [s.last_key_point for s in states_seen]
        self.assertEqual(kps, sorted(kps), 'key points went backwards')
        distinct = sorted(set(kps) - {0})
        self.assertIn(distinct, ([2, 3, 4], [2, 3, 4, 5]), 'key points seen: %r' % distinct)
        # Exactly one stop, no retreat, at key point 4 or 5.
        self.assertEqual(len(stops_seen), 1, 'stops: %r' % [s[0].reason for s in stops_seen])
        stop, _ = stops_seen[0]
        self.assertFalse(stop.retreat)
        self.assertIn('key point', stop.reason)
        first = next(i for i, s in enumerate(states_seen) if s.stop)
        first_stop_state = states_seen[first]
        self.assertIn(first_stop_state.last_key_point, (4, 5))
        # From the stop on, the state says stopped at the stop's key point, whatever the force
        # does next; the layer the force shows goes on to the breakthrough (key point 6).
        after_stop = states_seen[first:]
        self.assertTrue(all(s.stop for s in after_stop))
        self.assertEqual({s.state for s in after_stop}, {DrillingState.STOPPED})
        self.assertEqual({s.state_name for s in after_stop}, {'stopped'})
        self.assertEqual({s.last_key_point for s in after_stop},
                         {first_stop_state.last_key_point})
        self.assertEqual(after_stop[-1].layer_state, DrillingState.BREAKTHROUGH)
        self.assertTrue(all(s.state == s.layer_state for s in states_seen[:first]))
        stop_t = stop.header.stamp.to_sec() - t0
        self.assertGreater(stop_t, INNER_CONTACT_S)
        self.assertLess(stop_t, BREAKTHROUGH_S)
        self.assertAlmostEqual(first_stop_state.stop_time - t0, stop_t, delta=1e-6)
        if nan_every:
            self.assertTrue(warnings, 'no warning about the non-finite samples')
        # ~reset returns the recognizer to idle.
        rospy.wait_for_service('/state_recognizer/reset', 10.0)
        with lock:
            count = len(states)
        self.assertTrue(rospy.ServiceProxy('/state_recognizer/reset', Trigger)().success)
        for i in range(60):
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(t0 + 100.0 + i * 1e-3)
            pub.publish(msg)
        # The reset publishes a state at once, and the 60 samples one more (pre-average 50).
        deadline = rospy.Time.now() + rospy.Duration(30.0)
        while rospy.Time.now() < deadline:
            with lock:
                if len(states) >= count + 2:
                    break
            rospy.sleep(0.05)
        with lock:
            after = states[count:]
        self.assertGreaterEqual(len(after), 2, 'states after reset: %r' % after)
        self.assertEqual(after[-1].state, DrillingState.IDLE)
        self.assertFalse(after[-1].stop)


if __name__ == '__main__':
    rospy.init_node('test_recognizer_profile')
    rostest.rosrun('pedicle_drilling', 'recognizer_profile', RecognizerProfileTest, sys.argv)
