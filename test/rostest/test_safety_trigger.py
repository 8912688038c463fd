#!/usr/bin/python3
"""Scenario check for one SafetyMonitor trigger (private param ~trigger): nominal force, tracker
and prediction streams first (no stop, OK diagnostics), then the trigger; the monitor must send
exactly one StopCommand with retreat = true and the trigger's reason, report it as an ERROR on
/diagnostics, and clear it on ~reset."""
import math
import random
import sys
import threading
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, WrenchStamped
from std_srvs.srv import Trigger

from pedicle_drilling.msg import StopCommand, TrialStatus

# trigger -> reason name reported by the monitor
REASONS = {
    'force': 'force_exceeded',
    'position': 'position_error',
    'force_timeout': 'force_timeout',
    'tracker_timeout': 'tracker_timeout',
    'nan_force': 'nan_input',
    'nan_tracker': 'nan_input',
    'nan_prediction': 'nan_input',
    'force_silent_at_trial_start': 'force_timeout',
}
MARKER = (0.60, 0.02, 0.30)
MONITOR_STATUS = '/safety_monitor: monitor'
STREAM_STATUSES = ('/safety_monitor: /ft_sensor/wrench topic status',
                   '/safety_monitor: /tracker/marker_pose topic status')


class SafetyTriggerTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.stops = []
        self.diagnostics = []
        self.streams = set()
        self.triggered = False
        self.force_n = 2.0
        self.force_on = True
        self.tracker_on = True
        self.tracker_offset = 0.0
        self.nan_force = False
        self.nan_tracker = False
        self.nan_prediction = False
        self.rng = random.Random(3)
        rospy.Subscriber('/drill/stop', StopCommand, self.on_stop, queue_size=10)
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=100)
        self.wrench_pub = rospy.Publisher('/ft_sensor/wrench', WrenchStamped, queue_size=100)
        self.tracker_pub = rospy.Publisher('/tracker/marker_pose', PoseStamped, queue_size=10)
        self.pred_pub = rospy.Publisher('/compensation/predicted_marker_pose', PoseStamped,
                                        queue_size=10)
        self.status_pub = rospy.Publisher('/compensation/status', TrialStatus, queue_size=1,
                                          latch=True)

    def on_stop(self, msg):
        with self.lock:
            self.stops.append(msg)

    def on_diag(self, msg):
        with self.lock:
            # The monitor's status by its name, as the planner reads it; the other statuses of
            # the monitor are its input streams' rate and stamp checks.
            self.diagnostics.extend(s for s in msg.status if s.name == MONITOR_STATUS)
            self.streams.update(s.name for s in msg.status if s.name in STREAM_STATUSES)

    def publish_force(self, event):
        if not self.force_on:
            return
        msg = WrenchStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = 'ft_sensor'
        msg.wrench.force.z = self.force_n + self.rng.gauss(0.0, 0.03)
        msg.wrench.force.x = float('nan') if self.nan_force else 0.1
        self.wrench_pub.publish(msg)
        self.last_force = msg.header.stamp

    def publish_tracker(self, event):
        if not self.tracker_on:
            return
        stamp = rospy.Time.now()
        # A breathing marker (AP = z, 2.5 mm amplitude) and a prediction of the same motion.
        z = 0.0025 * math.sin(2 * math.pi * stamp.to_sec() / 5.0)
        pred = PoseStamped()
        pred.header.stamp = stamp
        pred.header.frame_id = 'tracker_camera'
        pred.pose.position.x, pred.pose.position.y = MARKER[0], MARKER[1]
        pred.pose.position.z = MARKER[2] + z
        pred.pose.orientation.w = 1.0
        tracked = PoseStamped()
        tracked.header = pred.header
        tracked.pose.orientation.w = 1.0
        tracked.pose.position.x = MARKER[0] + self.rng.gauss(0.0, 0.0002)
        tracked.pose.position.y = MARKER[1] + self.rng.gauss(0.0, 0.0002)
        tracked.pose.position.z = MARKER[2] + z + self.tracker_offset + self.rng.gauss(0.0, 0.0002)
        if self.nan_tracker:
            tracked.pose.position.y = float('nan')
        if self.nan_prediction:
            pred.pose.position.z = float('nan')
        self.tracker_pub.publish(tracked)
        self.last_tracker = stamp
        self.pred_pub.publish(pred)

    def test_trigger_stops_and_retreats_with_reason(self):
        trigger = rospy.get_param('~trigger')
        reason = REASONS[trigger]
        deadline = rospy.Time.now() + rospy.Duration(20.0)
        while rospy.Time.now() < deadline and (
                self.wrench_pub.get_num_connections() == 0 or
                self.tracker_pub.get_num_connections() == 0 or
                self.pred_pub.get_num_connections() == 0):
            rospy.sleep(0.1)
        # A force sensor dead from the start: no trial running yet, so nothing to stop.
        self.force_on = trigger != 'force_silent_at_trial_start'
        self.status_pub.publish(TrialStatus(phase=TrialStatus.IDLE, phase_name='idle',
                                           running=False))
        rospy.Timer(rospy.Duration(0.002), self.publish_force)
        rospy.Timer(rospy.Duration(0.125), self.publish_tracker)
        # Nominal phase: breathing motion predicted well, 2 N thrust: no stop, OK diagnostics.
        rospy.sleep(3.0)
        with self.lock:
            self.assertEqual(self.stops, [], 'stop during the nominal phase: %r' %
                             [s.reason for s in self.stops])
            self.assertTrue(any(d.level == DiagnosticStatus.OK for d in self.diagnostics),
                            'no OK diagnostic while fine')
            self.assertEqual(self.streams, set(STREAM_STATUSES))
        # Trigger.
        t_trigger = rospy.Time.now()
        if trigger == 'force':
            self.force_n = 12.0
        elif trigger == 'position':
            self.tracker_offset = 0.002
        elif trigger == 'force_timeout':
            self.force_on = False
        elif trigger == 'tracker_timeout':
            self.tracker_on = False
        elif trigger == 'nan_force':
            self.nan_force = True
        elif trigger == 'nan_tracker':
            self.nan_tracker = True
        elif trigger == 'nan_prediction':
            self.nan_prediction = True
        elif trigger == 'force_silent_at_trial_start':
            self.status_pub.publish(TrialStatus(  # the planner starts a trial
                phase=TrialStatus.DRILLING, phase_name='drilling', running=True))
        deadline = t_trigger + rospy.Duration(3.0)
        while rospy.Time.now() < deadline:
            with self.lock:
                if self.stops:
                    break
            rospy.sleep(0.01)
        with self.lock:
            self.assertTrue(self.stops, 'no stop after the %s trigger' % trigger)
            t_stop = rospy.Time.now()
        rospy.sleep(1.0)  # the stop is latched: no second command
        with self.lock:
            stops = list(self.stops)
            errors = [d for d in self.diagnostics if d.level == DiagnosticStatus.ERROR]
        self.assertEqual(len(stops), 1, [s.reason for s in stops])
        self.assertTrue(stops[0].retreat)
        self.assertTrue(stops[0].reason.startswith(reason), stops[0].reason)
        self.assertTrue(any(reason in d.message for d in errors),
                        'no ERROR diagnostic naming %s: %r' % (reason, [d.message for d in errors]))
        # A timeout must not fire before the stream has really been silent that long.
        if trigger == 'force_timeout':
            self.assertGreater((stops[0].header.stamp - self.last_force).to_sec(), 0.1)
        if trigger == 'tracker_timeout':
            self.assertGreater((stops[0].header.stamp - self.last_tracker).to_sec(), 0.5)
        if trigger == 'force_silent_at_trial_start':
            self.assertGreater((stops[0].header.stamp - t_trigger).to_sec(), 0.0)
        # Reset clears the latch and the diagnostics return to OK.
        self.force_n = 2.0
        self.force_on = self.tracker_on = True
        self.tracker_offset = 0.0
        self.nan_force = self.nan_tracker = self.nan_prediction = False
        rospy.wait_for_service('/safety_monitor/reset', 5.0)
        reset = rospy.ServiceProxy('/safety_monitor/reset', Trigger)
        if trigger == 'force_silent_at_trial_start':
            # The trial runs: nothing on the graph may reset the monitor; once the planner says
            # its trial is over (the monitor's diagnostics say so), the reset is taken.
            answer = reset()
            self.assertFalse(answer.success, answer.message)
            self.assertIn('refused', answer.message)
            self.status_pub.publish(TrialStatus(phase=TrialStatus.DONE, phase_name='done',
                                                running=False))
            self.wait_trial_over()
        self.assertTrue(reset().success)
        with self.lock:
            self.diagnostics = []
            self.stops = []
        rospy.sleep(2.5)
        with self.lock:
            self.assertEqual(self.stops, [])
            self.assertTrue(self.diagnostics)
            self.assertEqual(self.diagnostics[-1].level, DiagnosticStatus.OK)


    def wait_trial_over(self):
        """Until the monitor's diagnostics say trial_running false (30 s of wall time bound a
        broken run only)."""
        end = time.monotonic() + 30.0
        while time.monotonic() < end and not rospy.is_shutdown():
            with self.lock:
                latest = self.diagnostics[-1] if self.diagnostics else None
            values = {kv.key: kv.value for kv in latest.values} if latest else {}
            if values.get('trial_running') == 'false':
                return
            time.sleep(0.02)
        self.fail('the monitor never heard the trial end')


if __name__ == '__main__':
    rospy.init_node('test_safety_trigger')
    rostest.rosrun('pedicle_drilling', 'safety_trigger', SafetyTriggerTest, sys.argv)
