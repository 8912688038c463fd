"""A finished trial's row from its record, the same for both engines: the stop, the success
(paper Sec. V-C/E), the failure kind, the peak forces, the tracking error, the transport's and the
monitor's columns; its trace written. The core engine's records (engine_core.RecordedTrial) and the
ROS worker's (recorder.TrialRecorder) have the same interface."""
import json
import os

import numpy as np

from pd_campaign import outcome
from pd_campaign.atomic import atomic_write


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
