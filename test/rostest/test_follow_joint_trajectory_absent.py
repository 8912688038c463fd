#!/usr/bin/python3
"""hardware.launch with trajectory_interface:=action, no FollowJointTrajectory server
(follow_joint_trajectory_absent.test): the trial is refused naming the missing action, within
action_server_timeout_s, and nothing was started."""
import sys
import time
import unittest

import rospy
import rostest

from pedicle_drilling.msg import TrialStatus
from pedicle_drilling.srv import StartTrial


class FollowJointTrajectoryAbsentTest(unittest.TestCase):
    def test_a_trial_is_refused_naming_the_action(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        began = time.monotonic()
        res = start(mode='stationary', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                    max_duration_s=30.0)
        waited = time.monotonic() - began
        self.assertFalse(res.success, res.message)
        self.assertIn('no action server /arm_controller/follow_joint_trajectory', res.message)
        self.assertIn('nothing was started', res.message)
        # action_server_timeout_s 1.0 of wall time (with the service call's own time).
        self.assertGreaterEqual(waited, 0.9, res.message)
        self.assertLess(waited, 30.0, res.message)
        status = rospy.wait_for_message('/compensation/status', TrialStatus, 10.0)
        self.assertEqual(status.phase_name, 'idle')


if __name__ == '__main__':
    rospy.init_node('test_follow_joint_trajectory_absent')
    rostest.rosrun('pedicle_drilling', 'follow_joint_trajectory_absent',
                   FollowJointTrajectoryAbsentTest, sys.argv)
