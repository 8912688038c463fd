#!/usr/bin/python3
"""A static transform on /tf_static (tf2_ros's static_transform_publisher is not packaged in
Debian): hardware.launch's tracker registration, world -> the tracker's frame, from the lab's
hand-eye calibration.

    rosrun pedicle_drilling static_transform.py x y z yaw pitch roll parent child

Angles in radians (yaw about z, then pitch about y, then roll about x: the order of
static_transform_publisher). A value that is not a finite number, or a frame that is empty or
equal to the other, is refused with a message naming it (exit status 2)."""
import math
import sys

import rospy
import tf2_ros
from geometry_msgs.msg import TransformStamped

NAMES = ('x', 'y', 'z', 'yaw', 'pitch', 'roll')


def quaternion(yaw, pitch, roll):
    """(x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def parse(argv):
    """(values, parent, child) from the 8 arguments; raises ValueError naming the bad one."""
    if len(argv) != 8:
        raise ValueError('expected 8 arguments: x y z yaw pitch roll parent child, got %d'
                         % len(argv))
    values = []
    for name, text in zip(NAMES, argv[:6]):
        try:
            value = float(text)
        except ValueError:
            raise ValueError('%s: not a number: %r' % (name, text)) from None
        if not math.isfinite(value):
            raise ValueError('%s: not finite: %r' % (name, text))
        values.append(value)
    parent, child = argv[6], argv[7]
    if not parent or not child or parent == child:
        raise ValueError('parent and child frames must be non-empty and differ: %r, %r'
                         % (parent, child))
    return values, parent, child


def main():
    argv = rospy.myargv(sys.argv)[1:]
    try:
        values, parent, child = parse(argv)
    except ValueError as error:
        sys.stderr.write('static_transform.py: %s\n' % error)
        return 2
    rospy.init_node('static_transform', anonymous=True)
    t = TransformStamped()
    t.header.stamp = rospy.Time.now()
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = values[:3]
    q = quaternion(*values[3:])
    (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
     t.transform.rotation.w) = q
    broadcaster = tf2_ros.StaticTransformBroadcaster()
    broadcaster.sendTransform(t)
    rospy.loginfo('static_transform: %s -> %s', parent, child)
    rospy.spin()
    return 0


if __name__ == '__main__':
    sys.exit(main())
