"""The campaign's core engine: trials run by `trial_engine` (core::ClosedLoopEngine, no ROS),
one process per job. Each process prints one JSON line per trial with what the ROS worker
records from the topics; the same analysis (analysis.analyse_trial) turns it into a trials.csv row.
A trial's record depends on its seed only, so the rows do not depend on --jobs or --shard."""
import collections
import json
import os
import subprocess
import threading
import types

from pd_campaign.analysis import analyse_trial
from pd_campaign.tools import tool

CONDITION_COLUMNS = ('volunteer_id', 'amplitude_scale', 'ventilator_rate_bpm', 'tidal_volume_ml',
                     'force_noise_sd_n', 'arm_stiffness_scale', 'inner_cortical_mm',
                     'patient_ap_slope_mm_per_ml', 'patient_lag_s', 'patient_gain_change')


class RecordedTrial:
    """A trial record of trial_engine, with the interface of recorder.TrialRecorder."""

    def __init__(self, record):
        self.states = [tuple(s) for s in record['states']]
        self.key_points = [tuple(k) for k in record['key_points']]
        self.truth = [tuple(t) for t in record['truth']]
        self.stops = [tuple(s) for s in record['stops']]
        self.status = [tuple(s) for s in record['status']]
        self.last_truth = types.SimpleNamespace(**record['last_truth'])
        # Ground-truth peaks (the core engine computes them at 1 kHz; see analysis.peak_forces).
        self.truth_peaks = record.get('truth_peaks_n')
        self.protocol = record.get('protocol', 'recognition')
        # The monitor's re-tare check when the retreat ended (SafetyMonitor::retareCheck).
        retare = record.get('retare') or {}
        self.retare = retare if retare.get('done') else None

    def status_time(self, name):
        return next((t for (t, s) in self.status if s == name), None)


def trial_engine_command(trial_file, drilling_pose, models_dir, model, bone_motion,
                         feed_rate, max_duration, default_model, segment_profile='rest_to_rest',
                         fault_options=(), recognizer='pedicle_drilling/PaperRecognizer',
                         compensator='pedicle_drilling/PaperCompensator',
                         recognizer_params=None, compensator_params=None,
                         simulator_overrides=None, protocol='recognition',
                         simulator_settings=None, planner_settings=None, delays=None,
                         samples_dir=None, profile_path=None):
    """`fault_options`: (option, value) pairs of the fault sizes, e.g. ('--fault-spike-n', 15);
    `simulator_overrides`: the scenario's `simulator:` section, {group: {key: value}}, passed as
    the Simulator's parameters trial_distribution/<group>/<key> (the same declaration checks
    them in both engines); `samples_dir`: every trial's force-sensor samples to
    <samples_dir>/<trial_id>.npy (the dataset, pd_campaign.dataset); `profile_path`: where the
    trials' wall time went, by component (pd_campaign.profile)."""
    command = tool('trial_engine') + ['--trials', trial_file,
               '--drilling-pose', ','.join(repr(q) for q in drilling_pose),
               '--model', model, '--bone-motion', bone_motion,
               '--feed-rate', repr(feed_rate), '--max-duration', repr(max_duration),
               '--default-model', default_model, '--segment-profile', segment_profile]
    if models_dir:
        command += ['--models-dir', models_dir]
    for option, value in fault_options:
        command += [option, repr(value)]
    if recognizer != 'pedicle_drilling/PaperRecognizer':
        command += ['--recognizer', recognizer]
    if compensator != 'pedicle_drilling/PaperCompensator':
        command += ['--compensator', compensator]
    for option, params in (('--recognizer-param', recognizer_params),
                           ('--compensator-param', compensator_params)):
        for name, value in sorted((params or {}).items()):
            command += [option, '%s=%s' % (name, value)]
    for item in simulator_params(simulator_overrides, simulator_settings):
        command += ['--simulator-param', item]
    for item in settings_list(planner_settings):
        command += ['--planner-param', item]
    for name, value in sorted((delays or {}).items()):
        command += [DELAY_OPTIONS[name], repr(float(value))]
    if protocol != 'recognition':
        command += ['--protocol', protocol]
    if samples_dir:
        command += ['--samples-dir', samples_dir]
    if profile_path:
        command += ['--profile', profile_path]
    return command


# scenario key engine_delays -> trial_engine option (core::EngineDelays)
DELAY_OPTIONS = {'force_to_recognizer_s': '--force-delay-s', 'stop_to_planner_s': '--stop-delay-s',
                 'command_to_arm_s': '--command-delay-s', 'command_jitter_s': '--command-jitter-s',
                 'tracker_to_pipeline_s': '--tracker-delay-s'}


def settings_list(settings):
    """{name: value} as NAME=VALUE strings, sorted (booleans as true/false)."""
    return ['%s=%s' % (name, str(value).lower() if isinstance(value, bool) else value)
            for name, value in sorted((settings or {}).items())]


def simulator_params(section, settings=None):
    """The scenario's `simulator:` section, {group: {key: value}}, as the Simulator's parameters
    `trial_distribution/<group>/<key>=<value>`, then its `simulator_params:` {name: value}."""
    return ['trial_distribution/%s/%s=%r' % (group, key, float(value))
            for group, values in sorted((section or {}).items())
            for key, value in sorted(values.items())] + settings_list(settings)


def fault_columns(row, record):
    """fault, fault_time_s (from the start of drilling), stop_delay_s (fault to the first stop
    command) and retreat_delay_s (fault to the start of the retreat) of a finished trial."""
    fault = record.get('fault') or {}
    row['fault'] = fault.get('name', 'none')
    for key in ('fault_time_s', 'stop_delay_s', 'retreat_delay_s'):
        row[key] = None
    if row['fault'] == 'none' or not fault.get('injected'):
        return row
    t_fault = fault['t']
    t_drill = next((t for (t, s) in record['status'] if s == 'drilling'), None)
    row['fault_time_s'] = t_fault - t_drill if t_drill is not None else None
    stop = next((s for s in record['stops'] if s[0] >= t_fault), None)
    row['stop_delay_s'] = stop[0] - t_fault if stop else None
    retreat = next((t for (t, s) in record['status'] if s == 'retreating' and t >= t_fault), None)
    row['retreat_delay_s'] = retreat - t_fault if retreat is not None else None
    return row


def row_from_line(line, trace_dir):
    """A trials.csv row from one output line of trial_engine (errored trials included)."""
    result = json.loads(line)
    row = dict(result['trial'])
    row['engine'] = 'core'
    row.setdefault('fault', 'none')
    if 'error' in result:
        row['success'] = False
        row['error'] = str(result['error']).replace('\n', ' ')[:300]
        return row
    record = result['record']
    for key in CONDITION_COLUMNS:
        row[key] = record['conditions'][key]
    row['wall_s'] = None  # trial_engine reports no wall time per trial: nothing to compare
    model_ap = record.get('model_ap') or {}
    row['model_ap_slope_mm_per_ml'] = model_ap.get('q1_mm_per_ml')
    if record['conditions'].get('volunteer_id') == 0:
        # A population patient: its model was identified from its own recording for this trial.
        row['identification_r2_ap'] = model_ap.get('r2')
    watch = record.get('controller_watch') or {}
    row['watch_desired_ratio'] = watch.get('desired_ratio')
    row['watch_following_ratio'] = watch.get('following_ratio')
    limit = record.get('depth_limit') or {}
    error = limit.get('estimate_error_max_m')
    row['depth_estimate_error_mm'] = error * 1e3 if error is not None else None
    row['plan_far_side_error_mm'] = limit.get('plan_far_side_error_m', 0.0) * 1e3
    # The estimate error's maxima over 0.25 s windows (what the margin's choice pools).
    row['depth_window_errors_mm'] = ';'.join(
        '%.4f' % (e * 1e3) for e in limit.get('window_errors_m') or []) or None
    try:
        row = analyse_trial(RecordedTrial(record), row, result['trial'], trace_dir)
        return fault_columns(row, record)
    except RuntimeError as error:
        row['success'] = False
        row['error'] = str(error)[:300]
        return row


def start(command):
    """trial_engine `command` started with pipes: stdin for `--trials -` (TrialFeed), stdout for
    its JSON lines."""
    return subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            start_new_session=True)


class TrialFeed:
    """The design's trials to `trial_engine --trials -` processes, in design order, the next one to
    the process that finished one: each holds one trial queued behind the one it runs, so none
    waits for the campaign, and none idles while another finishes a fixed share of the design.
    Thread-safe: each process's reader thread calls start() once, then next() on each
    of its output lines; a process's stdin is closed when the trials run out."""

    AHEAD = 2  # trials a process holds: the one it runs and the next

    def __init__(self, trials):
        self._trials = collections.deque(trials)
        self._lock = threading.Lock()

    def start(self, process):
        for _ in range(self.AHEAD):
            self.next(process)

    def next(self, process):
        with self._lock:
            trial = self._trials.popleft() if self._trials else None
        try:
            if trial is None:
                self.close(process)
                return
            process.stdin.write(json.dumps(trial) + '\n')
            process.stdin.flush()
        except (BrokenPipeError, ValueError):
            # The process ended (its exit status says why): the trial goes back to the front,
            # for a process still running. The trials it had taken are not finished.
            with self._lock:
                self._trials.appendleft(trial)

    @staticmethod
    def close(process):
        """End of input for `process` (it finishes what it holds, then exits)."""
        try:
            if not process.stdin.closed:
                process.stdin.close()
        except (BrokenPipeError, OSError):
            pass


def drilling_pose(package_root):
    """Arm joint values of config/drilling_pose.yaml (the planner's ~drilling_pose)."""
    import yaml
    with open(os.path.join(package_root, 'config', 'drilling_pose.yaml')) as handle:
        pose = yaml.safe_load(handle)['drilling_pose']
    return [float(pose['rsssii_joint%d' % i]) for i in range(1, 7)]
