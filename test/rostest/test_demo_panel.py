#!/usr/bin/python3
"""demo.launch driven through the DrillingPanel. The test never calls the planner's
service itself: it publishes "start" on drilling_panel/press, which clicks the panel's Start
button (a greyed-out button ignores it, so the press is repeated until the planner reports the
trial under way). Then it waits for the trial's end and checks, from the plugins' own state and
from a screenshot, that each shows it:
- the panel's summary (drilling_panel/summary) names the end, the stop, the residual and a
  verdict, and agrees with the simulator's last ground truth;
- the force plot reported the stop marked, the display the residual shown (their log lines);
- the screenshot holds the stop line (red, the force plot), the residual highlight (yellow, the
  display) and the verdict in its colour (green SUCCESS or red FAILURE, the panel).
The screenshot is kept in the artefacts directory (the README's picture comes from it)."""
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

from pedicle_drilling.msg import GroundTruth, TrialStatus
from test_rviz_screenshot import (artifacts_dir, highlight_pixels, rviz_window_present,
                                  screenshot_channels)

LOCK = threading.Lock()
LOGS = []
SUMMARIES = []
PHASES = []
TRUTH = []


def keep(store, value):
    def callback(msg):
        with LOCK:
            store.append(value(msg))
    return callback


def wait_for(predicate, timeout, what):
    deadline = time.time() + timeout
    while time.time() < deadline and not rospy.is_shutdown():
        with LOCK:
            if predicate():
                return
        time.sleep(0.1)
    raise AssertionError('timed out waiting for %s' % what)


class DemoPanelTest(unittest.TestCase):
    def test_a_trial_started_from_the_panel_is_shown_to_its_end(self):
        wait_for(lambda: SUMMARIES, 120.0, 'the panel (drilling_panel/summary)')
        press = rospy.Publisher('/drilling_panel/press', String, queue_size=1)
        started = False
        for _ in range(60):
            with LOCK:
                count = len(PHASES)
            press.publish(String(data='start'))
            try:
                wait_for(lambda: 'moving_to_pose' in PHASES[count:], 3.0, 'the trial to start')
                started = True
                break
            except AssertionError:
                continue  # the panel has not seen the planner's service yet: its button is grey
        self.assertTrue(started, 'the panel never started a trial; phases %r' % PHASES)
        wait_for(lambda: PHASES and PHASES[-1] in ('done', 'failed'), 200.0, 'the trial end')
        wait_for(lambda: any('trial done' in s or 'trial failed' in s for s in SUMMARIES), 30.0,
                 'the panel to show the end')
        wait_for(lambda: any('ForcePlotPanel: stop marked' in m for m in LOGS), 30.0,
                 'the force plot to mark the stop')
        wait_for(lambda: any('DrillingDisplay: trial' in m and 'residual shown' in m
                             for m in LOGS), 30.0, 'the display to show the residual')
        with LOCK:
            summary = [s for s in SUMMARIES if 'trial done' in s or 'trial failed' in s][-1]
            truth = TRUTH[-1]
        rospy.loginfo('panel: %s', summary)
        self.assertIn('trial done', summary)
        self.assertRegex(summary, r'stop /(state_recognizer|safety_monitor): ')  # the trial's stop
        self.assertRegex(summary, r'verdict (SUCCESS|FAILURE)')
        residual_mm = truth.residual_inner_cortical_m * 1e3
        self.assertIn('residual %.2f mm' % residual_mm, summary)
        # The screenshot: rviz renders a few frames after the last change; then all three show.
        self.assertTrue(rviz_window_present())
        time.sleep(2.0)
        path = os.path.join(artifacts_dir(), rospy.get_param('~screenshot', 'demo_panel.png'))
        subprocess.run(['import', '-window', 'root', path], check=True, timeout=30)
        r, g, b = screenshot_channels(path)
        stop_red = int(((r > 220) & (g < 90) & (b < 90)).sum())
        residual_yellow = highlight_pixels(path)
        verdict_green = int(((g > 180) & (r < 100) & (b < 100)).sum())
        rospy.loginfo('screenshot %s: %d stop-red, %d residual-yellow, %d verdict-green pixels',
                      path, stop_red, residual_yellow, verdict_green)
        self.assertGreater(stop_red, 100, 'no stop line in the force plot')
        self.assertGreater(residual_yellow, 40, 'no residual highlight in the display')
        if 'SUCCESS' in summary:
            self.assertGreater(verdict_green, 20, 'the SUCCESS verdict is not shown')


if __name__ == '__main__':
    rospy.init_node('test_demo_panel')
    rospy.Subscriber('/rosout', Log, keep(LOGS, lambda m: m.msg), queue_size=1000)
    rospy.Subscriber('/drilling_panel/summary', String, keep(SUMMARIES, lambda m: m.data),
                     queue_size=100)
    rospy.Subscriber('/compensation/status', TrialStatus, keep(PHASES, lambda m: m.phase_name),
                     queue_size=100)
    rospy.Subscriber('/simulator/ground_truth', GroundTruth, keep(TRUTH, lambda m: m),
                     queue_size=100)
    rostest.rosrun('pedicle_drilling', 'demo_panel_trial', DemoPanelTest, sys.argv)
