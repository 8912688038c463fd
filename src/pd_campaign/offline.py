"""The offline harness of the baseline recognizers (pd_campaign.baselines): a recognizer scored on
the labelled force dataset (doc/dataset.md) with the very objects the closed loop runs.

- ``offline_stop`` / ``evaluate_offline``: push a trial's raw samples, in order, through a
  recognizer (reset first, one Python call per sample, exactly as the C++ side does) and read the
  dataset's label at the first sample whose output says ``stop``: correct (inner cortical),
  early (air, outer cortical, cancellous), late (canal: broken through) or none. A recognizer
  that defines ``push_sample(sample)`` is given the whole sample as the closed loop gives it
  (src/python/python_recognizer.cpp): the dict {'t', 'thrust', 'force': (x, y, z), 'torque':
  (x, y, z), 'feed_depth_m', 'spindle_rpm', 'feed_command_m', 'tracker': (x, y, z),
  'tracker_stamp'}, built from the dataset's columns (WRENCH_COLUMNS,
  format 1.1.0 on; the force's z is the thrust, config/recognizer.yaml's axis z); any other
  recognizer ``push(t, thrust)``. A format 1.0.0 dataset has the thrust only: a ``push_sample``
  recognizer on it is a MissingColumnsError naming the missing columns.
- ``tune``: a grid search on the training split, the best few re-scored on the validation
  split, the best of those chosen."""
import itertools
import math
import os

import numpy as np

from pd_campaign import dataset
from pd_campaign.atomic import atomic_write
from pd_campaign.dataset import CANAL, INNER_CORTICAL, WRENCH_COLUMNS
from pd_campaign.outcome import MAX_RESIDUAL_M

# The paper's success band: at most this much of the inner cortex left at the stop [mm].
MAX_RESIDUAL_MM = 1e3 * MAX_RESIDUAL_M
KEY_POINTS = {'idle': 0, 'outer_cortical': 1, 'cancellous': 3, 'inner_cortical': 4}
# The planner's plausibility bounds on the recognizer's layers, the defaults of
# core::TrialSequencer (outer_cortical_max_mm, cancellous_max_mm, recognizer_delay_s): off in the
# dataset's peak-force protocol, on in the closed loop (see plausibility_stop).
PLAUSIBILITY_BOUNDS_MM = (('outer_cortical', 3.5), ('cancellous', 8.3))
RECOGNIZER_DELAY_S = 1.5


# `recognize`'s header of a whole-sample trace (src/tools/recognize.cpp's kWholeHeader): the
# thrust, then dataset.WRENCH_COLUMNS in their order.
WHOLE_SAMPLE_HEADER = ('t,force,force_x,force_y,torque_x,torque_y,torque_z,feed_depth_m,'
                       'spindle_rpm,feed_command_m,tracker_x,tracker_y,tracker_z,tracker_stamp')



def export_traces(npz_path, out_dir):
    """Writes one CSV per trial of a split for `recognize`: `t,force`, or, when the split has
    the whole sample's columns (dataset.WRENCH_COLUMNS, format 1.1.0 on), `recognize`'s
    whole-sample header (WHOLE_SAMPLE_HEADER: a push_sample recognizer gets the whole sample, a
    thrust-only one the thrust as before); returns [(path, labels, residual_mm)]: the trial's
    per-sample layer labels and the inner cortex left below the deepest cut [mm] at each
    sample."""
    with np.load(npz_path) as z:
        columns = {name: z[name] for name in ('trial', 't', 'raw_force_n', 'layer',
                                              'max_depth_cut_m', 'trial_trial_id',
                                              'trial_inner_start_mm', 'trial_inner_cortical_mm')}
        whole = all(name in z.files for name in dataset.WRENCH_COLUMNS)
        if whole:
            columns.update({name: z[name] for name in dataset.WRENCH_COLUMNS})
    os.makedirs(out_dir, exist_ok=True)
    traces = []
    trial = columns['trial']
    for k in range(len(columns['trial_trial_id'])):
        rows = trial == k
        path = os.path.join(out_dir, '%04d.csv' % k)
        data = np.column_stack([columns['t'][rows], columns['raw_force_n'][rows]] + (
            [columns[name][rows] for name in dataset.WRENCH_COLUMNS] if whole else []))
        with atomic_write(path) as handle:
            handle.write((WHOLE_SAMPLE_HEADER if whole else 't,force') + '\n')
            np.savetxt(handle, data, fmt='%.17g', delimiter=',')
        end_mm = columns['trial_inner_start_mm'][k] + columns['trial_inner_cortical_mm'][k]
        traces.append((path, columns['layer'][rows],
                       end_mm - 1e3 * columns['max_depth_cut_m'][rows]))
    return traces


# --- offline evaluation ---------------------------------------------------------------------

def _as_list(values):
    return values.tolist() if hasattr(values, 'tolist') else list(values)


class MissingColumnsError(ValueError):
    """A recognizer that reads the whole sample (push_sample) on a dataset without its columns
    (format 1.0.0: the thrust only)."""


def reads_sample(recognizer):
    """True when `recognizer` defines push_sample (it is given the whole sample, as the closed
    loop's PythonRecognizer gives it)."""
    return callable(getattr(recognizer, 'push_sample', None))


def missing_wrench_columns(columns):
    """The WRENCH_COLUMNS that `columns` (a mapping, or None) lacks, in their order."""
    return [name for name in WRENCH_COLUMNS if columns is None or name not in columns]


def missing_message(missing):
    """The error of a push_sample recognizer on a dataset without the columns `missing`."""
    return ('the recognizer defines push_sample (it reads the whole sample) but the dataset has '
            'no column %s: a format 1.0.0 dataset holds the thrust only (raw_force_n); rebuild '
            'it with campaign_dataset (format 1.1.0 on), or replay a thrust-only recognizer'
            % ', '.join(missing))


def whole_samples(t, raw_force, wrench):
    """The push_sample dicts of a trace: `t`, `raw_force` (the thrust) and `wrench` {column:
    values} of the WRENCH_COLUMNS (MissingColumnsError if one is missing), as Python floats."""
    missing = missing_wrench_columns(wrench)
    if missing:
        raise MissingColumnsError(missing_message(missing))
    (fx, fy, tx, ty, tz, feed, rpm, command, kx, ky, kz,
     stamp) = (_as_list(wrench[name]) for name in WRENCH_COLUMNS)
    return [{'t': ti, 'thrust': fi, 'force': (fx[i], fy[i], fi),
             'torque': (tx[i], ty[i], tz[i]), 'feed_depth_m': feed[i], 'spindle_rpm': rpm[i],
             'feed_command_m': command[i], 'tracker': (kx[i], ky[i], kz[i]),
             'tracker_stamp': stamp[i]}
            for i, (ti, fi) in enumerate(zip(_as_list(t), _as_list(raw_force)))]


def replay(recognizer, t, raw_force, wrench=None):
    """Resets `recognizer` and pushes the samples (t[i], raw_force[i]) in order, as Python
    floats (as the C++ side passes them), until the first output with a true ``stop``: to
    ``push(t, thrust)``, or, when the recognizer defines push_sample, as whole sample dicts
    (whole_samples) built with `wrench` ({column: values} of WRENCH_COLUMNS; a missing one is a
    MissingColumnsError). Returns (index of that sample or None, [(index, state)] at every
    change of the reported state)."""
    if reads_sample(recognizer):
        samples = whole_samples(t, raw_force, wrench)
        recognizer.reset()
        push_sample = recognizer.push_sample
        outputs = (push_sample(sample) for sample in samples)
    else:
        recognizer.reset()
        push = recognizer.push
        outputs = (push(ti, fi) for ti, fi in zip(_as_list(t), _as_list(raw_force)))
    changes, state = [], 'idle'
    for i, out in enumerate(outputs):
        if out:
            if out.get('state', state) != state:
                state = out['state']
                changes.append((i, state))
            if out.get('stop'):
                return i, changes
    return None, changes


def offline_stop(recognizer, t, raw_force, wrench=None):
    """Resets `recognizer`, pushes the samples (t[i], raw_force[i]; the whole samples with
    `wrench` to a push_sample recognizer, see replay) in order and returns the index of the
    first sample whose output has a true ``stop`` (None if none does)."""
    return replay(recognizer, t, raw_force, wrench)[0]


def plausibility_stop(changes, t, depth_mm):
    """The index of the sample at which the planner's plausibility bound would stop the drill
    (core::TrialSequencer::checkLayer), or None: a layer the recognizer reports (outer_cortical
    from its first report of any state after idle, cancellous from its first report) still
    reported `RECOGNIZER_DELAY_S` after the cut went the layer's bound deeper than at that first
    report. `changes`: replay's state changes; `t`, `depth_mm`: arrays of the sample times and
    the deepest cut, up to the recognizer's stop. An approximation: the planner counts its
    predicted advance, not the true deepest cut (the two differ on a moving bone), and checks
    on its own reports and timer ticks."""
    first = None
    for name, bound_mm in PLAUSIBILITY_BOUNDS_MM:
        starts = [k for k, (_, state) in enumerate(changes)
                  if (state != 'idle' if name == 'outer_cortical' else state == name)]
        if not starts:
            continue
        begin = changes[starts[0]][0]
        if begin >= len(depth_mm):  # first reported at the stop itself: nothing to bound
            continue
        end = next((i for i, state in changes[starts[0]:] if state != name), len(t))
        deeper = np.flatnonzero(depth_mm[begin:end] - depth_mm[begin] >= bound_mm)
        if len(deeper):
            through = begin + int(deeper[0])
            trip = through + int(np.searchsorted(t[through:end], t[through] + RECOGNIZER_DELAY_S))
            if trip < end and (first is None or trip < first):
                first = trip
    return first


def _columns(npz):
    """The columns of a split that the offline evaluation reads, read once."""
    wanted = ('t', 'raw_force_n', 'layer', 'trial', 'max_depth_cut_m') + WRENCH_COLUMNS
    return {name: npz[name] for name in npz.files
            if name in wanted or name.startswith('trial_')}


class OfflineTrials:
    """A dataset split (a ``.npz`` path, a loaded npz or a dict of its arrays) cut into trials
    once, so that many recognizers can be scored on it: per trial the samples as Python lists
    (the WRENCH_COLUMNS too, under 'wrench', when the split has them), the labels, and the
    residual inner cortex [mm] at every sample when the columns allow it. `missing`: the
    WRENCH_COLUMNS the split lacks (all of them in a format 1.0.0 dataset)."""

    def __init__(self, data):
        if isinstance(data, OfflineTrials):
            self.trials, self.missing = data.trials, data.missing
            return
        if isinstance(data, (str, bytes, os.PathLike)):
            with np.load(data) as z:
                data = _columns(z)
        elif hasattr(data, 'files'):  # a loaded npz: each access would decompress again
            data = _columns(data)
        trial = np.asarray(data['trial'])
        order = np.argsort(trial, kind='stable')
        bounds = np.flatnonzero(np.diff(trial[order])) + 1
        ids = data.get('trial_trial_id')
        self.missing = missing_wrench_columns(data)
        self.trials = []
        for rows in np.split(order, bounds) if len(order) else []:
            k = int(trial[rows[0]])
            item = {'trial': k, 't': data['t'][rows].tolist(),
                    'raw_force_n': data['raw_force_n'][rows].tolist(),
                    'layer': np.asarray(data['layer'][rows]).astype(int)}
            if not self.missing:
                item['wrench'] = {name: data[name][rows].tolist() for name in WRENCH_COLUMNS}
            if ids is not None and k < len(ids):
                item['trial_id'] = str(ids[k])
                item['case'] = str(data['trial_case'][k]) if 'trial_case' in data else ''
                item['rpm'] = float(data['trial_rpm'][k]) if 'trial_rpm' in data else math.nan
            if all(name in data for name in ('max_depth_cut_m', 'trial_inner_start_mm',
                                              'trial_inner_cortical_mm')):
                end_mm = float(data['trial_inner_start_mm'][k] + data['trial_inner_cortical_mm'][k])
                item['depth_mm'] = 1e3 * np.asarray(data['max_depth_cut_m'][rows], dtype=float)
                item['residual_mm'] = end_mm - item['depth_mm']
                item['t_array'] = np.asarray(data['t'][rows], dtype=float)
            self.trials.append(item)

    def __len__(self):
        return len(self.trials)


def outcome_of(label):
    """correct, early, late or none, from the label at the stop (None: no stop)."""
    if label is None:
        return 'none'
    if label == INNER_CORTICAL:
        return 'correct'
    return 'late' if label >= CANAL else 'early'


def evaluate_offline(make_recognizer, data, trials=None):
    """Scores a recognizer on a dataset split: `make_recognizer()` gives a configured recognizer
    (made once, reset before every trial as in the closed loop); `data`: a ``.npz`` path, a
    loaded npz, a dict of its arrays or an OfflineTrials; `trials`: the trial indices to use
    (default all). Returns (counts, per_trial): counts {'correct', 'early', 'late', 'none',
    'trials', 'shallow', 'implausible'} where, when the split has depths (else 0), shallow
    counts the correct stops with more than 2 mm of the inner cortex left (the paper's criterion
    calls them failures) and implausible the trials in which the planner's plausibility bound
    would have stopped the drill before the recognizer did (plausibility_stop; off in the
    dataset's protocol, on in the closed loop); per_trial: a dict per trial (trial, trial_id,
    case, rpm, stop_index within the trial, t_stop, label, outcome, residual_mm,
    implausible_index)."""
    data = OfflineTrials(data)
    wanted = None if trials is None else {int(k) for k in trials}
    recognizer = make_recognizer()
    if reads_sample(recognizer) and data.missing:
        raise MissingColumnsError(missing_message(data.missing))
    counts = {'correct': 0, 'early': 0, 'late': 0, 'none': 0, 'trials': 0, 'shallow': 0,
              'implausible': 0}
    per_trial = []
    for item in data.trials:
        if wanted is not None and item['trial'] not in wanted:
            continue
        stop, changes = replay(recognizer, item['t'], item['raw_force_n'], item.get('wrench'))
        label = None if stop is None else int(item['layer'][stop])
        outcome = outcome_of(label)
        residual = trip = None
        if 'depth_mm' in item:
            if stop is not None:
                residual = float(item['residual_mm'][stop])
            trip = plausibility_stop(changes, item['t_array'][:stop], item['depth_mm'][:stop])
        counts[outcome] += 1
        counts['trials'] += 1
        if outcome == 'correct' and residual is not None and residual > MAX_RESIDUAL_MM:
            counts['shallow'] += 1
        counts['implausible'] += trip is not None
        per_trial.append({'trial': item['trial'], 'trial_id': item.get('trial_id', ''),
                          'case': item.get('case', ''), 'rpm': item.get('rpm', math.nan),
                          'stop_index': stop, 't_stop': None if stop is None else item['t'][stop],
                          'label': label, 'outcome': outcome, 'residual_mm': residual,
                          'implausible_index': trip})
    return counts, per_trial


def configured(make_recognizer, settings):
    recognizer = make_recognizer()
    recognizer.configure(dict(settings))
    return recognizer


def rank_key(counts):
    """Sort key: more correct stops inside the paper's success band first (a correct stop with
    more than 2 mm of the inner cortex left, `shallow`, fails the task in closed loop), then
    fewer late ones (a breakthrough is worse than an early stop)."""
    return (-(counts['correct'] - counts.get('shallow', 0)), counts['late'])


def tune(make_recognizer, grid, train, validation, keep=5, evaluate=None):
    """Grid search. `make_recognizer()`: an unconfigured recognizer (its class will do); `grid`:
    {name: [text values]}, every combination tried (the names in the grid's order, the values
    in their lists' order); `train`, `validation`: dataset splits (see evaluate_offline). Each
    combination is scored by its offline correct stops on train; the best `keep` on train are
    re-scored on validation and the one with the most correct stops there is chosen (ties: fewer
    late stops on validation, then the better rank on train). `evaluate(make, data)` returns
    (counts, per_trial); default evaluate_offline. Returns {'chosen': settings, 'top': [{settings,
    train, validation}, ...] (in train order), 'train': [(settings, counts), ...] (every
    combination, in grid order)}."""
    evaluate = evaluate or evaluate_offline
    if not isinstance(train, OfflineTrials) and evaluate is evaluate_offline:
        train = OfflineTrials(train)
    if not isinstance(validation, OfflineTrials) and evaluate is evaluate_offline:
        validation = OfflineTrials(validation)
    names = list(grid)
    combos = [dict(zip(names, values))
              for values in itertools.product(*[[str(v) for v in grid[n]] for n in names])]
    if not combos:
        raise ValueError('grid: no combination to try')
    scored = []
    for settings in combos:
        counts, _ = evaluate(lambda s=settings: configured(make_recognizer, s), train)
        scored.append((settings, counts))
    ranking = sorted(range(len(scored)), key=lambda i: (rank_key(scored[i][1]), i))
    top = []
    for i in ranking[:max(1, keep)]:
        settings, counts = scored[i]
        val, _ = evaluate(lambda s=settings: configured(make_recognizer, s), validation)
        top.append({'settings': settings, 'train': counts, 'validation': val})
    best = min(range(len(top)), key=lambda j: (rank_key(top[j]['validation']), j))
    return {'chosen': top[best]['settings'], 'top': top, 'train': scored}
