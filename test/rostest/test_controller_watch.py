#!/usr/bin/python3
"""The planner's closed loop on the arm's controllers, on the simulated pipeline
(drilling_pipeline.launch sim:=true, seed 5, compensated): each case makes a controller depart
from what the planner commanded and requires a stop from the planner with the controller watch's
reason (~expect, a substring), announced on drill/stop with retreat = true.

~case:
  foreign_joints    the planner is configured for one combined 7-joint controller (its
                    feed_controller = arm_controller) while the simulator has separate arm and feed
                    controllers, whose messages would be refused (their joints are not the
                    controller's set): the controller's state names its own joints, so the planner
                    refuses the trial before anything moves, naming the mismatch (a stricter
                    safe state than a stop: no command is sent).
  trajectory_ended  when the drilling starts (the tool still free: the slow path must be the only
                    thing that stops the trial), every command reaches the controllers 0.6 s late (the FaultInjector's command_delayed for ~command_fault_count
                    commands): each drilling segment arrives after its own last point and the
                    controller drops it (ros_control's rule); the arm stays behind the commanded
                    motion, the planner stops and retreats.
  following_error   when the drilling starts (the tool still free: the stall must be the only
                    thing that stops the trial), the feed drive stalls (simulator/stall_joint): the
                    feed controller's error grows with the commanded feed past its tolerance, the
                    planner stops and retreats.
"""
import sys
import threading
import unittest

import rospy
import rostest

from pedicle_drilling.msg import GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import InjectFault, StallJoint, StartTrial
from simulator_events import start_trial


class ControllerWatchTest(unittest.TestCase):
    def test_case(self):
        case = rospy.get_param('~case')
        expect = rospy.get_param('~expect')
        lock = threading.Lock()
        truth, stops, status = [], [], []
        drilling = threading.Event()
        ended = threading.Event()
        stopped = threading.Event()

        def on_truth(msg):
            with lock:
                truth.append(msg)

        def on_stop(msg):
            with lock:
                stops.append(msg)
            stopped.set()

        def on_status(msg):
            with lock:
                status.append(msg.phase_name)
            if msg.phase_name == 'drilling':
                drilling.set()
            if msg.phase_name in ('done', 'failed'):
                ended.set()

        rospy.Subscriber('/simulator/ground_truth', GroundTruth, on_truth, queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, on_stop, queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, on_status, queue_size=100)
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, lambda r: case == 'foreign_joints' and expect in r.message,
                          mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        if case == 'foreign_joints':
            self.assertFalse(res.success, 'a trial started on mismatched controllers')
            self.assertIn(expect, res.message)
            with lock:
                self.assertEqual(stops, [])
                self.assertTrue(all(p in ('idle',) for p in status), status)
            return
        self.assertTrue(res.success, res.message)
        if case == 'trajectory_ended':
            rospy.wait_for_service('/fault_injector/inject', 60.0)
            self.assertTrue(drilling.wait(120.0), 'the drilling never started')
            answer = rospy.ServiceProxy('/fault_injector/inject', InjectFault)(
                fault='command_delayed')
            self.assertTrue(answer.success, answer.message)
        elif case == 'following_error':
            rospy.wait_for_service('/simulator/stall_joint', 60.0)
            self.assertTrue(drilling.wait(120.0), 'the drilling never started')
            answer = rospy.ServiceProxy('/simulator/stall_joint', StallJoint)(
                joint='feed_joint', stalled=True)
            self.assertTrue(answer.success, answer.message)
        self.assertTrue(ended.wait(180.0), 'the trial did not end')
        self.assertTrue(stopped.wait(30.0), 'no stop announced on drill/stop')
        with lock:
            seen_stops = list(stops)
            phases = list(status)
            last_truth = truth[-1] if truth else None
        self.assertTrue(seen_stops, 'no stop; phases %s' % phases)
        first = seen_stops[0]
        report = '%s: first stop from %s: %s; phases %s' % (case, first.source, first.reason,
                                                             phases[-4:])
        sys.stdout.write(report + '\n')
        self.assertIn('compensation_planner', first.source, report)
        self.assertIn(expect, first.reason, report)
        self.assertTrue(first.retreat, report)
        self.assertIsNotNone(last_truth)
        self.assertFalse(last_truth.breakthrough, report)
        self.assertIn('retreating', phases, report)
        self.assertEqual(phases[-1], 'done', report)
        if case == 'trajectory_ended':
            self.assertGreater(last_truth.rejected_commands, 0, report)


if __name__ == '__main__':
    rospy.init_node('test_controller_watch')
    rostest.rosrun('pedicle_drilling', 'controller_watch', ControllerWatchTest, sys.argv)
