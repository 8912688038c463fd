#!/usr/bin/python3
"""Synthetic hardware for the rviz test of rviz/hardware.rviz: what a lab's drivers and our
nodes publish under hardware.launch, and no simulator (nothing on simulator/ground_truth).

* joint_states (the arm's and the SPMS's drivers, for robot_state_publisher): the joints of
  config/drilling_pose.yaml, loaded as private param ~drilling_pose, the SPMS at its nominal
  pose, with the feed joint
  advancing the tip from 5 mm above the planned entry to ~advance_m beyond it and back;
* the SPMS's controller: tf spms_base -> spms_platform (robot_state_publisher does not publish
  the floating joint), the platform at its nominal pose breathing ~breath_mm along z;
* the tracker's driver: tf tracker_camera -> tracker_marker (unless ~marker_on_tf is false: a
  tracker on a pose topic only) and the marker's pose on tracker/marker_pose (in
  tracker_camera) at ~tracker_rate_hz, the bone breathing ~breath_mm
  along world z; world -> tracker_camera comes from the launch's registration
  (static_transform.py, private param ~registration: "x y z yaw pitch roll" as its args);
* the planner: compensation/predicted_marker_pose (0.3 mm off the tracked pose, same stamp),
  compensation/status (latched, drilling);
* the planning tool: drilling_plan (latched), in tracker_marker, into the bone's top surface;
* the F/T sensor: ft_sensor/wrench at ~force_rate_hz (thrust along +z);
* the recognizer: drilling_state at 50 Hz (averaged force, A*, a key point every 3 s);
* the ventilator: tidal_volume at 50 Hz and ventilator/breath_source_status (latched).
"""
import math

import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TransformStamped, WrenchStamped
from sensor_msgs.msg import JointState

from pedicle_drilling.msg import (BreathSourceStatus, DrillingPlan, DrillingState, TidalVolume,
                                  TrialStatus)

from synthetic_drilling_scene import quaternion_from_rpy, quaternion_multiply, rotate

# The marker on the SPMS platform at its nominal pose (urdf/workcell.urdf: platform at
# (0.6, 0, 0.253923), marker 0.045 m to -y and 7.5 mm up), and the bone's top surface centre
# in the marker's frame (bone_mount_joint: 17.11 mm above the platform).
MARKER_IN_WORLD = (0.6, -0.045, 0.261423)
PLATFORM_IN_BASE = (0.0, 0.0, 0.253923)
ENTRY_IN_MARKER = (0.0, 0.045, 0.00961)
BREATH_PERIOD_S = 4.0


def conjugate(q):
    return (-q[0], -q[1], -q[2], q[3])


def main():
    rospy.init_node('synthetic_hardware_scene')
    joints = dict(rospy.get_param('~drilling_pose', {}))
    # The SPMS's driver: its sliders and rods at the nominal pose (urdf/workcell.urdf).
    joints.update({'slider%d_joint' % i: 0.10 for i in (1, 2, 3)})
    joints.update({'rod%d_joint' % i: -0.523599 for i in (1, 2, 3)})
    x, y, z, yaw, pitch, roll = (float(v) for v in rospy.get_param('~registration').split())
    registration_q = quaternion_from_rpy(roll, pitch, yaw)
    registration_t = (x, y, z)
    breath_m = 1e-3 * float(rospy.get_param('~breath_mm', 1.0))
    advance_m = float(rospy.get_param('~advance_m', 0.004))
    tracker_rate = float(rospy.get_param('~tracker_rate_hz', 8.0))
    force_rate = float(rospy.get_param('~force_rate_hz', 200.0))
    marker_on_tf = bool(rospy.get_param('~marker_on_tf', True))
    if tracker_rate <= 0.0 or force_rate <= 0.0:
        raise ValueError('~tracker_rate_hz and ~force_rate_hz must be > 0')

    broadcaster = tf2_ros.TransformBroadcaster()
    joint_pub = rospy.Publisher('joint_states', JointState, queue_size=10)
    marker_pub = rospy.Publisher('tracker/marker_pose', PoseStamped, queue_size=10)
    predicted_pub = rospy.Publisher('compensation/predicted_marker_pose', PoseStamped,
                                    queue_size=10)
    wrench_pub = rospy.Publisher('ft_sensor/wrench', WrenchStamped, queue_size=100)
    state_pub = rospy.Publisher('drilling_state', DrillingState, queue_size=10)
    tidal_pub = rospy.Publisher('tidal_volume', TidalVolume, queue_size=10)
    diagnostics_pub = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=5)
    status_pub = rospy.Publisher('compensation/status', TrialStatus, queue_size=1, latch=True)
    plan_pub = rospy.Publisher('drilling_plan', DrillingPlan, queue_size=1, latch=True)
    source_pub = rospy.Publisher('ventilator/breath_source_status', BreathSourceStatus,
                                 queue_size=1, latch=True)

    now = rospy.Time.now()
    plan = DrillingPlan()
    plan.header.stamp = now
    plan.header.frame_id = 'tracker_marker'
    plan.entry.x, plan.entry.y, plan.entry.z = ENTRY_IN_MARKER
    plan.direction.z = -1.0
    plan.depth_m = 0.0068
    plan.entry_tolerance_m = 0.001
    plan_pub.publish(plan)
    status_pub.publish(TrialStatus(phase=TrialStatus.DRILLING, phase_name='drilling',
                                   running=True))
    source = BreathSourceStatus(source='flow', topic='/breath_sensor/flow', ready=True,
                                message='flow: breath starts on /breath_sensor/flow',
                                timeout_s=12.0)
    source.header.stamp = now
    source_pub.publish(source)

    start = rospy.Time.now()
    rate = rospy.Rate(force_rate)
    next_slow = start
    next_tracker = start
    next_diagnostics = start
    while not rospy.is_shutdown():
        now = rospy.Time.now()
        t = (now - start).to_sec()
        wrench = WrenchStamped()
        wrench.header.stamp = now
        wrench.header.frame_id = 'ft_sensor'
        wrench.wrench.force.z = 2.0 + math.sin(0.8 * t) + 0.15 * math.sin(40.0 * t)
        wrench_pub.publish(wrench)
        breath = 0.5 * (1.0 - math.cos(2.0 * math.pi * t / BREATH_PERIOD_S))
        if now >= next_tracker:
            next_tracker = now + rospy.Duration(1.0 / tracker_rate)
            world = (MARKER_IN_WORLD[0], MARKER_IN_WORLD[1], MARKER_IN_WORLD[2] + breath_m * breath)
            # The marker in the camera's frame: the registration's inverse applied to it.
            inverse = conjugate(registration_q)
            in_camera = rotate(inverse, [world[i] - registration_t[i] for i in range(3)])
            q_camera = quaternion_multiply(inverse, (0.0, 0.0, 0.0, 1.0))
            transform = TransformStamped()
            transform.header.stamp = now
            transform.header.frame_id = 'tracker_camera'
            transform.child_frame_id = 'tracker_marker'
            (transform.transform.translation.x, transform.transform.translation.y,
             transform.transform.translation.z) = in_camera
            (transform.transform.rotation.x, transform.transform.rotation.y,
             transform.transform.rotation.z, transform.transform.rotation.w) = q_camera
            platform = TransformStamped()
            platform.header.stamp = now
            platform.header.frame_id = 'spms_base'
            platform.child_frame_id = 'spms_platform'
            platform.transform.translation.x = PLATFORM_IN_BASE[0]
            platform.transform.translation.y = PLATFORM_IN_BASE[1]
            platform.transform.translation.z = PLATFORM_IN_BASE[2] + breath_m * breath
            platform.transform.rotation.w = 1.0
            broadcaster.sendTransform([transform, platform] if marker_on_tf else [platform])
            pose = PoseStamped()
            pose.header = transform.header
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = in_camera
            pose.pose.orientation = transform.transform.rotation
            marker_pub.publish(pose)
            predicted = PoseStamped()
            predicted.header = transform.header
            predicted.pose.position.x = in_camera[0] + 0.0003
            predicted.pose.position.y = in_camera[1]
            predicted.pose.position.z = in_camera[2]
            predicted.pose.orientation = transform.transform.rotation
            predicted_pub.publish(predicted)
        if now >= next_slow:
            next_slow = now + rospy.Duration(0.02)
            # The feed: from 5 mm above the entry (drilling_pose.yaml) to advance_m beyond it
            # over 20 s, and back.
            phase = (t % 40.0) / 20.0
            feed = (0.005 + advance_m) * (phase if phase <= 1.0 else 2.0 - phase)
            joint_state = JointState()
            joint_state.header.stamp = now
            joint_state.name = list(joints) + (['feed_joint'] if 'feed_joint' not in joints
                                               else [])
            joint_state.position = [feed if name == 'feed_joint' else float(joints[name])
                                    for name in joint_state.name]
            joint_pub.publish(joint_state)
            state = DrillingState()
            state.header.stamp = now
            state.state = DrillingState.CANCELLOUS
            state.state_name = 'CANCELLOUS'
            state.layer_state = DrillingState.CANCELLOUS
            state.last_key_point = 1 + int(t / 3.0) % 6
            state.averaged_force = 2.0 + math.sin(0.8 * t)
            state.feature = 0.3 + 0.2 * math.cos(0.8 * t)
            state.k = 40
            state.amplitude_d = 2.1
            state.stop_index = -1
            state_pub.publish(state)
            tidal = TidalVolume()
            tidal.header.stamp = now
            tidal.volume_ml = 450.0 * breath
            tidal.flow_ml_s = 450.0 * math.pi / BREATH_PERIOD_S * math.sin(
                2.0 * math.pi * t / BREATH_PERIOD_S)
            tidal.breath_index = int(t / BREATH_PERIOD_S)
            tidal.time_in_breath_s = t % BREATH_PERIOD_S
            tidal_pub.publish(tidal)
            if now >= next_diagnostics:
                next_diagnostics = now + rospy.Duration(1.0)
                diagnostics = DiagnosticArray()
                diagnostics.header.stamp = now
                diagnostics.status.append(DiagnosticStatus(
                    level=DiagnosticStatus.OK, name='/safety_monitor: monitor',
                    message='ok'))
                diagnostics_pub.publish(diagnostics)
        rate.sleep()


if __name__ == '__main__':
    main()
