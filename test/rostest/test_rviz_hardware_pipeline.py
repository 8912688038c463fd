#!/usr/bin/python3
"""hardware.launch rviz:=true against the Simulator without its ground truth
(rviz_hardware_pipeline.test). Every wait is on an event, with a deadline on the trial's clock
(/clock) for a broken run:

1. before the trial the display reports ground truth off, the plan shown, the tracked marker
   shown, the tidal volume received (drilling_display/status);
2. the DrillingPanel's Start (drilling_panel/press, repeated until the planner reports the trial
   under way) starts a trial; during it the display shows the predicted marker and the trial
   drilling, the force plot has recognizer and thrust samples (force_plot/status). A trial that
   ends before its drilling is shown (the monitor stopping it on a machine rendering rviz in
   software) is followed by another, at most three;
3. the trial ends (done or failed: the outcome is not what this checks) and the force plot marks
   its stop (its log line);
4. nothing publishes simulator/ground_truth and rviz does not subscribe it;
5. once the display shows the stop, a screenshot shows the plan's colour and the stop line; it is kept in the
   artefacts directory (doc/images/rviz_hardware.png comes from it).
Private params: ~screenshot (file name).
"""
import os
import subprocess
import sys
import threading
import time
import unittest

import rosgraph
import rosnode
import rospy
import rostest
from rosgraph_msgs.msg import Log
from std_msgs.msg import String

from pedicle_drilling.msg import TrialStatus
from test_rviz_hardware import plan_pixels
from test_rviz_plugin_loaded import rviz_subscriptions
from test_rviz_screenshot import artifacts_dir, rviz_window_present, screenshot_channels

LOCK = threading.Lock()
LOGS = []
PHASES = []
DISPLAY = []
PLOT = []


def keep(store, value):
    def callback(msg):
        with LOCK:
            store.append(value(msg))
    return callback


# A wait's deadline is on the trial's clock (/clock): on a machine rendering rviz in software the
# simulator falls behind its quarter speed, and the trial with it. WALL_FACTOR bounds the wall
# time of a wait for a clock that stops (a dead simulator): the simulator may run at down to a
# twelfth of real time before a wait fails on the wall clock.
WALL_FACTOR = 12.0


def wait_for(predicate, timeout, what):
    """Waits until `predicate()` holds, at most `timeout` seconds of the trial's clock (and
    WALL_FACTOR times as many of the wall clock)."""
    wall_start = time.time()
    clock_start = rospy.get_time()
    clock = wall = 0.0
    while not rospy.is_shutdown():
        with LOCK:
            if predicate():
                return
        clock = rospy.get_time() - clock_start
        wall = time.time() - wall_start
        if clock > timeout or wall > WALL_FACTOR * timeout:
            break
        time.sleep(0.1)
    with LOCK:
        # The first line names what was waited for (CI's summary prints it); the state follows on
        # short lines of its own.
        raise AssertionError('timed out after %.0f s of the trial clock (%.0f s wall) waiting for '
                             '%s\n rviz alive: %s\n display: %.300r\n force plot: %.300r\n'
                             ' phases: %.300r' % (clock, wall, what, rviz_alive(),
                                                  DISPLAY[-1:], PLOT[-1:], PHASES[-8:]))


def rviz_alive():
    """Whether /rviz answers (a crashed rviz does not, until it respawns)."""
    return 'yes' if rosnode.rosnode_ping('/rviz', max_count=1) else 'no'


def seen(store, *parts):
    """Some message of `store` has every one of `parts`."""
    return any(all(p in s for p in parts) for s in store)


def ground_truth_publishers():
    publishers, _, _ = rosgraph.Master('/test_rviz_hardware_pipeline').getSystemState()
    return [nodes for topic, nodes in publishers if topic == '/simulator/ground_truth']


def ended(phases):
    return any(p in ('done', 'failed') for p in phases)


class RvizHardwarePipelineTest(unittest.TestCase):
    display_at = 0
    logs_at = 0

    def press_start(self, press):
        """Presses the DrillingPanel's Start until the planner reports a trial moving to its pose
        (the panel's button is grey until it has seen the planner's service); returns the index
        of that trial's first phase in PHASES."""
        for _ in range(60):
            with LOCK:
                count = len(PHASES)
                self.display_at = len(DISPLAY)
                self.logs_at = len(LOGS)
            press.publish(String(data='start'))
            try:
                wait_for(lambda: 'moving_to_pose' in PHASES[count:], 1.5, 'the trial to start')
                return count
            except AssertionError:
                continue
        self.fail('the panel never started a trial; phases %r' % PHASES)

    def test_a_trial_on_hardware_topics_is_shown_without_ground_truth(self):
        wait_for(lambda: seen(DISPLAY, 'ground truth: off', 'plan: shown',
                              'tracked marker: shown', 'tidal volume: receiving'),
                 60.0, 'the display to show the plan, the tracker and the breath')
        press = rospy.Publisher('/drilling_panel/press', String, queue_size=1)
        # A trial stopped before its drilling (the monitor's timeouts on a machine rendering rviz
        # in software) shows no drilling: Start again, at most three trials.
        for attempt in range(1, 4):
            count = self.press_start(press)
            wait_for(lambda: seen(DISPLAY[self.display_at:], 'predicted marker: shown',
                                  'trial: drilling') or ended(PHASES[count:]), 50.0,
                     'the display to show the prediction during the drilling (trial %d)' % attempt)
            with LOCK:
                drilled = seen(DISPLAY[self.display_at:], 'predicted marker: shown',
                               'trial: drilling')
            if drilled:
                break
            rospy.logwarn('trial %d ended before its drilling was shown (phases %s): Start again',
                          attempt, ' '.join(PHASES[count:]))
        self.assertTrue(drilled, 'no trial of three was shown drilling; phases %r' % PHASES)
        wait_for(lambda: seen(PLOT, 'recognizer samples: yes', 'thrust samples: yes',
                              'ground truth: off'), 15.0, 'the force plot samples')
        wait_for(lambda: any('ForcePlotPanel: stop marked' in m for m in LOGS[self.logs_at:]),
                 60.0,
                 'the force plot to mark the stop')
        wait_for(lambda: PHASES and PHASES[-1] in ('retreating', 'done', 'failed'), 30.0,
                 'the trial to stop')
        # The display has taken the stop in (its text follows the trial's phase): the picture
        # then agrees with the panels.
        wait_for(lambda: any(seen(DISPLAY, 'trial: ' + p)
                             for p in ('retreating', 'done', 'failed')), 15.0,
                 'the display to show the stop')
        self.assertEqual(ground_truth_publishers(), [])
        self.assertNotIn('/simulator/ground_truth', rviz_subscriptions())
        self.assertIn('/drilling_plan', rviz_subscriptions())
        # The screenshot: until rviz has drawn the plan and the stop line, up to the deadline.
        self.assertTrue(rviz_window_present(), 'rviz window not found')
        path = os.path.join(artifacts_dir(),
                            rospy.get_param('~screenshot', 'rviz_hardware_pipeline.png'))
        deadline = time.time() + 60.0
        while True:
            subprocess.run(['import', '-window', 'root', path], check=True, timeout=30)
            r, g, b = screenshot_channels(path)
            stop_red = int(((r > 220) & (g < 90) & (b < 90)).sum())
            plan = plan_pixels(path)
            if (plan >= 20 and stop_red > 100) or time.time() > deadline:
                break
        with LOCK:
            rospy.loginfo('screenshot %s: %d plan, %d stop-red pixels; phases %s', path, plan,
                          stop_red, ' '.join(PHASES))
        self.assertGreaterEqual(plan, 20, 'the plan is not drawn')
        self.assertGreater(stop_red, 100, 'no stop line in the force plot')
        wait_for(lambda: PHASES and PHASES[-1] in ('done', 'failed'), 30.0, 'the trial end')


if __name__ == '__main__':
    rospy.init_node('test_rviz_hardware_pipeline')
    rospy.Subscriber('/rosout', Log, keep(LOGS, lambda m: m.msg), queue_size=1000)
    rospy.Subscriber('/compensation/status', TrialStatus, keep(PHASES, lambda m: m.phase_name),
                     queue_size=100)
    rospy.Subscriber('/drilling_display/status', String, keep(DISPLAY, lambda m: m.data),
                     queue_size=100)
    rospy.Subscriber('/force_plot/status', String, keep(PLOT, lambda m: m.data), queue_size=100)
    rostest.rosrun('pedicle_drilling', 'rviz_hardware_pipeline', RvizHardwarePipelineTest,
                   sys.argv)
