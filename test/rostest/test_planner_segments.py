#!/usr/bin/python3
"""Scenario check of the CompensationPlanner against the real Ventilator nodelet and a synthetic
tracker: trial sequence, 125 ms trapezoidal segments, feed targets with (compensated) and without
(uncompensated) the predicted AP displacement, the predicted marker pose, and the stops (hold, or
retreat along the drill axis)."""
import bisect
import math
import sys
import threading
import unittest

import rospy
import rostest
import yaml
from geometry_msgs.msg import PoseStamped
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory

from pedicle_drilling.msg import StopCommand, TidalVolume, TrialStatus
from pedicle_drilling.srv import StartTrial

FEED_HOME = 0.01       # config/compensation_planner.yaml feed_home_m
FEED_RATE = 0.5e-3     # m/s
PERIOD = 0.125


def retracts(traj):
    """True for a trajectory that takes the feed back (a retreat; segments only advance)."""
    return traj.points[-1].positions[-1] < traj.points[0].positions[-1] - 1e-6


class PlannerSegmentsTest(unittest.TestCase):
    def setUp(self):
        with open(rospy.get_param('~patient_model')) as handle:
            self.q1_ap = yaml.safe_load(handle)['axes']['ap']['q1'] * 1e-3  # m/ml
        self.lock = threading.Lock()
        self.trajectories = []
        self.status = []
        self.spindle = []
        self.predicted = []
        self.tv_t = []
        self.tv = []
        self.marker_stamps = []
        rospy.Subscriber('/arm_controller/command', JointTrajectory, self.keep(self.trajectories),
                         queue_size=100)
        rospy.Subscriber('/compensation/status', TrialStatus, self.keep(self.status),
                         queue_size=100)
        rospy.Subscriber('/spindle/command', Float64, self.keep(self.spindle), queue_size=10)
        rospy.Subscriber('/compensation/predicted_marker_pose', PoseStamped,
                         self.keep(self.predicted), queue_size=100)
        rospy.Subscriber('/tidal_volume', TidalVolume, self.on_tv, queue_size=1000)
        self.marker_pub = rospy.Publisher('/tracker/marker_pose', PoseStamped, queue_size=10)
        self.stop_pub = rospy.Publisher('/drill/stop', StopCommand, queue_size=10)
        rospy.Timer(rospy.Duration(0.125), self.publish_marker)
        rospy.wait_for_service('/compensation_planner/start_trial', 30.0)
        self.start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        # The latched status (idle) arrives once the subscription is connected: wait for it, so
        # that no trial's status is sent while the connection is being made (a status published
        # then came twice: once latched, once live).
        deadline = rospy.Time.now() + rospy.Duration(30.0)  # bounds a broken run only
        while self.status_count() == 0 and rospy.Time.now() < deadline:
            rospy.sleep(0.02)
        self.assertGreater(self.status_count(), 0, 'no latched compensation/status')

    def keep(self, store):
        def callback(msg):
            with self.lock:
                store.append(msg)
        return callback

    def on_tv(self, msg):
        with self.lock:
            self.tv_t.append(msg.header.stamp.to_sec())
            self.tv.append(msg.volume_ml)

    def tv_at(self, t):
        with self.lock:
            i = bisect.bisect_left(self.tv_t, t)
            self.assertTrue(0 < i < len(self.tv_t), 'no tidal volume around %.3f' % t)
            t0, t1 = self.tv_t[i - 1], self.tv_t[i]
            v0, v1 = self.tv[i - 1], self.tv[i]
        return v0 + (v1 - v0) * (t - t0) / (t1 - t0)

    def publish_marker(self, event):
        msg = PoseStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = 'world'
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = 0.6, 0.0, 0.27
        msg.pose.orientation.w = 1.0
        self.marker_pub.publish(msg)
        with self.lock:
            self.marker_stamps.append(msg.header.stamp.to_sec())

    def wait_status(self, wanted, after=0, timeout=60.0):
        """Waits for the phase `wanted` among the statuses after index `after` (the event; the
        timeout only bounds a failure); returns its message."""
        deadline = rospy.Time.now() + rospy.Duration(timeout)
        while rospy.Time.now() < deadline:
            with self.lock:
                for msg in self.status[after:]:
                    if msg.phase == wanted:
                        return msg
            rospy.sleep(0.02)
        with self.lock:
            self.fail('phase %d not reached; seen %r'
                      % (wanted, [s.phase_name for s in self.status[after:]]))

    def status_count(self):
        with self.lock:
            return len(self.status)

    def run_trial(self, mode, segments_wanted, max_duration=0.0):
        """Starts a trial and returns its first `segments_wanted` drilling segments, waiting
        for them as they arrive (events, not a sleep)."""
        with self.lock:
            first = len(self.trajectories)
        first_status = self.status_count()
        self.trial_status_start = first_status
        t_call = rospy.Time.now()
        res = self.start(mode=mode, spindle_rpm=0.0, feed_rate_mm_s=0.0,
                         max_duration_s=max_duration)
        self.assertTrue(res.success, res.message)
        drilling = self.wait_status(TrialStatus.DRILLING, first_status)
        with self.lock:
            statuses = [s.phase for s in self.status[first_status:]]
        statuses = statuses[statuses.index(TrialStatus.MOVING_TO_POSE):]
        self.assertEqual(statuses[:3], [TrialStatus.MOVING_TO_POSE, TrialStatus.REGISTERING,
                                        TrialStatus.DRILLING])
        self.assertTrue(drilling.running)
        # This trial's trajectories are stamped from its start on; the previous trial's (its
        # retreat, which may still arrive after its 'done') are stamped before the call. The
        # move to the drilling pose is this trial's one one-point trajectory.
        deadline = rospy.Time.now() + rospy.Duration(60.0)
        while True:
            with self.lock:
                trajs = [t for t in self.trajectories[first:] if t.header.stamp >= t_call]
            moves = [i for i, t in enumerate(trajs) if len(t.points) == 1]
            segments = trajs[moves[0] + 1:] if moves else []
            if len(segments) >= segments_wanted or rospy.Time.now() > deadline:
                break
            rospy.sleep(0.02)
        self.assertEqual(len(moves), 1, 'move trajectories: %r' % moves)
        move = trajs[moves[0]]
        self.assertEqual(move.joint_names[-1], 'feed_joint')
        self.assertEqual(len(move.joint_names), 7)
        self.assertAlmostEqual(move.points[-1].positions[-1], FEED_HOME, places=9)
        self.assertAlmostEqual(move.points[-1].time_from_start.to_sec(), 2.0, places=6)
        self.assertGreaterEqual(len(segments), segments_wanted)
        return segments[:segments_wanted]

    def check_segments(self, segments, compensated):
        t_reg = segments[0].header.stamp.to_sec()
        feed_index = segments[0].joint_names.index('feed_joint')
        tv_reg = self.tv_at(t_reg)
        max_comp = 0.0
        checked = 0
        for k, seg in enumerate(segments):
            # Segments of 125 ms on a regular grid, 5 points, ending at rest.
            self.assertAlmostEqual(seg.header.stamp.to_sec() - t_reg, k * PERIOD, delta=1e-6)
            self.assertEqual(len(seg.points), 5)
            self.assertAlmostEqual(seg.points[-1].time_from_start.to_sec(), PERIOD, delta=1e-6)
            self.assertEqual(seg.points[-1].velocities[feed_index], 0.0)
            t1 = seg.header.stamp.to_sec() + PERIOD
            feed = seg.points[-1].positions[feed_index]
            expected = FEED_HOME + FEED_RATE * (t1 - t_reg)
            with self.lock:
                known = bool(self.tv_t) and t1 < self.tv_t[-1]
            if known:
                if compensated:
                    # Bone moves +z (AP, towards the drill), the drill axis is -z: the feed
                    # retracts by the predicted displacement since the start.
                    expected -= self.q1_ap * (self.tv_at(t1) - tv_reg)
                self.assertAlmostEqual(feed, expected, delta=3e-5,
                                       msg='segment %d (%s)' % (k, compensated))
                checked += 1
            max_comp = max(max_comp, abs(feed - FEED_HOME - FEED_RATE * (t1 - t_reg)))
        self.assertGreater(checked, 10)
        return max_comp

    def test_compensated_then_uncompensated_then_stops(self):
        # Compensated: the feed follows the predicted displacement (about 5 mm peak to peak).
        segments = self.run_trial('compensated', 36, max_duration=6.0)
        max_comp = self.check_segments(segments, compensated=True)
        self.assertGreater(max_comp, 2e-3)
        # The predicted marker pose follows the same prediction at the tracker's stamps.
        with self.lock:
            predicted = list(self.predicted)
        self.assertGreater(len(predicted), 20)
        a, b = predicted[2], predicted[-2]
        dz = b.pose.position.z - a.pose.position.z
        dz_expected = self.q1_ap * (self.tv_at(b.header.stamp.to_sec()) -
                                    self.tv_at(a.header.stamp.to_sec()))
        self.assertAlmostEqual(dz, dz_expected, delta=2e-5)
        # Absolute check: the registration averaged the 4 marker samples before the first
        # prediction (each moved back by the predicted motion); the synthetic marker does not
        # move, so pred_z(t) = z_marker + q1 (Tv(t) - mean Tv(t_i)).
        first = predicted[0].header.stamp.to_sec()
        with self.lock:
            before = [t for t in self.marker_stamps if t < first - 1e-6][-4:]
        tv_reg = sum(self.tv_at(t) for t in before) / 4.0
        for p in predicted[:10]:
            expected = 0.27 + self.q1_ap * (self.tv_at(p.header.stamp.to_sec()) - tv_reg)
            self.assertAlmostEqual(p.pose.position.z, expected, delta=3e-5)
        self.assertGreater(max(p.pose.position.z for p in predicted) -
                           min(p.pose.position.z for p in predicted), 2e-3)
        # max_duration_s ends it: retract, then done; the spindle is switched off.
        self.wait_status(TrialStatus.DONE, self.trial_status_start)
        with self.lock:
            self.assertEqual(self.spindle[-1].data, 0.0)
            # rad/s (REP 103): 12000 rpm, repeated while it ran (the driver's watchdog).
            running = [s.data for s in self.spindle if s.data != 0.0]
            self.assertGreater(len(running), 1)
            for speed in running:
                self.assertAlmostEqual(speed, 12000.0 * math.pi / 30.0, places=9)

        # Uncompensated: feed only.
        segments = self.run_trial('uncompensated', 20)
        max_comp = self.check_segments(segments, compensated=False)
        self.assertLess(max_comp, 1e-6)
        # Safety stop: retreat along the drill axis (feed joint back by up to 25 mm, > 0).
        with self.lock:
            first = len(self.trajectories)
        self.stop_pub.publish(StopCommand(source='test', reason='test retreat', retreat=True))
        self.wait_status(TrialStatus.RETREATING, self.trial_status_start)
        self.wait_status(TrialStatus.DONE, self.trial_status_start)
        with self.lock:
            after = self.trajectories[first:]
            self.assertEqual(self.spindle[-1].data, 0.0)
        # Segments published before the stop was handled may still arrive after it; the retreat
        # is the first trajectory that takes the feed back, and everything after it (one
        # connection keeps the order).
        start = next(i for i, t in enumerate(after) if retracts(t))
        feeds = [p.positions[-1] for t in after[start:] for p in t.points]
        self.assertLess(feeds[-1], 1e-6)  # fully retracted (retreat clamped at the feed's end)
        self.assertGreaterEqual(min(feeds), 0.0)
        self.assertTrue(all(b <= a + 1e-9 for a, b in zip(feeds, feeds[1:])))

        # Stationary trial, recognizer-type stop (no retreat): hold, then retract after the hold.
        segments = self.run_trial('stationary', 12)
        with self.lock:
            first = len(self.trajectories)
        self.stop_pub.publish(StopCommand(source='test', reason='key point 4', retreat=False))
        self.wait_status(TrialStatus.STOPPED, self.trial_status_start)
        self.wait_status(TrialStatus.DONE, self.trial_status_start)
        with self.lock:
            held = self.trajectories[first:]
        # The hold lasts until the retreat's first trajectory (stop_hold_s later).
        held = held[:next(i for i, t in enumerate(held) if retracts(t))]
        # Segments published before the stop was handled (up to two periods ahead) may still
        # arrive after it; the hold starts with the trajectory the planner re-sends at the stop,
        # stamped at the stop time and therefore off the 125 ms grid of the segments.
        t_reg = segments[0].header.stamp.to_sec()

        def on_grid(traj):
            k = (traj.header.stamp.to_sec() - t_reg) / PERIOD
            return abs(k - round(k)) < 1e-5  # 1.25 us: stamps are exact to the ns

        resend = [i for i, traj in enumerate(held) if not on_grid(traj)]
        self.assertTrue(resend, 'no hold trajectory re-sent at the stop')
        before = [p.positions[-1] for t in held[:resend[0]] for p in t.points]
        feeds = [p.positions[-1] for t in held[resend[0]:] for p in t.points]
        self.assertGreater(len(feeds), 4)
        # The segment in progress settles at the feed reached at the stop: from the re-sent
        # trajectory on, at most one segment of feed progress (62.5 um), then constant.
        self.assertLess(max(feeds) - min(feeds), PERIOD * FEED_RATE + 1e-6)
        after = [p.positions[-1] for t in held[resend[0] + 1:] for p in t.points]
        if after:
            self.assertLess(max(after) - min(after), 1e-9)
            self.assertAlmostEqual(after[0], feeds[len(held[resend[0]].points) - 1], delta=1e-9)
        # Held at most two segments of feed (0.125 mm) past what was commanded before.
        if before:
            self.assertLess(abs(feeds[0] - before[0]), 2 * PERIOD * FEED_RATE + 1e-6)
        self.wait_status(TrialStatus.RETREATING, self.trial_status_start)


if __name__ == '__main__':
    rospy.init_node('test_planner_segments')
    rostest.rosrun('pedicle_drilling', 'planner_segments', PlannerSegmentsTest, sys.argv)
