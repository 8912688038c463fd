#!/usr/bin/python3
"""The DrillingPanel's settings come back from a saved rviz configuration: rviz starts
with test/config/panel_settings.rviz, whose panel entry is not the default, and the panel's
drilling_panel/controls report (latched, from its own widgets) names exactly those settings."""
import sys
import threading
import time
import unittest

import rospy
import rostest
from std_msgs.msg import String

LOCK = threading.Lock()
CONTROLS = []


class RvizPanelSettingsTest(unittest.TestCase):
    def test_saved_settings_are_loaded(self):
        deadline = time.time() + 90.0
        while time.time() < deadline:
            with LOCK:
                if CONTROLS:
                    break
            time.sleep(0.1)
        with LOCK:
            self.assertTrue(CONTROLS, 'the panel never published drilling_panel/controls')
            report = CONTROLS[-1]
        self.assertIn('settings: mode stationary, profile exact, 16000 rpm, 0.75 mm/s, seed 7',
                      report)


if __name__ == '__main__':
    rospy.init_node('test_rviz_panel_settings')

    def keep(msg):
        with LOCK:
            CONTROLS.append(msg.data)

    rospy.Subscriber('/drilling_panel/controls', String, keep, queue_size=10)
    rostest.rosrun('pedicle_drilling', 'rviz_panel_settings', RvizPanelSettingsTest, sys.argv)
