#!/usr/bin/python3
"""Generic scenario check: a nodelet given a bad parameter logs an error naming it and
publishes nothing on its output topic (a safe state)."""
import sys
import threading
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rosgraph_msgs.msg import Log
import roslib.message


class BadParameterTest(unittest.TestCase):
    def test_error_names_parameter_and_nothing_published(self):
        expected = rospy.get_param('~expected_error')
        topic = rospy.get_param('~topic')
        topic_type = roslib.message.get_message_class(rospy.get_param('~topic_type'))
        lock = threading.Lock()
        errors = []
        published = []

        def on_log(msg):
            if msg.level >= Log.ERROR:
                with lock:
                    errors.append(msg.msg)

        def on_diagnostics(msg):
            with lock:
                errors.extend(s.message for s in msg.status if s.level >= DiagnosticStatus.ERROR)

        # The startup failure is latched on /diagnostics, so subscribing late still sees it.
        rospy.Subscriber('/diagnostics', DiagnosticArray, on_diagnostics, queue_size=100)
        rospy.Subscriber('/rosout_agg', Log, on_log, queue_size=100)
        rospy.Subscriber('/rosout', Log, on_log, queue_size=100)
        rospy.Subscriber(topic, topic_type, lambda m: published.append(m), queue_size=10)
        deadline = rospy.Time.now() + rospy.Duration(20.0)
        found = False
        while rospy.Time.now() < deadline and not found:
            with lock:
                found = any(expected in e for e in errors)
            rospy.sleep(0.2)
        self.assertTrue(found, 'no error naming %r; errors seen: %r' % (expected, errors))
        rospy.sleep(2.0)
        self.assertEqual(published, [], 'a misconfigured nodelet must not publish')


if __name__ == '__main__':
    rospy.init_node('test_bad_parameters')
    rostest.rosrun('pedicle_drilling', 'bad_parameters', BadParameterTest, sys.argv)
