"""A campaign worker: its own ROS master on its own port, the full nodelet pipeline in sim time,
and a sequence of trials. Prints one JSON line per finished trial on stdout (the parent collects
them), so nothing finished is lost if the campaign is interrupted.

Run by `campaign`; not meant to be started by hand (but can be, for debugging):
  /usr/bin/python3 -m pd_campaign.worker --port 11411 --trials trials.json --out DIR
"""
import argparse
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np

from pd_campaign.atomic import atomic_write
from pd_campaign import outcome, tools

PIPELINE_SERVICES = {
    'reset': '/simulator/reset',
    'identify': '/motion_identification/identify',
    'start_trial': '/compensation_planner/start_trial',
    'resume': '/simulator/resume',
}


def _recording(handler):
    """A TrialRecorder callback: under the recorder's lock, and dropped once the trial's record
    is closed (end_at): rospy's threads go on delivering what the simulator publishes after
    DONE while the worker analyses the record."""
    def wrapped(self, msg):
        with self._lock:
            if not self.closed:
                handler(self, msg)
    wrapped.__doc__ = handler.__doc__
    return wrapped


class TrialRecorder:
    """Collects what one trial needs from the topics (all sim-time stamps)."""

    def __init__(self):
        self._lock = threading.Lock()
        self.clear()

    def clear(self, min_stamp=0.0, trial_start=0.0):
        with self._lock:
            self._clear(min_stamp, trial_start)

    def _clear(self, min_stamp, trial_start):
        self.closed = False       # end_at closed the record: nothing more is added
        # Messages stamped before min_stamp are the previous trial's, still in transit: dropped.
        # Stops before the trial's start are not the trial's (a monitor that stops between the
        # reset and the start is reset by the start; the core engine's cannot stop before it).
        self.min_stamp = min_stamp
        self.trial_start = max(min_stamp, trial_start)
        self.states = []          # (t, averaged_force, feature, state_name, last_key_point)
        self.key_points = []      # (id, t)
        self.truth = []           # (t, layer, max_depth, residual, breakthrough, rel_ap, contact,
                                  #  contact losses so far)
        self.last_truth = None
        self.truth_msgs = []      # the GroundTruth messages of self.truth (ROS engine)
        self.stops = []           # (t, source, reason, retreat)
        self.status = []          # (t, phase name)
        self.phase = None         # the latest TrialStatus phase (ROS engine)
        self.stops_heard = 0      # the planner's count of the trial's stops at that phase
        self.retare = None        # the monitor's re-tare check when the retreat ended
        self.inputs = None        # (t, {key: value}): the monitor's input streams, latest
        self.monitor_statuses = []  # every (t, {key: value}) of the monitor, in order
        self._last_kp = 0

    @_recording
    def on_state(self, msg):
        t = msg.header.stamp.to_sec()
        if t < self.min_stamp:
            return
        self.states.append((t, msg.averaged_force, msg.feature, msg.state_name,
                            msg.last_key_point))
        if msg.last_key_point > self._last_kp:
            for kp in range(self._last_kp + 1, msg.last_key_point + 1):
                self.key_points.append((kp, t))
            self._last_kp = msg.last_key_point

    @_recording
    def on_truth(self, msg):
        if msg.header.stamp.to_sec() < self.min_stamp:
            return
        self.last_truth = msg
        self.truth_msgs.append(msg)
        self.truth.append((msg.header.stamp.to_sec(), msg.specimen_layer, msg.max_depth_cut_m,
                           msg.residual_inner_cortical_m, msg.breakthrough, msg.relative_ap_m,
                           msg.contact, msg.contact_loss_count))

    @_recording
    def on_stop(self, msg):
        if msg.header.stamp.to_sec() < self.trial_start:
            return
        self.stops.append((msg.header.stamp.to_sec(), msg.source, msg.reason, msg.retreat))

    @_recording
    def on_retare(self, msg):
        """pedicle_drilling/RetareCheck: the SafetyMonitor's re-tare check after the retreat."""
        if msg.done and msg.header.stamp.to_sec() >= self.min_stamp:
            self.retare = {'t': msg.header.stamp.to_sec(), 'drift': msg.drift,
                           'offset_n': msg.offset_n, 'message': msg.message}

    @_recording
    def on_diagnostics(self, msg):
        """/diagnostics: the SafetyMonitor's status carries its input streams as received."""
        t = msg.header.stamp.to_sec()
        if t < self.min_stamp:
            return
        for status in msg.status:
            if status.name.endswith(': monitor'):
                self.inputs = (t, {kv.key: kv.value for kv in status.values})
                self.monitor_statuses.append(self.inputs)

    @_recording
    def on_status(self, msg):
        """pedicle_drilling/TrialStatus: the phase, stamped with the (sim) time of the change."""
        if msg.header.stamp.to_sec() < self.min_stamp:
            return
        self.phase = msg.phase
        self.status.append((msg.header.stamp.to_sec(), msg.phase_name))
        self.stops_heard = msg.stops  # the planner's count of the trial's stops, so far

    def status_time(self, name):
        return next((t for (t, s) in self.status if s == name), None)

    def end_at(self, t_done):
        """The ROS engine's simulator runs on after DONE until the next reset (as fast as the
        machine allows at --real-time-factor 0): the trial's record ends at DONE, whenever the
        worker got to it. The ground truth up to the first sample at or after DONE (the one the
        core engine records at DONE), the recognizer's states and key points up to DONE, and the
        monitor's inputs as it reported them when it heard the trial end (its first status with
        trial_running false after one with true; the latest one without that key)."""
        with self._lock:
            self.closed = True
        end = next((k for k, row in enumerate(self.truth) if row[0] >= t_done), None)
        if end is not None:
            self.truth = self.truth[:end + 1]
            self.truth_msgs = self.truth_msgs[:end + 1]
            self.last_truth = self.truth_msgs[-1]
        self.states = [s for s in self.states if s[0] <= t_done]
        self.stops = [s for s in self.stops if s[0] <= t_done]
        self.key_points = [k for k in self.key_points if k[1] <= t_done]
        inputs = self.trial_end_inputs()
        if inputs is not None:
            self.inputs = inputs

    def trial_end_inputs(self):
        """The monitor's status when it heard the trial end (see end_at), or None yet."""
        running = False
        for t, values in list(self.monitor_statuses):
            if values.get('trial_running') == 'true':
                running = True
            elif running and values.get('trial_running') == 'false':
                return (t, values)
        return None


def retare_columns(retare):
    """retare_offset_n (the mean force against the tare when the retreat ended) and
    drift_detected, from the monitor's re-tare check (None, False: no check recorded)."""
    if not retare:
        return {'retare_offset_n': None, 'drift_detected': False}
    return {'retare_offset_n': retare.get('offset_n'), 'drift_detected': bool(retare['drift'])}


INPUT_COLUMNS = ('force_delay_max_ms', 'force_samples_missing', 'tracker_delay_max_ms',
                 'tracker_samples_missing')


def input_columns(inputs):
    """The SafetyMonitor's input streams in the trial (its diagnostics at the trial's end): the
    largest delay from a sample's stamp to its handling and the samples missing from the
    stamps' gaps, for the F/T sensor and the tracker. None when not recorded (the core engine,
    whose delays are its configuration)."""
    if inputs is None:
        return dict.fromkeys(INPUT_COLUMNS)
    values = inputs[1]

    def number(key):
        try:
            value = float(values[key])
        except (KeyError, ValueError):
            return None
        return int(value) if key.endswith('_missing') else value  # counts are integers
    return {key: number(key) for key in INPUT_COLUMNS}


TRANSPORT_COLUMNS = ('late_commands', 'max_command_lateness_ms', 'command_waits',
                     'command_wait_wall_s', 'command_wait_expired', 'lockstep_timeouts',
                     'rejected_commands')


def transport_columns(last_truth):
    """What the ROS transport did in the trial, as the Simulator nodelet counted it (the last
    ground truth): arm trajectories that arrived after their own start and the latest of them,
    the trajectories a controller refused (its rules, controller_rules), and how often and how long sim time waited for the next trajectory (~command_wait_s). The
    core engine has no transport: None."""
    if last_truth is None or not hasattr(last_truth, 'late_commands'):
        return dict.fromkeys(TRANSPORT_COLUMNS)
    return {'late_commands': last_truth.late_commands,
            'max_command_lateness_ms': 1e3 * last_truth.max_command_lateness_s,
            'command_waits': last_truth.command_waits,
            'command_wait_wall_s': last_truth.command_wait_wall_s,
            'command_wait_expired': last_truth.command_wait_expired,
            'lockstep_timeouts': getattr(last_truth, 'lockstep_timeouts', None),
            'rejected_commands': getattr(last_truth, 'rejected_commands', None)}


def tracking_error(truth, t_start, t_end):
    """RMS and max (mm) of the relative AP tip-bone motion about its best line (removes the feed)
    over [t_start, t_end]; None when too few samples."""
    sel = [(t, rel) for (t, _, _, _, _, rel, *_rest) in truth if t_start <= t <= t_end]
    if len(sel) < 10:
        return None, None
    t = np.array([s[0] for s in sel])
    rel = np.array([s[1] for s in sel]) * 1e3
    slope, intercept = np.polyfit(t, rel, 1)
    residual = rel - (slope * t + intercept)
    return float(np.sqrt(np.mean(residual ** 2))), float(np.max(np.abs(residual)))


def peak_forces(states, truth, t_stop=None):
    """F_out and F_in as the paper reads them (Sec. V-D, Fig. 16): peaks of the recognizer's
    averaged force (the DrillingState force), F_out before the tip's deepest cut enters the
    inner cortical layer, F_in after it, both up to the first stop command `t_stop` (under the
    recognition protocol the recognizer's own stop; the drill is not cutting after it). The
    cancellous layer between is lower than both. None: no sample in that window."""
    inner_start = next((t for (t, layer, *_rest) in truth if layer == 'inner_cortical'), None)
    kept = [(t, f) for (t, f, *_r) in states if t_stop is None or t <= t_stop]
    out = [f for (t, f) in kept if inner_start is None or t < inner_start]
    inn = [f for (t, f) in kept if inner_start is not None and t >= inner_start]
    return (max(out) if out else None), (max(inn) if inn else None)


# Sim time between two trials' starts (time_zero); half of it between a trial's two resets (the
# bench's model-played motion). Each half is more than a reset can be from the next: the hold
# (pre_trial_s, at most 60 s, the simulator's bound; the identification window with online
# identification), a breath (60 s at 1 bpm), max_duration_s (at most 600 s) and the run-on after DONE until the
# worker's next reset. A time_zero the simulator is already past falls back to the next 0.1 s
# (a valid trial, reported on stderr).
TRIAL_SPACING_S = 2000


def time_zero(trial, second=False):
    """The sim time of the trial's time 0 (a whole number of seconds, so on the simulator's
    0.1 s grid): set by its place in the campaign's design, so that the ROS pipeline's nodes see
    the same stamps, and do the same arithmetic on them, in every run of the trial. A second
    reset of the trial (the bench's model-played motion) starts half a spacing later. None
    without a place: the simulator's default (the next 0.1 s)."""
    position = trial.get('design_position')
    if position is None:
        return None
    return (int(position) + 1) * TRIAL_SPACING_S + (TRIAL_SPACING_S // 2 if second else 0)


def run_trial(rospy, srv, msgs, recorder, trial, args, trace_dir):
    wall_start = time.time()
    zeros = (time_zero(trial), time_zero(trial, second=True))
    trial = dict(trial)
    trial.pop('design_position', None)
    row = dict(trial)
    row['engine'] = 'ros'
    recorder.clear()
    moving = trial['case'] != 'stationary'
    # The trial starts where the core engine starts the seed's trial: the simulator holds sim
    # time there (pre_trial_s after the reset, then a breath phase drawn from the seed) until
    # the planner has started it (simulator/resume below).
    reply = _reset(srv, trial, moving, args, zeros[0])
    recorder.clear(reply.reset_time.to_sec(), reply.trial_start.to_sec())
    row['inner_cortical_mm'] = reply.inner_cortical_thickness_m * 1e3
    row['volunteer_id'] = reply.volunteer_id
    row['amplitude_scale'] = reply.patient_amplitude_scale
    row['ventilator_rate_bpm'] = reply.ventilator_rate_bpm
    row['tidal_volume_ml'] = reply.ventilator_tidal_volume_ml
    row['force_noise_sd_n'] = reply.force_noise_sd_n
    row['arm_stiffness_scale'] = reply.arm_stiffness_scale
    # The recognizer and the safety monitor are reset by the planner's start_trial (the trial
    # sequence owns that); what the previous trial still had in transit is older than the reset.
    model_path = os.path.abspath(os.path.join(args.out, 'models', '%s.yaml' % trial['trial_id']))
    if moving and args.models_dir:
        # The simulator's virtual patient is one of the five virtual volunteers (the reset
        # reports which): use the model identified beforehand from that volunteer's own
        # spontaneous-breathing recording, as in the paper.
        model_path = os.path.join(args.models_dir, 'volunteer_%d_%s.yaml'
                                  % (reply.volunteer_id, args.model))
        if not os.path.exists(model_path):
            raise RuntimeError('no identified model %s' % model_path)
    elif moving:
        # Record breathing for the identification window (sim time: the hold is after it),
        # then identify.
        _wait_sim_until(recorder, reply.trial_start.to_sec())
        ident = srv['identify'](model=args.model, method='ceres', output_path=model_path)
        if not ident.success:
            raise RuntimeError('identification failed: %s' % ident.message)
        ap = [a for a in ident.model.axes if a.axis == 'AP']
        row['identification_r2_ap'] = ap[0].r2 if ap else None
    else:
        model_path = args.default_model
    rospy.set_param('/compensation_planner/patient_model_path', model_path)
    if moving and args.bone_motion == 'model':
        # The paper's bench protocol (Algorithm 1: "SPMS and RSSSII do move"): the SPMS plays
        # the displacement the patient's model predicts. The same seed draws the same trial
        # again; only what the bone plays changes.
        rospy.set_param('/simulator/bone_motion_model_path', model_path)
        try:
            reply = _reset(srv, trial, moving, args, zeros[1])
        finally:
            rospy.set_param('/simulator/bone_motion_model_path', '')
        recorder.clear(reply.reset_time.to_sec(), reply.trial_start.to_sec())
    bag = start_bag(args, trial) if args.bags else None
    try:
        try:
            reply = srv['start_trial'](mode=trial['case'], spindle_rpm=trial['rpm'],
                                       feed_rate_mm_s=args.feed_rate,
                                       max_duration_s=args.max_duration)
        finally:
            srv['resume']()  # started or refused, sim time runs on
        if not reply.success:
            raise RuntimeError('start_trial failed: %s' % reply.message)
        row = finish_trial(recorder, row, trial, args, trace_dir, wall_start)
    finally:
        if bag is not None:
            stop_bag(bag)
    if bag is not None:
        # A kept recording says what it lost: <trial>.bag.json beside it, and the row.
        bag_path = os.path.join(args.out, 'bags', trial['trial_id'] + '.bag')
        try:
            check = check_bag(bag_path)
        except Exception as error:  # a bag the recorder did not close (killed) or cannot read
            check = {'bag': os.path.basename(bag_path), 'complete': False,
                     'summary': 'unreadable bag: %s' % ' '.join(str(error).split())}
        with atomic_write(bag_path + '.json') as handle:
            json.dump(check, handle, indent=1)
        row['bag_lost'] = check['summary'] if check['summary'] else 'nothing'
    return row


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


def _wait_until(predicate, bound_s, period_s=0.01, what=None):
    """Polls predicate() until it holds (True) or `bound_s` of wall time passed (False): the
    bound only keeps a dead node from hanging the worker. A wait named `what` that took over
    5 s of wall time, or ran out, is reported on stderr (the campaign's log)."""
    start = time.time()
    deadline = start + bound_s
    held = True
    while not predicate():
        if time.time() >= deadline:
            held = False
            break
        time.sleep(period_s)
    if what and (not held or time.time() - start > 5.0):
        sys.stderr.write('campaign worker: waited %.1f s for %s%s\n'
                         % (time.time() - start, what, '' if held else ' (gave up)'))
    return held


def finish_trial(recorder, row, trial, args, trace_dir, wall_start):
    from pedicle_drilling.msg import TrialStatus  # ROS engine only
    if not _wait_until(lambda: recorder.phase in (TrialStatus.DONE, TrialStatus.FAILED),
                       args.trial_timeout, 0.02, 'the trial to end'):
        raise RuntimeError('trial did not finish within %.0f s wall (status: %s)' % (
            args.trial_timeout, recorder.status[-1][1] if recorder.status else 'none'))
    if recorder.phase == TrialStatus.FAILED:
        raise RuntimeError('the planner failed the trial (statuses: %s)'
                           % ' '.join(s for _, s in recorder.status))
    # The monitor checks the sensor's tare when it hears the retreat end: wait for its result
    # (an event; the bound only keeps a trial whose monitor is gone from hanging).
    t_done = recorder.status_time('done')

    def fresh():
        return (recorder.retare is not None and t_done is not None
                and recorder.retare['t'] >= t_done - 1e-3)
    if not _wait_until(fresh, 5.0, what='the re-tare check'):
        recorder.retare = None  # none for this trial (a previous trial's, latched, is not it)
    # The monitor's diagnostics at the trial's end (its input streams, complete): the status it
    # published when it heard the trial end (an event: trial_running turns false; the stamp is
    # the monitor's ROS time, the latest /clock, which can trail DONE by a clock period).
    _wait_until(lambda: recorder.trial_end_inputs() is not None, 5.0,
                what="the monitor's status at the trial's end")
    # Each topic has its own connection: on a loaded machine the ground truth and the
    # recognizer's states may trail the status that said DONE. Wait until both have reached the
    # trial's end (events: the simulator and the recognizer go on publishing after it), so that
    # nothing the trial recorded is cut off; the bound only keeps a dead node from hanging it.
    def caught_up():
        truth = recorder.last_truth
        return (t_done is not None and truth is not None
                and truth.header.stamp.to_sec() >= t_done
                and (not recorder.states or recorder.states[-1][0] >= t_done))
    _wait_until(caught_up, 30.0, what='the ground truth and the states to reach DONE')
    # The stops come on their own connection too: wait until every stop the planner handled in
    # the trial (its DONE status counts them) is recorded; one still missing after the bound is
    # an error, not a trial without a stop.
    def stops_in():
        return len([s for s in recorder.stops if t_done is None or s[0] <= t_done]) >= \
            recorder.stops_heard
    if not _wait_until(stops_in, 30.0, what='the stops the planner handled'):
        raise RuntimeError('the record has %d of the %d stop(s) the planner handled'
                           % (len(recorder.stops), recorder.stops_heard))
    if t_done is not None:
        recorder.end_at(t_done)
    row['wall_s'] = time.time() - wall_start
    return analyse_trial(recorder, row, trial, trace_dir)


def analyse_trial(recorder, row, trial, trace_dir):
    """The outcome of a finished trial from what was recorded (the same for both engines):
    stop, success (paper Sec. V-C/E), peak forces, tracking error; writes the trace."""
    t_drill = recorder.status_time('drilling')
    if t_drill is None:
        raise RuntimeError('the trial never reached the drilling phase')
    truth = recorder.last_truth
    stop = recorder.stops[0] if recorder.stops else None
    row['stop_source'] = stop[1] if stop else 'none'
    row['stop_reason'] = stop[2] if stop else 'max_duration'
    row['breakthrough'] = bool(truth.breakthrough) if truth else False
    row['residual_mm'] = truth.residual_inner_cortical_m * 1e3 if truth else None
    row['max_depth_mm'] = truth.max_depth_cut_m * 1e3 if truth else None
    # A stop without retreat is the recognizer's, but for the drives' hold when a process died.
    recognizer_stop = (stop is not None and not stop[3]
                       and not stop[1].endswith(('drill_guard', 'drive_guard')))
    row['inner_start_mm'] = truth.inner_cortical_start_m * 1e3 if truth else None
    # Paper Sec. V-C/E: stopped by the recognizer inside the inner cortical layer (entered, not
    # passed) with a residual thickness in (0, 2 mm].
    row['success'] = bool(recognizer_stop and truth is not None and not truth.breakthrough
                          and truth.max_depth_cut_m > truth.inner_cortical_start_m
                          and 0.0 < truth.residual_inner_cortical_m <= 2.0e-3)
    states = [s for s in recorder.states if s[0] >= t_drill]
    truth_rows = [r for r in recorder.truth if r[0] >= t_drill]
    # Why it ended so: the failure kind and the field's metrics (pd_campaign.outcome).
    row['failure_kind'], metrics = outcome.classify(
        truth_rows, recorder.stops, truth.inner_cortical_start_m if truth else 0.0,
        row['success'])
    row.update(metrics)
    # The H1 stops whatever followed them (a run-down breakthrough after an H1 stop included).
    row['first_stop_kind'] = outcome.first_stop_kind(recorder.stops)
    row['h1_error_mm'] = (outcome.h1_error_mm(stop[2])
                          if row['first_stop_kind'] == 'safety_h1' else None)
    row['f_out_n'], row['f_in_n'] = peak_forces(states, truth_rows, stop[0] if stop else None)
    # The same peaks of the true thrust, block-averaged like the recognizer's force but before
    # the sensor (core engine; the ROS pipeline publishes no such peaks): the sensor chain's
    # share of F_out / F_in is the difference. 0 means the layer was not reached.
    peaks = getattr(recorder, 'truth_peaks', None)
    row['f_out_truth_n'], row['f_in_truth_n'] = (
        (peaks[0] or None, peaks[1] or None) if peaks else (None, None))
    row['protocol'] = getattr(recorder, 'protocol', 'recognition')
    t1 = stop[0] if stop else (recorder.truth[-1][0] if recorder.truth else t_drill)
    # Tracking while cutting: from the first contact to the stop. Before the first contact the
    # tip moves through air with no thrust and so no deflection; how long that lasts depends on
    # where the breathing put the bone at registration (0-10 s at the paper's 5 mm start gap),
    # and a window that includes it compares the line fit of different deflection histories.
    t_contact = next((r[0] for r in truth_rows if len(r) > 6 and r[6]), t_drill)
    row['tracking_rms_mm'], row['tracking_max_mm'] = tracking_error(truth_rows, t_contact, t1)
    # Separations of drill and bone between the first contact and the stop (the simulator counts
    # them at 1 kHz; the count at the last ground truth before the stop).
    at_stop = [r for r in recorder.truth if r[0] <= t1 and len(r) > 7]
    row['contact_loss_count'] = at_stop[-1][7] if at_stop else None
    # From the trial's time 0 (the ROS engine: the reset's stamp, not the first ground truth
    # this worker happened to receive after it) to the record's end.
    start = getattr(recorder, 'min_stamp', 0.0) or (recorder.truth[0][0] if recorder.truth else 0)
    row['sim_duration_s'] = (recorder.truth[-1][0] - start) if recorder.truth else None
    row.update(transport_columns(recorder.last_truth))
    row.update(input_columns(getattr(recorder, 'inputs', None)))
    row.update(retare_columns(getattr(recorder, 'retare', None)))
    # json.dumps, then one write: the same text as json.dump, through the C encoder (json.dump
    # encodes in Python, chunk by chunk: a third of the campaign process's time per trial).
    text = json.dumps({'t': [s[0] - t_drill for s in states], 'force': [s[1] for s in states],
                       'feature': [s[2] for s in states],
                       'key_points': [{'id': k, 't': t - t_drill} for k, t in recorder.key_points
                                      if t >= t_drill],
                       'stop_t': stop[0] - t_drill if stop else None})
    with atomic_write(os.path.join(trace_dir, trial['trial_id'] + '.json')) as handle:
        handle.write(text)
    return row


def _reset(srv, trial, moving, args, zero_s=None):
    """simulator/reset for the trial, holding sim time at the engine's start of the trial; its
    time 0 at sim time zero_s (see time_zero) when given."""
    import rospy
    stamp = rospy.Time(int(zero_s)) if zero_s is not None else rospy.Time()
    reply = srv['reset'](seed=trial['seed'], moving_bone=moving, hold_at_trial_start=True,
                         pre_trial_s=args.pre_trial_s, time_zero=stamp)
    if not reply.success:
        raise RuntimeError('simulator reset failed: %s' % reply.message)
    if zero_s is not None and reply.reset_time != stamp:
        # The simulator was already past it (a stalled worker): a valid trial, whose stamps
        # (and so the last bits of its numbers) are not those of another run.
        sys.stderr.write('campaign worker: %s started at sim time %.1f s, not %d s\n'
                         % (trial['trial_id'], reply.reset_time.to_sec(), zero_s))
    return reply


def _wait_sim_until(recorder, stamp):
    """Waits until the ground truth reaches sim time `stamp` (the simulator's hold)."""
    if not _wait_until(lambda: (recorder.last_truth is not None and
                                recorder.last_truth.header.stamp.to_sec() >= stamp - 1e-6),
                       120.0):
        raise RuntimeError('sim time did not reach %.3f s' % stamp)


PAPER_CLASSES = {'recognizer': 'pedicle_drilling/PaperRecognizer',
                 'compensator': 'pedicle_drilling/PaperCompensator'}
NODE_CONFIGS = {'recognizer': 'recognizer.yaml', 'compensator': 'compensation_planner.yaml'}
# The StateRecognizer's own settings in recognizer.yaml, no parameter of the recognizer class;
# its sensor_rate_hz is the simulated sensor's (launch_arguments: force_rate_hz).
NODE_ONLY_SETTINGS = ('axis', 'queue_size', 'rate_tolerance', 'rate_window_s', 'sensor_rate_hz')


def plugin_config(kind, class_name, settings, package_root, out_path):
    """The nodelet's parameter file with a class's NAME=VALUE settings (campaign
    --recognizer-param / --compensator-param, as the core engine takes them), written to
    `out_path`; None when there are none (the launch then loads the package's file). Every
    class gets them as text in ~recognizer_params / ~compensator_params and reads them itself,
    as in the core engine (the paper recognizer with its ParamTable); a paper recognizer's
    setting leaves the node's own key of the package file (~window, ...): the node refuses a
    parameter given both ways. ValueError naming a setting the nodelet would not take (the
    paper compensator has none; the node's own settings are not the recognizer's)."""
    if not settings:
        return None
    import yaml
    with open(os.path.join(package_root, 'config', NODE_CONFIGS[kind])) as handle:
        config = yaml.safe_load(handle) or {}
    pairs = []
    for item in settings:
        name, sep, value = item.partition('=')
        if not sep or not name:
            raise ValueError('--%s-param %r is not NAME=VALUE' % (kind, item))
        pairs.append((name, value))
    if class_name == PAPER_CLASSES[kind]:
        for name, _ in pairs:
            if kind != 'recognizer' or name not in config or name in NODE_ONLY_SETTINGS:
                raise ValueError('--%s-param %s: not a parameter of %s' % (kind, name, class_name))
            del config[name]  # given once, in ~recognizer_params
    config[kind + '_params'] = dict(pairs)
    with atomic_write(out_path) as handle:
        yaml.safe_dump(config, handle, default_flow_style=False)
    return out_path


def launch_arguments(args):
    """The pipeline launch's NAME:=VALUE arguments of a worker (besides the nodelets' parameter
    files). roslaunch takes an argument the launch file does not declare without a word:
    test_worker_config checks each against campaign_pipeline.launch. A simulated sensor rate
    (--simulator-param force_sensor_rate_hz) is the launch's force_rate_hz: the recognizer and
    the monitor are declared at it, as the core engine declares it to its recognizer."""
    rates = [setting.split('=', 1)[1] for setting in getattr(args, 'simulator_param', None) or ()
             if setting.split('=', 1)[0] == 'force_sensor_rate_hz']
    return ['patient_model:=%s' % args.default_model,
            'real_time_factor:=%g' % args.real_time_factor,
            'clock_period_ms:=%d' % (10 if args.bags else 100),
            'segment_profile:=%s' % args.segment_profile,
            'depth_limit:=%s' % args.depth_limit,
            'recognizer:=%s' % args.recognizer, 'compensator:=%s' % args.compensator,
            # ~identify writes only there (the trials' models, model_path below)
            'model_folder:=%s' % os.path.abspath(os.path.join(args.out, 'models'))] + [
                'force_rate_hz:=%s' % rate for rate in rates[-1:]]


class PipelineDown(RuntimeError):
    """The worker's master or pipeline did not come up: no trial can run."""


def wait_for_pipeline(rospy, service, launch, log_path, bound_s=60.0):
    """Waits for the launched pipeline's `service`, at most `bound_s` of wall time. A launch
    that exited (a launch file that is not there or does not parse, an argument it does not
    take) is PipelineDown at once, with the end of its log, not a timeout a minute later; a
    service not up in time is PipelineDown too (the worker then names the launch's processes
    that died: died_processes)."""
    deadline = time.monotonic() + bound_s
    while True:
        if launch.poll() is not None:
            with open(log_path, errors='replace') as handle:
                text = re.sub(r'\x1b\[[0-9;]*[A-Za-z]|\x1b\][^\x07]*\x07', '', handle.read())
            tail = [line.strip() for line in text.splitlines() if line.strip()]
            raise PipelineDown('the pipeline\'s roslaunch exited (%s) before %s was up; its log '
                               '%s ends: %s' % (launch.returncode, service, log_path,
                                                ' | '.join(tail[-6:])))
        try:
            left = deadline - time.monotonic()
            rospy.wait_for_service(service, timeout=max(0.05, min(1.0, left)))
            return
        except rospy.ROSException:
            if time.monotonic() >= deadline:
                raise PipelineDown('%s not up %.0f s after the pipeline\'s launch; its log: %s'
                                   % (service, bound_s, log_path)) from None


def batch_scheduling():
    """This worker and everything it starts (inherited) under SCHED_BATCH: a thread woken by
    another (a message queued, a condition notified) does not preempt it. Under the lockstep the
    simulator's thread then publishes a whole step before the participants run, and the
    participants' thread handles all of it at once, instead of one thread switch per message
    (a third of the ROS trial's wall time; doc/benchmarks.md). Only the order of execution
    changes, which the lockstep makes irrelevant to the trial. An unprivileged process may
    choose it; where it is refused the worker says so and runs as it is."""
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError) as error:
        sys.stderr.write('campaign worker: SCHED_BATCH refused (%s); running as it is\n' % error)


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument('--port', type=int, required=True)
    parser.add_argument('--trials', required=True)
    parser.add_argument('--out', required=True)
    parser.add_argument('--scenario', default='')
    parser.add_argument('--bags', action='store_true')
    parser.add_argument('--feed-rate', type=float, default=0.5)
    parser.add_argument('--max-duration', type=float, default=60.0)
    parser.add_argument('--trial-timeout', type=float, default=120.0)
    parser.add_argument('--identification-window-s', type=float, default=30.0)
    parser.add_argument('--pre-trial-s', type=float, default=None,
                        help='sim time from the reset to the trial (then a breath phase drawn '
                        'from the seed); default: 1 s (the core engine\'s), or the '
                        'identification window when the model is identified online')
    parser.add_argument('--default-model', required=True)
    parser.add_argument('--models-dir', default='',
                        help='identified volunteer models (volunteer_<id>_<model>.yaml); '
                        'empty: identify online on the simulator')
    parser.add_argument('--model', default='linear')
    parser.add_argument('--recognizer', default='pedicle_drilling/PaperRecognizer',
                        help='the StateRecognizer nodelet\'s ~recognizer class')
    parser.add_argument('--compensator', default='pedicle_drilling/PaperCompensator',
                        help='the CompensationPlanner nodelet\'s ~compensator class')
    parser.add_argument('--recognizer-param', action='append', default=[],
                        metavar='NAME=VALUE', help='a recognizer parameter (campaign\'s)')
    parser.add_argument('--compensator-param', action='append', default=[],
                        metavar='NAME=VALUE', help='a compensator parameter (campaign\'s)')
    parser.add_argument('--segment-profile', default='rest_to_rest',
                        help="the planner's ~segment_profile (scenario key compensation_profile)")
    parser.add_argument('--depth-limit', default='true', choices=('true', 'false'),
                        help="the plan's depth limit (scenario key depth_limit): false runs the "
                             "paper's system without a plan (drilling_pipeline.launch "
                             "depth_limit:=false)")
    parser.add_argument('--bone-motion', default='virtual_patient',
                        choices=('model', 'virtual_patient'),
                        help='model: the SPMS plays the trial\'s identified model (the paper\'s '
                        'bench protocol); virtual_patient: the volunteer\'s truth with lag, '
                        'drift and small movements')
    parser.add_argument('--simulator-overrides', default='{}',
                        help='JSON of the scenario\'s simulator section: '
                        '{group: {key: value}} under /simulator/trial_distribution')
    parser.add_argument('--simulator-param', action='append', default=[],
                        help='NAME=VALUE (VALUE in JSON): a Simulator parameter read at every '
                        'reset (scenario keys simulator_params, and engine_delays as '
                        'command_delay_s, command_jitter_s, tracker_delay_s)')
    parser.add_argument('--launch', default='campaign_pipeline.launch')
    parser.add_argument('--real-time-factor', type=float, default=20.0)
    parser.add_argument('--cpu', type=int, default=None,
                        help='run this worker and everything it starts on this CPU (campaign '
                        '--pin-workers)')
    args = parser.parse_args(argv)
    if args.cpu is not None:
        # Inherited by the master, roslaunch and the nodelet manager started below: the
        # lockstep's thread hand-offs stay on one CPU (no cross-CPU wake-ups).
        os.sched_setaffinity(0, {args.cpu})
    batch_scheduling()
    if args.pre_trial_s is None:
        args.pre_trial_s = args.identification_window_s if not args.models_dir else 1.0
    with open(args.trials) as handle:
        trials = json.load(handle)
    # Loopback only, whatever the shell exported (doc/network.md): the
    # master, rosout, the launch's nodes, rosbag and this node. ROS_HOSTNAME names the host in
    # the URIs; roscpp keeps its topics and services on loopback only with ROS_IP=127.x.
    os.environ['ROS_MASTER_URI'] = 'http://127.0.0.1:%d' % args.port
    os.environ['ROS_HOSTNAME'] = '127.0.0.1'
    os.environ['ROS_IP'] = '127.0.0.1'
    log_dir = os.path.join(args.out, 'logs', 'worker-%d' % args.port)
    os.makedirs(log_dir, exist_ok=True)
    os.environ['ROS_LOG_DIR'] = log_dir
    trace_dir = os.path.join(args.out, 'traces')
    os.makedirs(trace_dir, exist_ok=True)
    os.makedirs(os.path.join(args.out, 'models'), exist_ok=True)
    children = []

    def shutdown(*_):
        for child in reversed(children):
            if child.poll() is None:
                try:
                    os.killpg(child.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        for child in reversed(children):
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(child.pid, signal.SIGKILL)

    def terminate(*_):
        # Stop the children, then leave at once: an exception raised here (SystemExit) would
        # surface inside whatever rospy call the main thread was in, and rospy turns some of
        # those into its own errors, which the trial loop records and goes on past (a master
        # gone: five trials of 'unable to contact master').
        shutdown()
        os._exit(143)

    signal.signal(signal.SIGTERM, terminate)
    devnull = open(os.path.join(log_dir, 'children.log'), 'w')  # not atomic: a live log
    down = False
    try:
        children.append(subprocess.Popen(['roscore', '-p', str(args.port)], stdout=devnull,
                                         stderr=subprocess.STDOUT, start_new_session=True))
        import rosgraph
        for _ in range(200):
            if rosgraph.is_master_online():
                break
            time.sleep(0.1)
        else:
            raise PipelineDown('roscore on port %d did not start' % args.port)
        import rospy  # after ROS_MASTER_URI is set
        from pedicle_drilling.msg import (DrillingState, GroundTruth, RetareCheck, StopCommand,
                                          TrialStatus)
        from pedicle_drilling.srv import IdentifyMotion, ResetSimulation, StartTrial
        # The worker runs on wall time: it is initialised before /use_sim_time is set, so it
        # does not have to follow a /clock that runs many times faster than real time.
        rospy.init_node('campaign_worker_%d' % args.port, disable_signals=True)
        rospy.set_param('/use_sim_time', True)
        configs = []
        for kind, launch_arg in (('recognizer', 'recognizer_config'),
                                 ('compensator', 'planner_config')):
            try:
                path = plugin_config(kind, getattr(args, kind), getattr(args, kind + '_param'),
                                     tools.package_dir(),
                                     os.path.join(log_dir, NODE_CONFIGS[kind]))
            except ValueError as error:
                raise PipelineDown(str(error)) from None
            if path:
                configs.append('%s:=%s' % (launch_arg, path))
        children.append(subprocess.Popen(
            ['roslaunch', 'pedicle_drilling', args.launch] + configs + launch_arguments(args),
            stdout=devnull, stderr=subprocess.STDOUT, start_new_session=True))
        from std_srvs.srv import Trigger
        types = {'reset': ResetSimulation, 'identify': IdentifyMotion, 'start_trial': StartTrial,
                 'resume': Trigger}
        srv = {}
        for key, name in PIPELINE_SERVICES.items():
            wait_for_pipeline(rospy, name, children[-1], devnull.name)
            srv[key] = rospy.ServiceProxy(name, types[key])
        # The scenario's simulator section: set after the launch loaded config/simulator.yaml,
        # read by the simulator at every reset. One reset checks it before any trial.
        for setting in args.simulator_param:  # read at every reset
            name, value = setting.split('=', 1)
            rospy.set_param('/simulator/%s' % name, json.loads(value))  # a number or a flag
        overrides = json.loads(args.simulator_overrides)
        for group, values in overrides.items():
            for key, value in values.items():
                rospy.set_param('/simulator/trial_distribution/%s/%s' % (group, key), value)
        if (overrides or args.simulator_param) and trials:
            reply = srv['reset'](seed=trials[0]['seed'], moving_bone=False)
            if not reply.success:
                sys.stderr.write('campaign worker: the scenario\'s simulator section or '
                                 'command delay was refused: %s\n' % reply.message)
                sys.exit(2)
        recorder = TrialRecorder()
        from diagnostic_msgs.msg import DiagnosticArray
        subscribers = [
            rospy.Subscriber('/drilling_state', DrillingState, recorder.on_state,
                             queue_size=10000),
            rospy.Subscriber('/simulator/ground_truth', GroundTruth, recorder.on_truth,
                             queue_size=10000),
            rospy.Subscriber('/drill/stop', StopCommand, recorder.on_stop, queue_size=100),
            rospy.Subscriber('/safety_monitor/retare_check', RetareCheck, recorder.on_retare,
                             queue_size=10),
            rospy.Subscriber('/compensation/status', TrialStatus, recorder.on_status,
                             queue_size=100),
            rospy.Subscriber('/diagnostics', DiagnosticArray, recorder.on_diagnostics,
                             queue_size=100)]
        # Every recorded topic connected before the first trial: a connection made during it
        # cut the trial's record (a worker's first trial once lost its ground truth up to the
        # inner layer: no F_in, no stop depth; test_engine_agreement).
        for sub in subscribers:
            if not _wait_until(lambda: sub.get_num_connections() > 0, 60.0,
                               what='a publisher of %s' % sub.name):
                raise PipelineDown('nothing publishes %s 60 s after the pipeline came up'
                                   % sub.name)
        for trial in trials:
            try:
                row = run_trial(rospy, srv, None, recorder, trial, args, trace_dir)
            except Exception as error:  # recorded, the campaign goes on
                row = dict(trial)
                row['engine'] = 'ros'
                row['success'] = False
                row['error'] = str(error).replace('\n', ' ')[:300]
            # A finished trial's line is written whole: SIGTERM waits until it is out.
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
            sys.stdout.write(json.dumps(row) + '\n')
            sys.stdout.flush()
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    except PipelineDown as error:  # no trial ran: said once, not a traceback per worker
        sys.stderr.write('campaign worker: %s\n' % error)
        down = True
    finally:
        shutdown()
        devnull.close()
        # A process of the launch that died (the nodelet manager's crash ends every service
        # call with a transport error) is named on stderr, which the campaign shows.
        for line in died_processes(os.path.join(log_dir, 'children.log')):
            sys.stderr.write('campaign worker: %s\n' % line)
    if down:
        sys.exit(1)


def died_processes(log_path):
    """The lines of roslaunch's log (children.log) that report a process of the launch dead,
    with its exit code (-11: a segmentation fault)."""
    try:
        with open(log_path, errors='replace') as handle:
            return [line.strip() for line in handle if 'process has died' in line]
    except OSError:
        return []


if __name__ == '__main__':
    main()
