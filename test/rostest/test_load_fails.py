#!/usr/bin/python3
"""Generic scenario check: a nodelet given a bad parameter fails its load. Started by hand as
`nodelet standalone` and as `nodelet load` into a running manager, each process exits non-zero
(waits for the process to end, not for a time); the manager's latched /diagnostics names the
parameter, and the manager is still there to load a good one. Optional ~good_parameters: a
mapping of other private parameters the nodelet needs to get as far as the bad one."""
import subprocess
import sys
import threading
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nodelet.srv import NodeletList


def run_nodelet(command, node_name, *extra):
    parameter = rospy.get_param('~bad_parameter')
    value = rospy.get_param('~bad_value')
    args = ['rosrun', 'nodelet', 'nodelet', command, rospy.get_param('~nodelet_type')]
    args += list(extra) + ['__name:=' + node_name, '_%s:=%s' % (parameter, value)]
    args += ['_%s:=%s' % item for item in sorted(rospy.get_param('~good_parameters', {}).items())]
    return subprocess.run(args, capture_output=True, text=True, timeout=60)


class LoadFailsTest(unittest.TestCase):
    def test_standalone_exits_non_zero_naming_the_parameter(self):
        out = run_nodelet('standalone', 'bad_standalone')
        self.assertNotEqual(out.returncode, 0, out.stdout + out.stderr)
        self.assertIn(rospy.get_param('~bad_parameter'), out.stdout + out.stderr)

    def test_load_into_a_manager_exits_non_zero_and_the_manager_reports_it(self):
        manager = rospy.get_param('~manager')
        rospy.wait_for_service(manager + '/list', timeout=60.0)
        lock = threading.Lock()
        errors = []
        seen = threading.Event()
        parameter = rospy.get_param('~bad_parameter')

        def on_diagnostics(msg):
            with lock:
                for s in msg.status:
                    if s.level >= DiagnosticStatus.ERROR and s.name.startswith('/bad_loaded'):
                        errors.append(s.message)
                        if parameter in s.message:
                            seen.set()

        sub = rospy.Subscriber('/diagnostics', DiagnosticArray, on_diagnostics, queue_size=10)
        out = run_nodelet('load', 'bad_loaded', manager)
        self.assertNotEqual(out.returncode, 0, out.stdout + out.stderr)
        # Latched by the manager: seen even though the subscription may come after the failure.
        self.assertTrue(seen.wait(timeout=60.0), 'no /diagnostics error naming %r: %r'
                        % (parameter, errors))
        sub.unregister()
        loaded = rospy.ServiceProxy(manager + '/list', NodeletList)().nodelets
        self.assertNotIn('/bad_loaded', loaded)


if __name__ == '__main__':
    rospy.init_node('test_load_fails')
    rostest.rosrun('pedicle_drilling', 'load_fails', LoadFailsTest, sys.argv)
