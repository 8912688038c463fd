#!/usr/bin/python3
"""hardware.launch with trajectory_interface:=action against the Simulator serving
FollowJointTrajectory (follow_joint_trajectory.test).

The first trial drills through the action interface: every segment is a goal on
<controller>/follow_joint_trajectory (none on <controller>/command), none rejected or aborted,
and the trial ends on the recognizer's stop in the inner cortex. The second trial's feed
controller aborts its goal while drilling (simulator/abort_controller, PATH_TOLERANCE_VIOLATED):
a controller fault, the planner stops and retracts with the reason naming the action and the
error code."""
import sys
import threading
import unittest

import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from trajectory_msgs.msg import JointTrajectory

from pedicle_drilling.msg import (FollowJointTrajectoryActionGoal,
                                  FollowJointTrajectoryActionResult, GroundTruth, StopCommand,
                                  TrialStatus)
from pedicle_drilling.srv import AbortController, StartTrial

SETTLE_S = 2.0  # sim time with the drives enabled before the first trial starts [s]
CONTROLLERS = ('arm_controller', 'feed_controller')


class FollowJointTrajectoryTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.lock = threading.Lock()
        cls.truth = []
        cls.stops = []
        cls.status = []
        cls.goals = {c: 0 for c in CONTROLLERS}
        cls.commands = {c: 0 for c in CONTROLLERS}
        cls.results = []
        cls.drives_enabled = threading.Event()
        cls.settled = threading.Event()
        cls.enabled_at = None
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, cls.on_truth, queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, cls.keep(cls.stops), queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, cls.keep(cls.status),
                         queue_size=100)
        for c in CONTROLLERS:
            rospy.Subscriber('/%s/follow_joint_trajectory/goal' % c,
                             FollowJointTrajectoryActionGoal, cls.count(cls.goals, c),
                             queue_size=100)
            rospy.Subscriber('/%s/command' % c, JointTrajectory, cls.count(cls.commands, c),
                             queue_size=100)
            rospy.Subscriber('/%s/follow_joint_trajectory/result' % c,
                             FollowJointTrajectoryActionResult,
                             cls.keep(cls.results, c), queue_size=1000)

    @classmethod
    def keep(cls, store, tag=None):
        def callback(msg):
            with cls.lock:
                store.append(msg if tag is None else (tag, msg))
        return callback

    @classmethod
    def count(cls, counts, name):
        def callback(_):
            with cls.lock:
                counts[name] += 1
        return callback

    @classmethod
    def on_truth(cls, msg):
        with cls.lock:
            cls.truth.append(msg)
        if msg.drives_halted:
            return
        cls.drives_enabled.set()
        t = msg.header.stamp.to_sec()
        if cls.enabled_at is None:
            cls.enabled_at = t
        elif t >= cls.enabled_at + SETTLE_S:
            cls.settled.set()

    def phases(self, since=0):
        with self.lock:
            return [s.phase_name for s in self.status[since:]]

    def start_trial(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        self.assertTrue(self.drives_enabled.wait(60.0), 'the drivers never heard the drill guard')
        self.assertTrue(self.settled.wait(120.0), 'sim time did not advance %.0f s' % SETTLE_S)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        # The compensated mode needs the ventilator's settings and phase: retry until accepted.
        res = None
        for _ in range(150):
            with self.lock:
                first = len(self.status)
            res = start(mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                        max_duration_s=60.0)
            if res.success:
                return first
            rospy.sleep(0.2)
        self.fail(res.message)

    def wait_for_end(self, since):
        while not rospy.is_shutdown():
            names = self.phases(since)
            if 'drilling' in names and names[-1] in ('done', 'failed'):
                return names
            rospy.sleep(0.1)
        return self.phases(since)

    def test_a_a_compensated_trial_drills_through_the_action(self):
        since = self.start_trial()
        names = self.wait_for_end(since)
        with self.lock:
            stops = list(self.stops)
            final = self.truth[-1]
            goals = dict(self.goals)
            commands = dict(self.commands)
            results = list(self.results)
        report = 'phases %r; stops %r; goals %r; commands %r; layer %s' % (
            names, [(s.source, s.reason) for s in stops], goals, commands, final.specimen_layer)
        sys.stdout.write('follow_joint_trajectory: %s\n' % report)
        self.assertEqual(names[-1], 'done', report)
        # The segments went as goals, to both controllers, and nothing on the command topics.
        for c in CONTROLLERS:
            self.assertGreater(goals[c], 20, report)
            self.assertEqual(commands[c], 0, report)
        # Every goal ended as a JointTrajectoryController's would: replaced (preempted) by the
        # next one or succeeded; none rejected or aborted.
        bad = [(c, r.status.status, r.result.error_code, r.result.error_string)
               for c, r in results
               if r.status.status not in (GoalStatus.PREEMPTED, GoalStatus.SUCCEEDED)]
        self.assertEqual(bad, [], report)
        self.assertGreater(len(results), 20, report)
        # The recognizer's stop, first, without retreat; the canal intact, the tip stopped in the
        # inner cortex.
        self.assertTrue(stops, report)
        self.assertIn('state_recognizer', stops[0].source, report)
        self.assertFalse(stops[0].retreat, report)
        self.assertFalse(final.breakthrough, report)
        self.assertGreater(final.max_depth_cut_m, final.inner_cortical_start_m, report)
        self.assertLess(final.max_depth_cut_m, final.inner_cortical_end_m, report)
        self.assertEqual(final.rejected_commands, 0, report)

    def test_b_an_aborted_goal_stops_the_trial_with_retreat(self):
        with self.lock:
            stops_before = len(self.stops)
        since = self.start_trial()
        # 1 mm into the bone while drilling: the feed controller aborts its goal.
        while not rospy.is_shutdown():
            with self.lock:
                deep = self.truth[-1].max_depth_cut_m if self.truth else 0.0
            if 'drilling' in self.phases(since) and deep > 0.001:
                break
            rospy.sleep(0.02)
        abort = rospy.ServiceProxy('/simulator/abort_controller', AbortController)
        res = abort(controller='feed_controller')
        self.assertTrue(res.success, res.message)
        names = self.wait_for_end(since)
        with self.lock:
            stops = list(self.stops[stops_before:])
            final = self.truth[-1]
        report = 'phases %r; stops %r' % (names, [(s.source, s.reason) for s in stops])
        sys.stdout.write('follow_joint_trajectory abort: %s\n' % report)
        self.assertTrue(stops, report)
        fault = stops[0]
        self.assertIn('compensation_planner', fault.source, report)
        self.assertTrue(fault.retreat, report)
        self.assertIn('feed_controller/follow_joint_trajectory aborted a goal', fault.reason,
                      report)
        self.assertIn('PATH_TOLERANCE_VIOLATED', fault.reason, report)
        self.assertIn('retreating', names, report)
        self.assertIn(names[-1], ('done', 'failed'), report)
        self.assertFalse(final.breakthrough, report)


if __name__ == '__main__':
    rospy.init_node('test_follow_joint_trajectory')
    rostest.rosrun('pedicle_drilling', 'follow_joint_trajectory', FollowJointTrajectoryTest,
                   sys.argv)
