#!/usr/bin/python3
"""Every class in the package's plugin XML files (nodelet_plugins.xml, rviz_plugins.xml,
recognizer_plugins.xml, compensator_plugins.xml, as `rospack plugins` finds them through the
package's exports) loads through pluginlib by its name and constructs: plugin_load_test (built
with the tests) loads them by base class and reports each; this test compares its report with
the XML files, so a class added to an XML but not exported by its library fails here."""
import os
import subprocess
import sys
import unittest
import xml.etree.ElementTree as ET

import rospy
import rostest

EXPORTS = {'nodelet': ('nodelet::Nodelet',), 'rviz': ('rviz::Display', 'rviz::Panel'),
           'pedicle_drilling': ('pedicle_drilling::core::RecognizerInterface',
                                'pedicle_drilling::core::CompensatorInterface')}


def declared():
    """{(base class, class name)} from the plugin XML files pedicle_drilling exports."""
    classes = set()
    for exporter in EXPORTS:
        out = subprocess.run(['rospack', 'plugins', '--attrib=plugin', exporter],
                             capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            package, _, path = line.partition(' ')
            if package != 'pedicle_drilling':
                continue
            for c in ET.parse(path.strip()).getroot().iter('class'):
                classes.add((c.get('base_class_type'), c.get('name')))
    return classes


class PluginClassesTest(unittest.TestCase):
    def test_every_exported_class_loads(self):
        wanted = declared()
        bases = {b for b, _ in wanted}
        self.assertEqual(bases, {b for group in EXPORTS.values() for b in group}, wanted)
        binary = os.path.join(os.environ['PEDICLE_DRILLING_BIN_DIR'], 'plugin_load_test') \
            if os.environ.get('PEDICLE_DRILLING_BIN_DIR') else None
        if not binary or not os.path.exists(binary):
            out = subprocess.run(['catkin_find', 'pedicle_drilling', 'plugin_load_test'],
                                 capture_output=True, text=True).stdout.split()
            binary = out[0] if out else 'plugin_load_test'
        env = dict(os.environ, QT_QPA_PLATFORM='offscreen')
        run = subprocess.run([binary], capture_output=True, text=True, timeout=90, env=env)
        loaded = set()
        for line in run.stdout.splitlines():
            if line.startswith('loaded '):
                _, base, name = line.split(' ', 2)
                loaded.add((base, name))
        self.assertEqual(run.returncode, 0, run.stdout + run.stderr[-2000:])
        self.assertEqual(loaded, wanted, run.stdout)
        self.assertGreaterEqual(len(loaded), 7 + 3 + 2 + 2)  # nodelets, rviz, recognizers, comp.


if __name__ == '__main__':
    rospy.init_node('test_plugin_classes')
    rostest.rosrun('pedicle_drilling', 'plugin_classes', PluginClassesTest, sys.argv)
