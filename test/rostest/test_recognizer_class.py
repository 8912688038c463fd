#!/usr/bin/python3
"""Scenario: the StateRecognizer nodelet runs the class its ~recognizer names. Fed a
vertebra-like thrust profile at 1 kHz (air, outer cortex 3.5 N, cancellous 1.2 N, inner cortex
4 N, canal), the force-difference baseline must send exactly one StopCommand (retreat = false)
with its own reason, after the second fall of the force, and publish drilling_state."""
import sys
import threading
import unittest

import rospy
import rostest
from geometry_msgs.msg import WrenchStamped

from pedicle_drilling.msg import DrillingState, StopCommand

LEVELS = [(1.0, 0.0), (4.0, 3.5), (4.0, 1.2), (3.0, 4.0), (1.0, 0.0)]  # (s, N)
SECOND_FALL_S = 12.0


class RecognizerClassTest(unittest.TestCase):
    def test_the_named_class_runs_in_the_nodelet(self):
        lock = threading.Lock()
        stops, states = [], []
        rospy.Subscriber('/drill/stop', StopCommand, lambda m: stops.append(m), queue_size=10)
        rospy.Subscriber('/drilling_state', DrillingState, lambda m: states.append(m),
                         queue_size=1000)
        pub = rospy.Publisher('/ft_sensor/wrench', WrenchStamped, queue_size=5000)
        while pub.get_num_connections() == 0 and not rospy.is_shutdown():  # event: subscribed
            rospy.sleep(0.05)
        t = 0.0
        for seconds, level in LEVELS:
            for _ in range(int(seconds * 1000)):
                msg = WrenchStamped()
                msg.header.stamp = rospy.Time.from_sec(1000.0 + t)
                msg.wrench.force.z = level
                pub.publish(msg)
                t += 1e-3
                if int(t * 1000) % 200 == 0:
                    rospy.sleep(0.01)  # let the transport keep up (the queue holds 1000)
        # Event: the last sample's state came back (one state per 50 samples).
        deadline = rospy.Time.now() + rospy.Duration(30.0)
        while rospy.Time.now() < deadline:
            with lock:
                if states and states[-1].header.stamp.to_sec() >= 1000.0 + t - 0.06:
                    break
            rospy.sleep(0.05)
        rospy.sleep(0.5)  # a second stop, were there one, would be on its way
        self.assertEqual(len(stops), 1, [s.reason for s in stops])
        stop = stops[0]
        self.assertFalse(stop.retreat)
        self.assertIn('force-difference breakthrough 2', stop.reason)
        stop_t = stop.header.stamp.to_sec() - 1000.0
        self.assertGreater(stop_t, SECOND_FALL_S)
        self.assertLess(stop_t, SECOND_FALL_S + 0.5)
        self.assertGreater(len(states), 200)
        self.assertEqual(states[-1].state_name, 'stopped')


if __name__ == '__main__':
    rospy.init_node('test_recognizer_class')
    rostest.rosrun('pedicle_drilling', 'recognizer_class', RecognizerClassTest, sys.argv)
