#!/usr/bin/python3
"""The ForceTare relay (force_tare_relay.test): raw wrenches in, tared ones out, the tare on
request. Waits on messages, never on time: the raw stream is published until what is awaited
has arrived."""
import sys
import threading
import unittest

import rospy
import rostest
from geometry_msgs.msg import WrenchStamped

from pedicle_drilling.msg import TareRequest, TareResult

WEIGHT_N = 4.9


class ForceTareRelayTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.out = []
        self.results = []
        self.raw = rospy.Publisher('/ft_sensor/wrench_raw', WrenchStamped, queue_size=100)
        self.request = rospy.Publisher('/ft_sensor/tare_request', TareRequest, queue_size=10)
        rospy.Subscriber('/ft_sensor/wrench', WrenchStamped, self.keep(self.out), queue_size=1000)
        rospy.Subscriber('/ft_sensor/tare_result', TareResult, self.keep(self.results),
                         queue_size=10)
        self.count = 0

    def keep(self, store):
        def callback(msg):
            with self.lock:
                store.append(msg)
        return callback

    def publish_until(self, done, limit=20000):
        """Publishes raw samples (the weight plus a +-0.02 N alternation) until done()."""
        for _ in range(limit):
            with self.lock:
                if done():
                    return
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.now()
            msg.header.frame_id = 'ft_sensor'
            msg.wrench.force.z = WEIGHT_N + (0.02 if self.count % 2 else -0.02)
            msg.wrench.force.x = 0.3
            self.count += 1
            self.raw.publish(msg)
            rospy.sleep(0.002)
        self.fail('not done after %d samples' % limit)

    def test_the_relay_tares_on_request_and_refuses_a_bad_request(self):
        while self.raw.get_num_connections() == 0 or self.request.get_num_connections() == 0:
            rospy.sleep(0.05)
        # Untared: relayed as it is.
        self.publish_until(lambda: len(self.out) >= 10)
        with self.lock:
            self.assertAlmostEqual(self.out[-1].wrench.force.z, WEIGHT_N, delta=0.05)
        self.request.publish(TareRequest(samples=50, max_spread_n=0.5))
        self.publish_until(lambda: len(self.results) >= 1)
        with self.lock:
            result = self.results[-1]
            tared_from = len(self.out)
        self.assertTrue(result.success, result.message)
        self.assertEqual(result.samples, 50)
        self.assertAlmostEqual(result.bias.force.z, WEIGHT_N, delta=0.01)
        self.assertAlmostEqual(result.bias.force.x, 0.3, delta=1e-9)
        self.assertLess(result.spread_n, 0.05)
        self.publish_until(lambda: len(self.out) >= tared_from + 20)
        with self.lock:
            after = self.out[tared_from + 5:]
        for msg in after:
            self.assertAlmostEqual(msg.wrench.force.z, 0.0, delta=0.05)
            self.assertAlmostEqual(msg.wrench.force.x, 0.0, delta=1e-9)
        # A bad request: refused, said on the result topic; the bias kept.
        self.request.publish(TareRequest(samples=0, max_spread_n=0.5))
        self.publish_until(lambda: len(self.results) >= 2)
        with self.lock:
            refused = self.results[-1]
            count = len(self.out)
        self.assertFalse(refused.success)
        self.assertIn('refused', refused.message)
        self.publish_until(lambda: len(self.out) >= count + 5)
        with self.lock:
            self.assertAlmostEqual(self.out[-1].wrench.force.z, 0.0, delta=0.05)


if __name__ == '__main__':
    rospy.init_node('test_force_tare_relay')
    rostest.rosrun('pedicle_drilling', 'force_tare_relay', ForceTareRelayTest, sys.argv)
