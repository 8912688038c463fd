"""trials.csv, a campaign's trial rows: its columns, a row normalised to its types, the file
written whole or line by line as the trials finish (TrialsAppender), and read back."""
import csv
import io
import math
import os

from .atomic import atomic_write, named
from .design import CASES, FAULTS

TRIAL_COLUMNS = [
    'trial_id', 'case', 'rpm', 'index', 'seed', 'seed_space', 'fault', 'engine', 'success',
    'residual_mm',
    'f_out_n', 'f_in_n', 'f_out_truth_n', 'f_in_truth_n', 'protocol', 'stop_reason', 'stop_source', 'fault_time_s', 'stop_delay_s',
    'retreat_delay_s', 'breakthrough', 'failure_kind', 'stop_depth_mm', 'stop_residual_mm',
    'overshoot_mm', 'rundown_mm', 'detection_latency_ms', 'first_stop_kind', 'h1_error_mm',
    'max_depth_mm',
    'inner_start_mm',
    'inner_cortical_mm', 'volunteer_id', 'amplitude_scale', 'ventilator_rate_bpm',
    'tidal_volume_ml', 'force_noise_sd_n', 'arm_stiffness_scale', 'patient_ap_slope_mm_per_ml',
    'patient_lag_s', 'patient_gain_change', 'model_ap_slope_mm_per_ml',
    'tracking_rms_mm', 'tracking_max_mm', 'contact_loss_count', 'identification_r2_ap',
    'sim_duration_s', 'wall_s', 'late_commands', 'max_command_lateness_ms', 'command_waits',
    'command_wait_wall_s', 'command_wait_expired', 'lockstep_timeouts', 'rejected_commands',
    'watch_desired_ratio', 'watch_following_ratio', 'depth_estimate_error_mm',
    'plan_far_side_error_mm', 'depth_window_errors_mm', 'force_delay_max_ms', 'force_samples_missing', 'tracker_delay_max_ms', 'tracker_samples_missing', 'retare_offset_n',
    'drift_detected', 'bag_lost', 'error',
]


def _number(value):
    if value in (None, ''):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(number) else number


def normalise_row(row):
    """Types of a trials.csv row (strings from csv) as the report uses them."""
    out = dict(row)
    out['rpm'] = float(row['rpm'])
    out['index'] = int(row['index'])
    out['seed'] = int(row['seed'])
    out['success'] = str(row['success']).lower() in ('1', 'true')
    out['breakthrough'] = str(row.get('breakthrough', '')).lower() in ('1', 'true')
    out['drift_detected'] = str(row.get('drift_detected', '')).lower() in ('1', 'true')
    out['fault'] = row.get('fault') or 'none'
    for key in ('fault_time_s', 'stop_delay_s', 'retreat_delay_s', 'residual_mm', 'f_out_n', 'f_in_n', 'f_out_truth_n', 'f_in_truth_n', 'max_depth_mm', 'inner_start_mm',
                'inner_cortical_mm', 'amplitude_scale', 'ventilator_rate_bpm', 'tidal_volume_ml',
                'force_noise_sd_n', 'arm_stiffness_scale', 'patient_ap_slope_mm_per_ml',
                'patient_lag_s', 'patient_gain_change', 'model_ap_slope_mm_per_ml',
                'tracking_rms_mm', 'tracking_max_mm', 'contact_loss_count', 'identification_r2_ap',
                'sim_duration_s', 'wall_s', 'stop_depth_mm', 'stop_residual_mm', 'overshoot_mm',
                'rundown_mm', 'detection_latency_ms', 'h1_error_mm', 'late_commands',
                'max_command_lateness_ms', 'command_waits', 'command_wait_wall_s',
                'command_wait_expired', 'lockstep_timeouts', 'rejected_commands',
                'watch_desired_ratio', 'watch_following_ratio', 'depth_estimate_error_mm',
                'plan_far_side_error_mm', 'force_delay_max_ms', 'force_samples_missing',
                'tracker_delay_max_ms',
                'tracker_samples_missing', 'retare_offset_n'):
        out[key] = _number(row.get(key))
    out['failure_kind'] = row.get('failure_kind') or None
    out['first_stop_kind'] = row.get('first_stop_kind') or None
    return out


def sort_key(row):
    fault = row.get('fault') or 'none'
    return (row['rpm'], row['index'], CASES.index(row['case']) if row['case'] in CASES else 9,
            FAULTS.index(fault) if fault in FAULTS else len(FAULTS))


def _format(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return '' if math.isnan(value) else '%.6g' % value
    return '' if value is None else str(value)


def _csv_text(rows, header=False):
    """`rows` as trials.csv lines (csv's \\r\\n endings), with the header first if `header`."""
    text = io.StringIO(newline='')
    writer = csv.DictWriter(text, fieldnames=TRIAL_COLUMNS, extrasaction='ignore')
    if header:
        writer.writeheader()
    for row in rows:
        writer.writerow({k: _format(row.get(k)) for k in TRIAL_COLUMNS})
    return text.getvalue()


def write_trials_csv(rows, path):
    """trials.csv of `rows`, sorted, written to a temporary file and renamed."""
    with atomic_write(path, newline='') as handle:
        handle.write(_csv_text(sorted(rows, key=sort_key), header=True))


class TrialsAppender:
    """trials.csv while a campaign runs: the header and `rows` (the trials it has before it runs
    any: taken, or kept by --resume) written atomically, then one complete line per finished
    trial, appended with one write as it arrives (nothing finished is lost if the campaign is
    killed). Appending keeps the cost per trial constant; write_trials_csv rewrites the file
    sorted, atomically, when the campaign ends. A line that cannot be written whole (a full
    disk) is cut off again, and the OSError raised names the file: the lines before it stay."""

    def __init__(self, path, rows=()):
        self.path = path
        self._fd = -1
        with atomic_write(path, newline='') as handle:
            handle.write(_csv_text(rows, header=True))
            self._encoding = handle.encoding
        flags = os.O_WRONLY | os.O_APPEND | os.O_CLOEXEC
        self._fd = os.open(path, flags)  # not atomic: the live file, appended while running

    def append(self, row):
        data = _csv_text([row]).encode(self._encoding)
        size = os.fstat(self._fd).st_size
        try:
            while data:
                data = data[os.write(self._fd, data):]
        except OSError as error:
            try:
                os.ftruncate(self._fd, size)  # no half line after the whole ones
            except OSError:
                pass
            raise named(error, self.path)

    def close(self):
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def read_trials_csv(path, whole_lines=False):
    """The rows of trials.csv at `path`. `whole_lines`: a campaign's live file, which a campaign
    killed while appending (or a full disk) can leave with its last line cut: a line without
    its line ending, or without every column, is left out."""
    with open(path, newline='') as handle:
        text = handle.read()
    if whole_lines:
        text = text[:text.rfind('\n') + 1]
    reader = csv.DictReader(io.StringIO(text, newline=''))
    missing = [c for c in ('trial_id', 'case', 'rpm', 'index', 'seed', 'success')
               if c not in (reader.fieldnames or [])]
    if missing:
        raise ValueError('%s: missing columns %s' % (path, ', '.join(missing)))
    return [normalise_row(r) for r in reader
            if not whole_lines or (None not in r and None not in r.values())]
