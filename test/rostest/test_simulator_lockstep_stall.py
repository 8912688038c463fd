#!/usr/bin/python3
"""Scenario: a stall of the machine is not a participant's lateness (core::WaitDeadline).

This test is a lockstep participant. It withholds its answer to one step; while the simulator
waits for it, the simulator's process is stopped for 3 s (three times ~lockstep_timeout_s) and
continued; the answer follows 0.3 s later. The simulator, which did not run during the stop,
moves its deadline by the stall: no timeout is counted and the participant is not dropped."""
import os
import signal
import sys
import time
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest

from simulator_events import StepParticipant

NODE = '/test_participant'


def process_publishing(topic):
    """The pid of the process whose node publishes `topic` (the simulator's nodelet manager)."""
    master = rosgraph.Master('/test_simulator_lockstep_stall')
    publishers, _, _ = master.getSystemState()
    nodes = [nodes for name, nodes in publishers if name == topic][0]
    uri = master.lookupNode(nodes[0])
    _, _, pid = xmlrpc.client.ServerProxy(uri).getPid('/test_simulator_lockstep_stall')
    return pid


class LockstepStallTest(StepParticipant, unittest.TestCase):
    def setUp(self):
        self.participate(NODE)

    def test_a_stall_is_not_a_timeout(self):
        first = self.join_lockstep()
        self.wait_for(lambda: self.truth.header.stamp.to_sec() > first + 0.05, 'ground truth')
        self.assertEqual(self.truth.lockstep_timeouts, 0)
        pid = process_publishing('/simulator/step')
        self.assertNotEqual(pid, os.getpid())
        with self.cond:
            self.answering = False
        # The simulator now waits for our answer to this step: stop its process at once.
        self.wait_for(lambda: self.unanswered is not None, 'a step to withhold')
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(3.0)  # the stall itself (three lockstep timeouts), not a wait on an event
        finally:
            os.kill(pid, signal.SIGCONT)
        time.sleep(0.3)  # the answer comes well within the timeout of the running process
        with self.cond:
            self.answering = True
            stamp = self.unanswered
        self.answer(stamp)
        self.wait_for(lambda: self.last_step.to_sec() > stamp.to_sec() + 0.1, 'stepping on')
        self.wait_for(lambda: self.truth.header.stamp.to_sec() > stamp.to_sec() + 0.1,
                      'ground truth after the stall')
        self.assertEqual(self.truth.lockstep_timeouts, 0,
                         'the stall of the simulator\'s own process was counted as a timeout')


if __name__ == '__main__':
    rospy.init_node('test_simulator_lockstep_stall')
    rostest.rosrun('pedicle_drilling', 'simulator_lockstep_stall', LockstepStallTest, sys.argv)
