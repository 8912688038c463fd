#!/usr/bin/python3
"""Checks rviz/hardware.rviz against hardware topics only (rviz_hardware.test): no simulator, no
simulator/ground_truth. Every check waits for its event (a status message, a subscription, a
screenshot with the plan in it) up to a deadline; none sleeps for a fixed time.

1. the DrillingDisplay reports on drilling_display/status: ground truth off, the plan shown, the
   tracked and the predicted marker shown, drilling_state and tidal_volume received, the
   trial's phase;
2. the ForcePlotPanel reports on force_plot/status recognizer samples and thrust samples, and
   no ground truth;
3. rviz subscribes the hardware topics and not simulator/ground_truth;
4. rviz logged no error about our plugin on /rosout;
5. a screenshot shows the plan's colour (hardware.rviz: "Plan colour") and is not blank.
Private params: ~screenshot (file name), ~timeout_s, ~min_plan_pixels, ~plan_placed_by and
~anchor (how the display places the plan and its text: with the marker on tf "tf" and "bone
frame", hardware.rviz's bone frame being tracker_marker; with the tracker on a pose topic only
"the tracked marker" for both).
"""
import os
import subprocess
import sys
import threading
import time
import unittest

import rospy
import rostest
from rosgraph_msgs.msg import Log
from std_msgs.msg import String

from test_rviz_plugin_loaded import rviz_subscriptions
from test_rviz_screenshot import artifacts_dir, rviz_window_present, screenshot_channels

ERRORS = []
LATEST = {}
CONDITION = threading.Condition()


def on_log(msg):
    if msg.level >= Log.ERROR and 'rviz' in msg.name and (
            'pedicle_drilling' in msg.msg or 'failed to load' in msg.msg.lower()):
        ERRORS.append('%s: %s' % (msg.name, msg.msg))


def on_status(topic):
    def callback(msg):
        with CONDITION:
            LATEST[topic] = msg.data
            CONDITION.notify_all()
    return callback


def wait_for_status(topic, parts, timeout_s):
    """The newest message on `topic` once it has every one of `parts`; the last one seen (or
    None) at the deadline."""
    deadline = time.time() + timeout_s
    with CONDITION:
        while not all(p in LATEST.get(topic, '') for p in parts):
            left = deadline - time.time()
            if left <= 0.0:
                break
            CONDITION.wait(min(left, 1.0))
        return LATEST.get(topic)


def plan_pixels(path):
    """Pixels of hardware.rviz's plan colour (turquoise, 0; 230; 230): no red, green and blue
    both high and alike. The force plot's force curve (80; 200; 255) has red, its A* is orange."""
    r, g, b = screenshot_channels(path)
    return int(((r < 40) & (g > 170) & (b > 170) & (abs(g - b) < 40)).sum())


class RvizHardwareTest(unittest.TestCase):
    def timeout(self):
        return float(rospy.get_param('~timeout_s', 90.0))

    def test_1_display_has_the_hardware_inputs(self):
        wanted = ['ground truth: off', 'drilling state: receiving',
                  'plan: shown by ' + rospy.get_param('~plan_placed_by', 'tf') + ';',
                  'tracked marker: shown', 'predicted marker: shown', 'tidal volume: receiving',
                  'trial: drilling', 'anchor: ' + rospy.get_param('~anchor', 'bone frame')]
        status = wait_for_status('/drilling_display/status', wanted, self.timeout())
        self.assertIsNotNone(status, 'the display never published drilling_display/status')
        for part in wanted:
            self.assertIn(part, status)

    def test_2_force_plot_has_recognizer_and_thrust_samples(self):
        wanted = ['recognizer samples: yes', 'thrust samples: yes', 'ground truth: off']
        status = wait_for_status('/force_plot/status', wanted, self.timeout())
        self.assertIsNotNone(status, 'the force plot never published force_plot/status')
        for part in wanted:
            self.assertIn(part, status)

    def test_3_rviz_subscribes_hardware_topics_and_no_ground_truth(self):
        wanted = {'/drilling_plan', '/ft_sensor/wrench', '/drilling_state',
                  '/tracker/marker_pose', '/compensation/predicted_marker_pose', '/tidal_volume',
                  '/compensation/status'}
        deadline = time.time() + self.timeout()
        while time.time() < deadline and not wanted <= rviz_subscriptions():
            time.sleep(0.2)
        subscribed = rviz_subscriptions()
        self.assertTrue(wanted <= subscribed, 'rviz subscribes %s, expected %s' % (
            sorted(subscribed), sorted(wanted)))
        self.assertNotIn('/simulator/ground_truth', subscribed)

    def test_4_screenshot_shows_the_plan(self):
        self.assertTrue(os.environ.get('DISPLAY'), 'no DISPLAY: run under xvfb-run')
        # The display has placed the plan (test 1's event) before rviz renders it: screenshots
        # until the plan's colour is in one, up to the deadline.
        self.assertIsNotNone(wait_for_status('/drilling_display/status', ['plan: shown'],
                                             self.timeout()))
        self.assertTrue(rviz_window_present(), 'rviz window not found')
        path = os.path.join(artifacts_dir(), rospy.get_param('~screenshot', 'rviz_hardware.png'))
        wanted = int(rospy.get_param('~min_plan_pixels', 20))
        deadline = time.time() + self.timeout()
        count = 0
        while True:
            subprocess.run(['import', '-window', 'root', path], check=True, timeout=30)
            count = plan_pixels(path)
            if count >= wanted or time.time() > deadline:
                break
        rospy.loginfo('screenshot %s: %d plan pixels', path, count)
        self.assertGreaterEqual(count, wanted, 'the plan is not drawn (%d pixels)' % count)
        stats = subprocess.run(
            ['convert', path, '-colorspace', 'Gray', '-format', '%[fx:standard_deviation]',
             'info:'], capture_output=True, text=True, check=True)
        self.assertGreater(float(stats.stdout.strip()), 0.02, 'screenshot is blank or uniform')

    def test_5_no_plugin_errors(self):
        # After the others (unittest runs them in name order): rviz has loaded and run.
        self.assertEqual(ERRORS, [], 'rviz logged errors about our plugin')


if __name__ == '__main__':
    rospy.init_node('test_rviz_hardware')
    rospy.Subscriber('/rosout', Log, on_log, queue_size=100)
    for name in ('/drilling_display/status', '/force_plot/status'):
        rospy.Subscriber(name, String, on_status(name), queue_size=10)
    rostest.rosrun('pedicle_drilling', 'rviz_hardware', RvizHardwareTest, sys.argv)
