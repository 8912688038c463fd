#!/usr/bin/python3
"""A stock F/T sensor driver, as a lab's would be: it publishes geometry_msgs/WrenchStamped only
(no TareRequest/TareResult) and offers a std_srvs/Trigger zero service. Its "sensor" is the
simulator's tared stream (~input) plus the bias of an untared sensor (~offset: the tool's weight
and a lateral offset), published on ~output with stamp and frame kept; the zero service
(~zero_service, "" = none) removes the offset from the next sample on, as a driver that biases
its sensor does. Used by ft_zero_service.test and ft_zero_service_missing.test."""
import threading

import rospy
from geometry_msgs.msg import WrenchStamped
from std_msgs.msg import UInt32
from std_srvs.srv import Trigger, TriggerResponse


class StockDriver(object):
    def __init__(self):
        self.lock = threading.Lock()
        self.offset = [float(v) for v in rospy.get_param('~offset', [0.3, 0.0, 4.9])]
        self.zero_calls = 0
        self.pub = rospy.Publisher(rospy.get_param('~output', 'lab_ft/wrench'), WrenchStamped,
                                   queue_size=1000)
        # How often the zero service was called (latched), for the test.
        self.calls_pub = rospy.Publisher('~zero_calls', UInt32, queue_size=1, latch=True)
        self.calls_pub.publish(UInt32(0))
        rospy.Subscriber(rospy.get_param('~input', 'lab_ft/sensor'), WrenchStamped, self.relay,
                         queue_size=1000, tcp_nodelay=True)
        name = rospy.get_param('~zero_service', '')
        if name:
            rospy.Service(name, Trigger, self.zero)

    def relay(self, msg):
        with self.lock:
            msg.wrench.force.x += self.offset[0]
            msg.wrench.force.y += self.offset[1]
            msg.wrench.force.z += self.offset[2]
            self.pub.publish(msg)

    def zero(self, _request):
        with self.lock:
            self.offset = [0.0, 0.0, 0.0]
            self.zero_calls += 1
            self.calls_pub.publish(UInt32(self.zero_calls))
        return TriggerResponse(success=True, message='sensor biased')


if __name__ == '__main__':
    rospy.init_node('stock_ft_driver')
    StockDriver()
    rospy.spin()
