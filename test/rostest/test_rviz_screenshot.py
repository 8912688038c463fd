#!/usr/bin/python3
"""Waits for the rviz window on the (virtual) X display, takes a screenshot with ImageMagick's
`import` and checks that rviz actually rendered something (not a blank or uniform frame)."""
import os
import subprocess
import sys
import time
import unittest

import rospy
import rostest


def artifacts_dir():
    path = os.environ.get('PEDICLE_DRILLING_ARTIFACTS', '/tmp/pedicle_drilling_artifacts')
    os.makedirs(path, exist_ok=True)
    return path


def screenshot_channels(path):
    """The R, G, B channels of a screenshot as integer arrays (ImageMagick decodes it)."""
    import numpy as np
    height = int(subprocess.run(['identify', '-format', '%h', path], capture_output=True,
                                text=True, check=True).stdout)
    raw = subprocess.run(['convert', path, '-depth', '8', 'rgb:-'], capture_output=True,
                         check=True).stdout
    rgb = np.frombuffer(raw, np.uint8).reshape(height, -1, 3).astype(int)
    return rgb[..., 0], rgb[..., 1], rgb[..., 2]


def highlight_pixels(path):
    """Pixels of the DrillingDisplay's yellow residual highlight: bright, green close to red,
    little blue."""
    r, g, b = screenshot_channels(path)
    return int(((r > 120) & (g > 0.75 * r) & (b < 0.45 * r)).sum())


def rviz_window_present():
    out = subprocess.run(['xwininfo', '-root', '-tree'], capture_output=True, text=True)
    return out.returncode == 0 and 'rviz' in out.stdout.lower()


class RvizScreenshotTest(unittest.TestCase):
    def test_screenshot_has_content(self):
        self.assertTrue(os.environ.get('DISPLAY'), 'no DISPLAY: run under xvfb-run')
        deadline = time.time() + 60.0
        while time.time() < deadline and not rviz_window_present():
            time.sleep(0.5)
        self.assertTrue(rviz_window_present(), 'rviz window never appeared')
        time.sleep(float(rospy.get_param('~settle_s', 8.0)))  # let it render a few frames
        path = os.path.join(artifacts_dir(), rospy.get_param('~screenshot', 'rviz.png'))
        subprocess.run(['import', '-window', 'root', path], check=True, timeout=30)
        self.assertTrue(os.path.getsize(path) > 0)
        stats = subprocess.run(
            ['convert', path, '-colorspace', 'Gray', '-format', '%[fx:standard_deviation]', 'info:'],
            capture_output=True, text=True, check=True)
        deviation = float(stats.stdout.strip())
        rospy.loginfo('screenshot %s, grey standard deviation %.4f', path, deviation)
        self.assertGreater(deviation, 0.02, 'screenshot is blank or uniform')


if __name__ == '__main__':
    rospy.init_node('test_rviz_screenshot')
    rostest.rosrun('pedicle_drilling', 'rviz_offscreen', RvizScreenshotTest, sys.argv)
