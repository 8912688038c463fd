#!/usr/bin/python3
"""Virtual volunteers as rosbags, from the very CSV files the identify CLI reads.

    rosrun pedicle_drilling volunteers_to_bag.py --out DIR [--ids 1,2,3,4,5] [--duration 30]
        [--csv-dir DIR] [--start-time 1000] [--marker-offset 0,0,1.0]
        [--ap-axis +z] [--si-axis +y] [--lr-axis +x]

Without --csv-dir, `generate_volunteers --out DIR` is run first. For each id, DIR/volunteer_<id>.bag
holds, stamped at start_time + t (ROS time must be > 0; `rosbag play --clock` publishes it):
  tidal_volume          pedicle_drilling/TidalVolume, 64 Hz, from volunteer_<id>_tv64.csv
                        (volume_ml = tv; flow_ml_s = central difference of tv;
                        breath_index and time_in_breath_s = 0: not known to the recording)
  /tf                   tracker_camera -> tracker_marker, 8 Hz, from volunteer_<id>.csv
  tracker/marker_pose   geometry_msgs/PoseStamped in tracker_camera, the same 8 Hz positions
The marker position (m) in the tracker frame is marker_offset plus the displacement (mm / 1000)
placed on the tracker axes given by --ap-axis/--si-axis/--lr-axis (the MotionIdentification
nodelet's ~ap_axis/~si_axis/~lr_axis, same defaults), so the nodelet maps it back to AP/SI/LR
and its intercepts q0 equal the CLI's plus the mapped offset (in mm).
Exit status: 0 ok; 2 bad arguments, bad input or an output that cannot be written, with one
line naming the option or file (no partial bag is left: each is written and renamed).
"""
import csv
import math
import os
import re
import subprocess
import sys

import rosbag
import rospy
from geometry_msgs.msg import PoseStamped, TransformStamped
from tf2_msgs.msg import TFMessage

from pedicle_drilling.msg import TidalVolume
from pd_campaign.atomic import atomic_path
from pd_campaign.tools import argument_parser, tool

AXIS_RE = re.compile(r'^([+-]?)([xyz])$')


def parse_mapping(ap, si, lr):
    """Returns [(index, sign)] for AP, SI, LR; raises ValueError naming the axis."""
    out, used = [], set()
    for name, spec in (('ap', ap), ('si', si), ('lr', lr)):
        m = AXIS_RE.match(spec)
        if not m:
            raise ValueError('--%s-axis %r is not one of x, y, z with an optional sign'
                             % (name, spec))
        index = 'xyz'.index(m.group(2))
        if index in used:
            raise ValueError('--%s-axis %r reuses a tracker axis' % (name, spec))
        used.add(index)
        out.append((index, -1.0 if m.group(1) == '-' else 1.0))
    return out


def parse_numbers(option, text, kind):
    """Comma-separated numbers of one option; ValueError naming the option."""
    try:
        return [kind(x) for x in text.split(',')]
    except ValueError:
        raise ValueError('%s %r: must be comma-separated %s' % (
            option, text, 'integers' if kind is int else 'numbers'))


def read_columns(path, names):
    """Columns `names` of a CSV as floats; the first ('t') must strictly increase, every value
    be finite. Raises ValueError naming the file, the row and the column."""
    try:
        with open(path) as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise ValueError('%s: cannot be read: %s' % (path, e.strerror))
    if not rows:
        raise ValueError('%s: no data' % path)
    for n in names:
        if n not in rows[0]:
            raise ValueError('%s: missing column %r' % (path, n))
    columns = {n: [] for n in names}
    for number, row in enumerate(rows, 2):  # line 1 is the header
        for n in names:
            try:
                value = float(row[n])
            except (TypeError, ValueError):
                raise ValueError('%s line %d: column %r = %r is not a number'
                                 % (path, number, n, row[n]))
            if not math.isfinite(value):
                raise ValueError('%s line %d: column %r is not finite' % (path, number, n))
            columns[n].append(value)
    t = columns[names[0]]
    for i in range(1, len(t)):
        if not t[i] > t[i - 1]:
            raise ValueError('%s line %d: time %r does not increase (previous %r); the bag would '
                             'not be identifiable' % (path, i + 2, t[i], t[i - 1]))
    return columns


def write_bag(csv_path, tv_path, bag_path, start, offset, mapping):
    disp = read_columns(csv_path, ['t', 'ap', 'si', 'lr'])
    tv = read_columns(tv_path, ['t', 'tv'])
    # Written to a temporary file and renamed: a failed run leaves no partial bag behind.
    with atomic_path(bag_path) as tmp_path:
        with rosbag.Bag(tmp_path, 'w') as bag:
            return _write_messages(bag, disp, tv, start, offset, mapping)


def _write_messages(bag, disp, tv, start, offset, mapping):
    t, v = tv['t'], tv['tv']
    n = len(t)
    for i in range(n):
        lo, hi = max(i - 1, 0), min(i + 1, n - 1)
        msg = TidalVolume()
        msg.header.stamp = rospy.Time.from_sec(start + t[i])
        msg.header.frame_id = 'ventilator'
        msg.volume_ml = v[i]
        msg.flow_ml_s = (v[hi] - v[lo]) / (t[hi] - t[lo])
        bag.write('tidal_volume', msg, msg.header.stamp)
    for i, ti in enumerate(disp['t']):
        stamp = rospy.Time.from_sec(start + ti)
        p = list(offset)
        for (index, sign), axis in zip(mapping, ('ap', 'si', 'lr')):
            p[index] += sign * disp[axis][i] / 1000.0
        tf = TransformStamped()
        tf.header.stamp = stamp
        tf.header.frame_id = 'tracker_camera'
        tf.child_frame_id = 'tracker_marker'
        tf.transform.translation.x, tf.transform.translation.y, \
            tf.transform.translation.z = p
        tf.transform.rotation.w = 1.0
        bag.write('/tf', TFMessage(transforms=[tf]), stamp)
        pose = PoseStamped()
        pose.header.stamp = stamp
        pose.header.frame_id = 'tracker_camera'
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = p
        pose.pose.orientation.w = 1.0
        bag.write('tracker/marker_pose', pose, stamp)
    return len(tv['t']), len(disp['t'])


def main(argv):
    parser = argument_parser(description=__doc__.split('\n')[0])
    parser.add_argument('--out', required=True)
    parser.add_argument('--ids', default='1,2,3,4,5')
    parser.add_argument('--duration', default='30')
    parser.add_argument('--csv-dir', default='')
    parser.add_argument('--start-time', type=float, default=1000.0)
    parser.add_argument('--marker-offset', default='0,0,1.0')
    parser.add_argument('--ap-axis', default='+z')
    parser.add_argument('--si-axis', default='+y')
    parser.add_argument('--lr-axis', default='+x')
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:
        return 2 if e.code else 0
    try:
        mapping = parse_mapping(args.ap_axis, args.si_axis, args.lr_axis)
        offset = parse_numbers('--marker-offset', args.marker_offset, float)
        if len(offset) != 3 or not all(abs(x) < 1e3 for x in offset):
            raise ValueError('--marker-offset %r: must be three finite numbers x,y,z in m'
                             % args.marker_offset)
        if not args.start_time > 0.0:
            raise ValueError('--start-time must be > 0 s (ROS time 0 means "no time")')
        ids = parse_numbers('--ids', args.ids, int)
        if args.csv_dir and not os.path.isdir(args.csv_dir):
            raise ValueError('--csv-dir %r is not a folder' % args.csv_dir)
    except ValueError as e:
        print('volunteers_to_bag: %s' % e, file=sys.stderr)
        return 2
    csv_dir = args.csv_dir or args.out
    if not args.csv_dir:
        status = subprocess.call(tool('generate_volunteers') +
                                 ['--out', args.out, '--ids', args.ids,
                                  '--duration', args.duration])
        if status != 0:
            return status
    os.makedirs(args.out, exist_ok=True)
    for vid in ids:
        stem = os.path.join(csv_dir, 'volunteer_%d' % vid)
        bag_path = os.path.join(args.out, 'volunteer_%d.bag' % vid)
        try:
            n_tv, n_marker = write_bag(stem + '.csv', stem + '_tv64.csv', bag_path,
                                       args.start_time, offset, mapping)
        except ValueError as e:
            print('volunteers_to_bag: %s' % e, file=sys.stderr)
            return 2
        except OSError as e:
            print('volunteers_to_bag: %s: %s' % (bag_path, e.strerror), file=sys.stderr)
            return 2
        print('volunteer %d: %d tidal_volume, %d tf / marker_pose messages -> %s'
              % (vid, n_tv, n_marker, bag_path))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
