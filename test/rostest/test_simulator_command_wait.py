#!/usr/bin/python3
"""Scenario: sim time waits for the planner's next trajectory (Simulator ~command_wait_s).

With compensation/status at DRILLING, the simulator stops at the end of the last arm trajectory
it received; a following trajectory lets it go on, and so does a status that leaves the
streaming phases (DONE). The ground truth counts the waits and the trajectories that arrived
after their own start."""
import sys
import time
import unittest

import rospy
import rostest
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from pedicle_drilling.msg import TrialStatus
from simulator_events import SimulatorEvents

STEP = 1e-3  # the simulator's physics step


class CommandWaitTest(SimulatorEvents, unittest.TestCase):
    def setUp(self):
        self.watch_simulator()
        self.command = rospy.Publisher('/feed_controller/command', JointTrajectory, queue_size=10)
        self.status = rospy.Publisher('/compensation/status', TrialStatus, queue_size=10,
                                      latch=True)

    def publish_status(self, phase):
        msg = TrialStatus()
        msg.header.stamp = rospy.Time.from_sec(self.clock)
        msg.phase = phase
        self.status.publish(msg)

    def trajectory(self, start, duration, feed):
        """A feed_joint trajectory stamped `start` (rospy.Time), one point `duration` s later."""
        traj = JointTrajectory()
        traj.header.stamp = start
        traj.joint_names = ['feed_joint']
        point = JointTrajectoryPoint()
        point.positions = [feed]
        point.time_from_start = rospy.Duration.from_sec(duration)
        traj.points.append(point)
        return traj

    def test_sim_time_waits_for_the_next_trajectory(self):
        self.wait_for(lambda: self.clock is not None and self.truth is not None, 'simulator up')
        deadline = time.monotonic() + 20.0
        while (self.command.get_num_connections() == 0 or
               self.status.get_num_connections() == 0) and time.monotonic() < deadline:
            time.sleep(0.05)
        self.publish_status(TrialStatus.DRILLING)
        # The first trajectory starts 1 s of sim time ahead and ends 3 s ahead (0.75 s of wall
        # time at the real-time factor): the simulator has it before its end even on a loaded
        # machine. Whether it also arrived before its start is not this test's question: the
        # late-command count is compared with its value once the simulator waits.
        with self.cond:
            start_stamp = self.clock_stamp + rospy.Duration(1.0)
        end_stamp = start_stamp + rospy.Duration(2.0)
        end = end_stamp.to_sec()
        self.command.publish(self.trajectory(start_stamp, 2.0, 0.002))
        # The simulator reaches the trajectory's end and waits there.
        self.wait_for(lambda: self.clock >= end - 0.01, 'clock near the trajectory end')
        time.sleep(1.0)  # 4 s of sim time at the real-time factor, were it not waiting
        with self.cond:
            stalled = self.clock
        self.assertLessEqual(stalled, end + STEP + 1e-9, 'sim time ran past the last trajectory')
        # The last ground truth before the wait (it comes every 10 ms of sim time).
        self.wait_for(lambda: self.truth.header.stamp.to_sec() >= stalled - 0.01 - STEP,
                      'ground truth')
        with self.cond:
            late_before = self.truth.late_commands
        # The next trajectory, sent in time: sim time goes on, nothing was late.
        self.command.publish(self.trajectory(end_stamp, 0.3, 0.004))
        self.wait_for(lambda: self.clock > end + 0.1, 'clock past the first trajectory')
        self.wait_for(lambda: self.truth.header.stamp.to_sec() > end + 0.1, 'ground truth')
        with self.cond:
            truth = self.truth
        self.assertGreaterEqual(truth.command_waits, 1)
        self.assertGreater(truth.command_wait_wall_s, 0.5)
        self.assertEqual(truth.command_wait_expired, 0)
        self.assertEqual(truth.late_commands, late_before)
        # Leaving the streaming phases releases sim time past the second trajectory's end.
        self.publish_status(TrialStatus.DONE)
        self.wait_for(lambda: self.clock > end + 0.3 + 0.5, 'clock past the second trajectory')
        # A trajectory whose start has passed is counted, with its lateness.
        with self.cond:
            late_start = self.clock_stamp - rospy.Duration(0.5)
        self.command.publish(self.trajectory(late_start, 1.0, 0.003))
        self.wait_for(lambda: self.truth.late_commands > late_before, 'late command counted')
        with self.cond:
            truth = self.truth
        self.assertEqual(truth.late_commands, late_before + 1)
        # At least the 0.5 s it was stamped before the clock; at most the sim time from its
        # stamp to the ground truth that counted it (whatever the machine's load).
        self.assertGreaterEqual(truth.max_command_lateness_s, 0.5)
        if late_before == 0:  # else the maximum may be the first trajectory's
            self.assertLessEqual(truth.max_command_lateness_s,
                                 (truth.header.stamp - late_start).to_sec() + STEP)


if __name__ == '__main__':
    rospy.init_node('test_simulator_command_wait')
    rostest.rosrun('pedicle_drilling', 'simulator_command_wait', CommandWaitTest, sys.argv)
