#!/usr/bin/python3
"""Synthetic drilling scene for the rviz tests, without the simulator.

* tf: every joint of the `robot_description` URDF as a static transform parent -> child, with the
  joint values of config/drilling_pose.yaml loaded as private param ~drilling_pose (a dict;
  missing joints at 0; the floating SPMS platform joint at its URDF origin).
* pedicle_drilling/GroundTruth on `simulator/ground_truth` and pedicle_drilling/DrillingState on
  `drilling_state` at ~rate_hz, describing a hole drilled into the inner cortical layer
  (depths from private params, metres).
"""
import math
import xml.etree.ElementTree as ET

import rospy
import tf2_ros
from geometry_msgs.msg import TransformStamped

from pedicle_drilling.msg import DrillingState, GroundTruth


def quaternion_from_rpy(roll, pitch, yaw):
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy,  # x
            cr * sp * cy + sr * cp * sy,  # y
            cr * cp * sy - sr * sp * cy,  # z
            cr * cp * cy + sr * sp * sy)  # w


def quaternion_multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def rotate(q, v):
    qv = quaternion_multiply(quaternion_multiply(q, (v[0], v[1], v[2], 0.0)),
                             (-q[0], -q[1], -q[2], q[3]))
    return qv[:3]


def floats(text, default):
    return [float(x) for x in (text or default).split()]


def joint_transforms(urdf_xml, positions, stamp):
    """One TransformStamped per URDF joint: origin, then the joint motion about/along its axis."""
    transforms = []
    for joint in ET.fromstring(urdf_xml).findall('joint'):
        origin = joint.find('origin')
        xyz = floats(origin.get('xyz') if origin is not None else None, '0 0 0')
        rpy = floats(origin.get('rpy') if origin is not None else None, '0 0 0')
        axis_el = joint.find('axis')
        axis = floats(axis_el.get('xyz') if axis_el is not None else None, '1 0 0')
        norm = math.sqrt(sum(a * a for a in axis)) or 1.0
        axis = [a / norm for a in axis]
        q = quaternion_from_rpy(*rpy)
        value = float(positions.get(joint.get('name'), 0.0))
        kind = joint.get('type')
        if kind in ('revolute', 'continuous'):
            s = math.sin(value / 2)
            q = quaternion_multiply(q, (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(value / 2)))
        elif kind == 'prismatic':
            offset = rotate(q, [a * value for a in axis])
            xyz = [xyz[i] + offset[i] for i in range(3)]
        t = TransformStamped()
        t.header.stamp = stamp
        t.header.frame_id = joint.find('parent').get('link')
        t.child_frame_id = joint.find('child').get('link')
        t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = xyz
        (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
         t.transform.rotation.w) = q
        transforms.append(t)
    return transforms


def main():
    rospy.init_node('synthetic_drilling_scene')
    positions = rospy.get_param('~drilling_pose', {})
    broadcaster = tf2_ros.StaticTransformBroadcaster()
    broadcaster.sendTransform(
        joint_transforms(rospy.get_param('robot_description'), positions, rospy.Time.now()))

    gt_pub = rospy.Publisher('simulator/ground_truth', GroundTruth, queue_size=5)
    state_pub = rospy.Publisher('drilling_state', DrillingState, queue_size=5)
    outer_end = rospy.get_param('~outer_cortical_end_m', 0.002)
    inner_start = rospy.get_param('~inner_cortical_start_m', 0.006)
    inner_end = rospy.get_param('~inner_cortical_end_m', 0.0081)
    cut = rospy.get_param('~max_depth_cut_m', 0.0068)
    rate = rospy.Rate(rospy.get_param('~rate_hz', 20.0))
    start = rospy.Time.now()
    while not rospy.is_shutdown():
        now = rospy.Time.now()
        t = (now - start).to_sec()
        gt = GroundTruth()
        gt.header.stamp = now
        gt.header.frame_id = 'bone'
        gt.seed = 7
        gt.specimen_layer = 'inner_cortical'
        gt.tip_depth_m = cut
        gt.max_depth_cut_m = cut
        gt.outer_cortical_end_m = outer_end
        gt.inner_cortical_start_m = inner_start
        gt.inner_cortical_end_m = inner_end
        gt.residual_inner_cortical_m = max(0.0, inner_end - cut)  # GroundTruth.msg
        gt.breakthrough = cut >= inner_end
        gt.thrust_n = 2.8 + 0.1 * math.sin(2.0 * math.pi * t)
        gt.contact = True
        state = DrillingState()
        state.header.stamp = now
        state.state = DrillingState.INNER_CORTICAL
        state.state_name = 'INNER_CORTICAL'
        state.last_key_point = 1 + int(t / 3.0) % 6  # a new key point every 3 s: chart markers
        state.averaged_force = 2.0 + math.sin(0.8 * t)
        state.feature = 0.3 + 0.2 * math.cos(0.8 * t)
        state.k = 40
        state.amplitude_d = 2.1
        state.stop_index = -1
        gt_pub.publish(gt)
        state_pub.publish(state)
        rate.sleep()


if __name__ == '__main__':
    main()
