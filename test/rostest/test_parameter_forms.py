#!/usr/bin/python3
"""Generic scenario check: nodelets given a parameter in an accepted form start (their service
appears), and those given a refused form report an error naming the parameter (latched on
/diagnostics). Waits on the events themselves, not on time."""
import sys
import threading
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus


class ParameterFormsTest(unittest.TestCase):
    def test_accepted_forms_start_and_refused_forms_name_the_parameter(self):
        services = rospy.get_param('~started_services')
        refused = rospy.get_param('~refused')
        parameter = rospy.get_param('~refused_parameter')
        for name in services:
            rospy.wait_for_service(name, timeout=60.0)
        lock = threading.Lock()
        errors = []
        done = threading.Event()

        def on_diagnostics(msg):
            with lock:
                errors.extend(s.name + ' ' + s.message for s in msg.status
                              if s.level >= DiagnosticStatus.ERROR)
                if all(any(r in e and parameter in e for e in errors) for r in refused):
                    done.set()

        sub = rospy.Subscriber('/diagnostics', DiagnosticArray, on_diagnostics, queue_size=100)
        done.wait(timeout=60.0)
        sub.unregister()
        with lock:
            for r in refused:
                self.assertTrue(any(r in e and parameter in e for e in errors),
                                'no error from %r naming %r; errors seen: %r'
                                % (r, parameter, errors))
            for name in services:
                node = name.split('/')[1]
                self.assertFalse(any(e.startswith('/' + node + ':') for e in errors),
                                 '%s started but reported %r' % (node, errors))


if __name__ == '__main__':
    rospy.init_node('test_parameter_forms')
    rostest.rosrun('pedicle_drilling', 'parameter_forms', ParameterFormsTest, sys.argv)
