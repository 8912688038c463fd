#!/usr/bin/python3
"""Checks that rviz loaded our plugin (pedicle_drilling/DrillingDisplay, ForcePlotPanel) from
rviz/drilling.rviz and that the display draws:

1. pluginlib sees our plugin description: `rospack plugins --attrib=plugin rviz` lists
   pedicle_drilling's rviz_plugins.xml, which declares both classes;
2. the rviz node subscribes the display's inputs (simulator/ground_truth is subscribed by nothing
   else in rviz), so the display object was created and enabled;
3. rviz logged no error about our classes on /rosout (pluginlib's "failed to load" included);
4. a screenshot contains the residual-thickness highlight (the display's residual colour,
   yellow in drilling.rviz): only our display draws that colour in the 3D view.
Private params: ~screenshot (file name), ~settle_s, ~min_highlight_pixels.
"""
import os
import subprocess
import sys
import time
import unittest
import xml.etree.ElementTree as ET

import rosgraph
import rospy
import rostest
from rosgraph_msgs.msg import Log

from test_rviz_screenshot import artifacts_dir, highlight_pixels, rviz_window_present

CLASSES = ('pedicle_drilling/DrillingDisplay', 'pedicle_drilling/ForcePlotPanel',
           'pedicle_drilling/DrillingPanel')
ERRORS = []


def on_log(msg):
    if msg.level >= Log.ERROR and 'rviz' in msg.name and (
            'pedicle_drilling' in msg.msg or 'failed to load' in msg.msg.lower()):
        ERRORS.append('%s: %s' % (msg.name, msg.msg))


def rviz_subscriptions():
    """Topics subscribed by the rviz node, from the master."""
    _, subscribers, _ = rosgraph.Master('/test_rviz_plugin_loaded').getSystemState()
    return {topic for topic, nodes in subscribers if any(n.startswith('/rviz') for n in nodes)}


class RvizPluginLoadedTest(unittest.TestCase):
    def test_plugin_description_is_registered(self):
        out = subprocess.run(['rospack', 'plugins', '--attrib=plugin', 'rviz'],
                             capture_output=True, text=True, check=True).stdout
        paths = [line.split(None, 1)[1] for line in out.splitlines()
                 if line.startswith('pedicle_drilling ')]
        self.assertEqual(len(paths), 1, 'rviz plugins: %s' % out)
        self.assertTrue(paths[0].endswith('rviz_plugins.xml'), paths[0])
        declared = {c.get('name') for c in ET.parse(paths[0]).getroot().iter('class')}
        for name in CLASSES:
            self.assertIn(name, declared)

    def test_panel_without_the_pipeline_greys_out_and_stays_responsive(self):
        """No planner or simulator here: the DrillingPanel's buttons are greyed out with the
        reason, a press on Start does nothing, and the panel keeps answering."""
        from std_msgs.msg import String
        controls = []
        rospy.Subscriber('/drilling_panel/controls', String, lambda m: controls.append(m.data))
        deadline = time.time() + 60.0
        while time.time() < deadline and not controls:
            time.sleep(0.1)
        self.assertTrue(controls, 'the panel never published drilling_panel/controls')
        self.assertIn('start disabled', controls[-1])
        self.assertIn('compensation_planner/start_trial is not available', controls[-1])
        summaries = []
        rospy.Subscriber('/drilling_panel/summary', String, lambda m: summaries.append(m.data))
        press = rospy.Publisher('/drilling_panel/press', String, queue_size=1)
        deadline = time.time() + 30.0
        while time.time() < deadline and press.get_num_connections() == 0:
            time.sleep(0.1)
        press.publish(String(data='start'))
        # After the press the panel's own thread still handles messages: a phase published here
        # (there is no planner in this launch) changes its summary, which only its GUI-thread
        # refresh publishes.
        from pedicle_drilling.msg import TrialStatus
        status = rospy.Publisher('/compensation/status', TrialStatus, queue_size=1, latch=True)
        status.publish(TrialStatus(phase=TrialStatus.MOVING_TO_POSE, phase_name='moving_to_pose',
                                   running=True))
        deadline = time.time() + 30.0
        while time.time() < deadline and not any('moving_to_pose' in m for m in summaries):
            time.sleep(0.1)
        self.assertTrue(any('moving_to_pose' in m for m in summaries),
                        'the panel stopped answering: %r' % summaries)
        self.assertFalse(any('started' in m for m in summaries))
        status.publish(TrialStatus(phase=TrialStatus.IDLE, phase_name='idle', running=False))

    def test_display_loaded_subscribed_and_drew(self):
        deadline = time.time() + 60.0
        wanted = {'/simulator/ground_truth', '/drilling_state'}
        while time.time() < deadline and not wanted <= rviz_subscriptions():
            time.sleep(0.5)
        self.assertTrue(wanted <= rviz_subscriptions(),
                        'rviz subscribes %s, expected %s' % (sorted(rviz_subscriptions()),
                                                             sorted(wanted)))
        self.assertTrue(rviz_window_present(), 'rviz window not found')
        time.sleep(float(rospy.get_param('~settle_s', 8.0)))
        self.assertEqual(ERRORS, [], 'rviz logged errors about our plugin')
        path = os.path.join(artifacts_dir(),
                            rospy.get_param('~screenshot', 'rviz_drilling_plugin.png'))
        subprocess.run(['import', '-window', 'root', path], check=True, timeout=30)
        count = highlight_pixels(path)
        rospy.loginfo('screenshot %s: %d residual-highlight pixels', path, count)
        self.assertGreaterEqual(count, int(rospy.get_param('~min_highlight_pixels', 40)),
                                'the residual highlight is not drawn (%d pixels)' % count)


if __name__ == '__main__':
    rospy.init_node('test_rviz_plugin_loaded')
    rospy.Subscriber('/rosout', Log, on_log, queue_size=100)
    rostest.rosrun('pedicle_drilling', 'rviz_drilling_plugin', RvizPluginLoadedTest, sys.argv)
