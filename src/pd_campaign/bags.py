"""A --engine ros trial's rosbag (campaign --bags): the topics kept, the recorder started and
stopped around the trial, and the check of what a kept recording lost."""
import os
import signal
import subprocess
import time

# Topics kept in a trial's rosbag (--bags): enough to replay the trial in rviz
# (rviz/drilling.rviz) and to re-run a recognizer on the raw force. No /clock: `rosbag play
# --clock` publishes one from the recorded times (a recorded /clock would be a second clock).
BAG_TOPICS = ['/tf', '/tf_static', '/joint_states', '/ft_sensor/wrench', '/tracker/marker_pose',
              '/tidal_volume', '/simulator/ground_truth', '/drilling_state', '/drill/stop',
              '/compensation/status', '/compensation/predicted_marker_pose',
              '/arm_controller/command', '/feed_controller/command', '/spindle/command',
              '/ventilator/settings', '/diagnostics']
# Published in every trial, so a bag without them lost them (the others may stay silent).
BAG_REQUIRED = ['/tf', '/tf_static', '/joint_states', '/ft_sensor/wrench', '/tracker/marker_pose',
                '/simulator/ground_truth', '/drilling_state', '/compensation/status',
                '/arm_controller/command', '/spindle/command', '/ventilator/settings',
                '/diagnostics']


def start_bag(args, trial):
    bag_dir = os.path.join(args.out, 'bags')
    os.makedirs(bag_dir, exist_ok=True)
    process = subprocess.Popen(
        ['rosbag', 'record', '--quiet', '-O', os.path.join(bag_dir, trial['trial_id'] + '.bag')]
        + BAG_TOPICS, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True)
    time.sleep(1.0)  # let the recorder subscribe before the trial starts
    return process


def stop_bag(process):
    """Stops the recorder and returns once its whole process group has exited: `rosbag` is a
    wrapper whose `record` child renames <trial>.bag.active to <trial>.bag when it closes."""
    try:
        os.killpg(process.pid, signal.SIGINT)  # rosbag closes the file cleanly on SIGINT
        process.wait(timeout=30)
        deadline = time.time() + 30
        while time.time() < deadline:
            os.killpg(process.pid, 0)  # raises ProcessLookupError once the group is gone
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)


def check_bag(path):
    """What a trial's bag holds and what it lost: message counts per topic, required topics
    with no message, and the gaps in the force stream (consecutive header stamps more than 1.5
    sample periods apart: samples the recorder dropped). The sample period is the stream's own
    median spacing, so any DAQ rate (the Simulator's ~force_sensor_rate_hz, a real sensor's) is
    checked against itself. Returns the report (a dict)."""
    import rosbag
    counts = {topic: 0 for topic in BAG_TOPICS}
    stamps = []
    with rosbag.Bag(path) as bag:
        for topic, msg, _ in bag.read_messages(topics=BAG_TOPICS):
            counts[topic] += 1
            if topic == '/ft_sensor/wrench':
                stamps.append(msg.header.stamp.to_sec())
    spacing = [(a, b - a) for a, b in zip(stamps, stamps[1:])]
    steps = sorted(dt for _, dt in spacing)
    period = steps[len(steps) // 2] if steps else 0.0
    # No spacing (fewer than two distinct stamps): no gap.
    gaps = [(t, dt) for t, dt in spacing if dt > 1.5 * period] if period > 0.0 else []
    lost = sum(int(round(dt / period)) - 1 for _, dt in gaps)
    missing = [topic for topic in BAG_REQUIRED if counts[topic] == 0]
    summary = []
    if missing:
        summary.append('no message on ' + ', '.join(missing))
    if gaps:
        summary.append('%d force samples lost in %d gaps (longest %.0f ms at t=%.3f s)' % (
            lost, len(gaps), 1e3 * max(dt for _, dt in gaps),
            max(gaps, key=lambda g: g[1])[0]))
    return {'bag': os.path.basename(path), 'messages': counts, 'missing_topics': missing,
            'force_samples': len(stamps), 'force_samples_lost': lost,
            'force_gaps': [{'t': t, 'dt_s': dt} for t, dt in gaps],
            'complete': not summary, 'summary': '; '.join(summary)}
