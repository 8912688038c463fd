#!/usr/bin/python3
"""Scenario: fewer synchronised steps under the lockstep (StepAck.next_step).

This test is the only lockstep participant. Answering with next_step zero it is stepped at every
1 ms step. Answering with next_step = never, it sees only the steps at which the simulator
published one of its streams (every step it sees has a stream message of that stamp), far fewer
than the steps run (GroundTruth lockstep_steps < lockstep_steps_run). Answering with next_step =
its step + 7 ms, it sees a step at least every 7 ms, and the 7 ms gaps show the request is what
stepped it (the streams come every 100 ms here)."""
import sys
import threading
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped, WrenchStamped
from sensor_msgs.msg import JointState

from pedicle_drilling.msg import JointTrajectoryControllerState, StepAck
from simulator_events import StepParticipant

NEVER = rospy.Time(2**32 - 1, 999999999)
MS = 1000000  # ns


class NextStepTest(StepParticipant, unittest.TestCase):
    WAIT_BOUND_S = 60.0

    def setUp(self):
        self.mode = 'every'  # under self.cond: how this participant answers
        self.steps = []      # (mode it answered in, stamp in ns) of every step received
        self.stream_ns = set()
        self.stream_lock = threading.Lock()
        self.participate('/test_next_step')
        for topic, kind in [('/ft_sensor/wrench', WrenchStamped), ('/joint_states', JointState),
                            ('/tracker/marker_pose', PoseStamped),
                            ('/arm_controller/state', JointTrajectoryControllerState),
                            ('/feed_controller/state', JointTrajectoryControllerState)]:
            rospy.Subscriber(topic, kind, self.on_stream, queue_size=1000)

    def on_stream(self, msg):
        with self.stream_lock:
            self.stream_ns.add(msg.header.stamp.to_nsec())

    def on_truth(self, msg):
        self.on_stream(msg)
        super().on_truth(msg)

    def answer(self, stamp):
        with self.cond:
            mode = self.mode
            self.steps.append((mode, stamp.to_nsec()))
        ack = StepAck(stamp=stamp, node=self.node)
        if mode == 'never':
            ack.next_step = NEVER
        elif mode == 'seven':
            ack.next_step = stamp + rospy.Duration(0, 7 * MS)
        self.ack.publish(ack)

    def collect(self, mode, sim_s):
        """Answers in `mode` for sim_s of sim time; returns the steps answered in it."""
        with self.cond:
            self.mode = mode
            start = self.last_step.to_nsec()
        self.wait_for(lambda: self.last_step.to_nsec() > start + int(sim_s * 1e9), mode)
        with self.cond:
            # The first step after the switch was asked for by an answer in the previous mode.
            return [t for m, t in self.steps if m == mode and t > start][1:]

    def test_participants_step_when_they_need_to(self):
        self.join_lockstep()
        every = self.collect('every', 0.2)
        gaps = {b - a for a, b in zip(every, every[1:])}
        self.assertEqual(gaps, {MS}, 'next_step zero: stepped at every 1 ms step')

        never = self.collect('never', 2.0)
        span_ms = (never[-1] - never[0]) / MS
        self.assertGreater(span_ms, 1500.0)
        # Ten streams or so per 100 ms at most: far fewer steps than the 1 ms grid's.
        self.assertLess(len(never), 0.2 * span_ms, 'stepped where nothing was published')
        # Every step seen published a stream (their messages arrive on other connections: wait).
        missing = lambda: [t for t in never if t not in self.stream_ns]  # noqa: E731
        self.wait_for(lambda: not missing(), 'a stream message at every step seen', bound=10.0)

        seven = self.collect('seven', 1.0)
        gaps = [b - a for a, b in zip(seven, seven[1:])]
        self.assertTrue(all(MS <= g <= 7 * MS for g in gaps), 'a requested step was skipped')
        self.assertGreater(gaps.count(7 * MS), len(gaps) // 2, 'the requests stepped it')

        # The simulator counts the steps it waited at among those it ran.
        self.wait_for(lambda: self.truth.lockstep_steps_run > 0, 'the steps counted')
        with self.cond:
            truth = self.truth
        self.assertLess(truth.lockstep_steps, truth.lockstep_steps_run)


if __name__ == '__main__':
    rospy.init_node('test_simulator_lockstep_next_step')
    rostest.rosrun('pedicle_drilling', 'simulator_lockstep_next_step', NextStepTest, sys.argv)
