"""Baseline drilling-state recognizers for the labelled force dataset (doc/dataset.md),
written against the Python recognizer contract of pd_campaign.recognizers, and the offline
harness that scores any recognizer on the dataset with the very objects the closed loop runs.

- ``offline_stop`` / ``evaluate_offline``: push a trial's raw samples, in order, through a
  recognizer (reset first, one Python call per sample, exactly as the C++ side does) and read the
  dataset's label at the first sample whose output says ``stop``: correct (inner cortical),
  early (air, outer cortical, cancellous), late (canal: broken through) or none.
- ``tune``: a grid search on the training split, the best few re-scored on the validation
  split, the best of those chosen.
- ``ChangePointRecognizer``: Bayesian online change-point detection (Adams and MacKay 2007) on
  the logarithm of block means, with a segment logic on relative levels.
- ``LearnedRecognizer``: a small classifier (gradient-boosted trees or logistic regression,
  fitted with scikit-learn by ``train_learned``) exported to JSON and evaluated in plain Python.

Command line::

    python3 -m pd_campaign.baselines train --train train.npz --validation validation.npz \\
        --out model.json [--seed 0] [--kind gradient_boosting|logistic]
    python3 -m pd_campaign.baselines evaluate --data validation.npz \\
        --recognizer pd_campaign.baselines.ChangePointRecognizer [--param name=value ...]
    python3 -m pd_campaign.baselines tune \\
        --recognizer pd_campaign.recognizers.ThresholdRecognizer --train train.npz \\
        --validation validation.npz --grid cortical_n=2.0,2.2 --grid confirm=1,2 [--keep 5]

Never choose anything on the test split: tune on train, select on validation."""

import argparse
import array
import collections
import importlib
import itertools
import json
import math
import os
import sys
import tempfile

import numpy as np

from pd_campaign.atomic import atomic_write
from pd_campaign.dataset import CANAL, INNER_CORTICAL
from pd_campaign.outcome import MAX_RESIDUAL_M
from pd_campaign.recognizers import Recognizer

# The paper's success band: at most this much of the inner cortex left at the stop [mm].
MAX_RESIDUAL_MM = 1e3 * MAX_RESIDUAL_M
KEY_POINTS = {'idle': 0, 'outer_cortical': 1, 'cancellous': 3, 'inner_cortical': 4}
# The planner's plausibility bounds on the recognizer's layers, the defaults of
# core::TrialSequencer (outer_cortical_max_mm, cancellous_max_mm, recognizer_delay_s): off in the
# dataset's peak-force protocol, on in the closed loop (see plausibility_stop).
PLAUSIBILITY_BOUNDS_MM = (('outer_cortical', 3.5), ('cancellous', 8.3))
RECOGNIZER_DELAY_S = 1.5
MODEL_FORMAT = 'pd_campaign.baselines.LearnedRecognizer/1'


# --- offline evaluation ---------------------------------------------------------------------

def _as_list(values):
    return values.tolist() if hasattr(values, 'tolist') else list(values)


def replay(recognizer, t, raw_force):
    """Resets `recognizer` and pushes the samples (t[i], raw_force[i]) in order, as Python
    floats (as the C++ side passes them), until the first output with a true ``stop``. Returns
    (index of that sample or None, [(index, state)] at every change of the reported state)."""
    recognizer.reset()
    push = recognizer.push
    changes, state = [], 'idle'
    for i, (ti, fi) in enumerate(zip(_as_list(t), _as_list(raw_force))):
        out = push(ti, fi)
        if out:
            if out.get('state', state) != state:
                state = out['state']
                changes.append((i, state))
            if out.get('stop'):
                return i, changes
    return None, changes


def offline_stop(recognizer, t, raw_force):
    """Resets `recognizer`, pushes the samples (t[i], raw_force[i]) in order and returns the index
    of the first sample whose output has a true ``stop`` (None if none does)."""
    return replay(recognizer, t, raw_force)[0]


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
    wanted = ('t', 'raw_force_n', 'layer', 'trial', 'max_depth_cut_m')
    return {name: npz[name] for name in npz.files
            if name in wanted or name.startswith('trial_')}


class OfflineTrials:
    """A dataset split (a ``.npz`` path, a loaded npz or a dict of its arrays) cut into trials
    once, so that many recognizers can be scored on it: per trial the samples as Python lists,
    the labels, and the residual inner cortex [mm] at every sample when the columns allow it."""

    def __init__(self, data):
        if isinstance(data, OfflineTrials):
            self.trials = data.trials
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
        self.trials = []
        for rows in np.split(order, bounds) if len(order) else []:
            k = int(trial[rows[0]])
            item = {'trial': k, 't': data['t'][rows].tolist(),
                    'raw_force_n': data['raw_force_n'][rows].tolist(),
                    'layer': np.asarray(data['layer'][rows]).astype(int)}
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
    counts = {'correct': 0, 'early': 0, 'late': 0, 'none': 0, 'trials': 0, 'shallow': 0,
              'implausible': 0}
    per_trial = []
    for item in data.trials:
        if wanted is not None and item['trial'] not in wanted:
            continue
        stop, changes = replay(recognizer, item['t'], item['raw_force_n'])
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


def _configured(make_recognizer, settings):
    recognizer = make_recognizer()
    recognizer.configure(dict(settings))
    return recognizer


def _rank_key(counts):
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
        counts, _ = evaluate(lambda s=settings: _configured(make_recognizer, s), train)
        scored.append((settings, counts))
    ranking = sorted(range(len(scored)), key=lambda i: (_rank_key(scored[i][1]), i))
    top = []
    for i in ranking[:max(1, keep)]:
        settings, counts = scored[i]
        val, _ = evaluate(lambda s=settings: _configured(make_recognizer, s), validation)
        top.append({'settings': settings, 'train': counts, 'validation': val})
    best = min(range(len(top)), key=lambda j: (_rank_key(top[j]['validation']), j))
    return {'chosen': top[best]['settings'], 'top': top, 'train': scored}


# --- parameter checks -----------------------------------------------------------------------

def _positive(value):
    return math.isfinite(value) and value > 0


def _fraction(value):
    return math.isfinite(value) and 0 < value < 1


def _at_least(low):
    return lambda value: value >= low


# --- Bayesian online change-point detection -------------------------------------------------

class RunLengthPosterior:
    """Bayesian online change-point detection (R. P. Adams and D. J. C. MacKay, "Bayesian Online
    Changepoint Detection", arXiv:0710.3742, 2007: the run-length recursion of their Algorithm
    1), for Gaussian observations with an unknown segment mean (conjugate Normal prior
    N(mu0, prior_sd^2)) and a known variance sigma^2, and a constant hazard H = P(a change
    before an observation). The run-length posterior is kept for run lengths 1..max_run (the
    current segment holds the last r observations, the newest included): a run grows with
    probability 1 - H times the observation's predictive density under the run's posterior, and
    a new run starts with probability H times its density under the prior predictive (the
    newest observation is the new segment's first, so r = 1 means "changed just before it").
    The support is truncated at max_run: the mass of longer runs is dropped and the rest
    renormalised, so that each update costs O(max_run) whatever the time."""

    def __init__(self, hazard, sigma, prior_sd, max_run):
        self.log_hazard = math.log(hazard)
        self.log_continue = math.log1p(-hazard)
        self.var = sigma * sigma
        self.prior_var = prior_sd * prior_sd
        self.max_run = int(max_run)
        self.start(0.0)

    def start(self, mu0):
        """Forgets every observation; new segments' means are drawn around mu0."""
        self.mu0 = float(mu0)
        self.log_w = np.zeros(0)  # log P(r | y_1..t), r = 1..len
        self.sums = np.zeros(0)   # sum of the last r observations
        self.runs = np.zeros(0)   # r
        self.count = 0

    def _log_predictive(self, y):
        """log p(y | the last r observations) for every kept run length r."""
        precision = 1.0 / self.prior_var + self.runs / self.var
        mean = (self.mu0 / self.prior_var + self.sums / self.var) / precision
        var = 1.0 / precision + self.var
        return -0.5 * (np.log(2.0 * math.pi * var) + (y - mean) ** 2 / var)

    def update(self, y):
        """One observation: the run-length posterior after it."""
        var0 = self.prior_var + self.var
        new_run = -0.5 * (math.log(2.0 * math.pi * var0) + (y - self.mu0) ** 2 / var0)
        if self.count:
            grown = self.log_w + self._log_predictive(y) + self.log_continue
            log_w = np.concatenate(([new_run + self.log_hazard], grown))[:self.max_run]
        else:
            log_w = np.array([new_run])
        log_w -= log_w.max()
        log_w -= math.log(np.exp(log_w).sum())
        self.log_w = log_w
        self.sums = np.concatenate(([y], self.sums + y))[:self.max_run]
        self.runs = np.arange(1.0, len(log_w) + 1.0)
        self.count += 1

    def map_run(self):
        """The most probable run length (observations in the current segment)."""
        return int(np.argmax(self.log_w)) + 1

    def segment_mean(self, run):
        """Posterior mean of the segment mean, given that the segment holds the last `run`."""
        precision = 1.0 / self.prior_var + run / self.var
        return (self.mu0 / self.prior_var + float(self.sums[run - 1]) / self.var) / precision


class ChangePointRecognizer(Recognizer):
    """Change-point recognizer: Bayesian online change-point detection (BOCPD; Adams and MacKay
    2007, arXiv:0710.3742; RunLengthPosterior) on the block means of `pre_average` raw samples
    (50, as the paper's recognizer averages), with a segment logic on relative levels.

    Observations: y = log(max(block mean, contact_n / 2)), so that a change of the force by a
    factor is a shift of the same size at every spindle speed (forces are lower at higher
    speed), and the detector's noise `sigma` is relative (0.05: about 5 %). Each segment's mean
    is unknown (Normal prior of sd `prior_sd` around the first block in contact); the variance
    is known; the hazard is constant (`hazard` per block, 1/mean segment length); the
    run-length posterior is truncated at `max_run` blocks.

    The current segment is the one of the most probable (MAP) run length; its level is the
    posterior mean of its mean (exp of it, in N); a segment counts only once it holds `min_run`
    blocks (a one-block dip of a breathing contact is no layer). Segment logic: idle until a
    block mean exceeds `contact_n` (contact: the detector starts); outer cortical, its level the
    highest segment level seen; a segment that begins after the peak's segment with a level
    below `cancellous_ratio` x the outer level: cancellous bone; a segment that begins after the
    one current on entering the cancellous bone (a detected change) with a level above
    `inner_ratio` x the outer level and above the lowest cancellous level: the inner cortex,
    once that holds for `confirm` consecutive blocks. Then the stop, latched until reset.

    The outer cortex is the reference because the inner cortex is cut with about the outer
    layer's force (the paper's recognizer normalises by the same amplitude, D); a rise above
    the cancellous minimum alone also fires on the cancellous bone's own density changes.
    The defaults of hazard, min_run, cancellous_ratio, inner_ratio, sigma and confirm are the
    ones `tune` chose on a dataset of `campaign_dataset --trials 40 --rpm 12000,16000,20000`
    (best 5 of 324 combinations on train, chosen on validation: calibration seeds of base seed
    3201 only; its test split was never read)."""

    PARAMETERS = {
        'pre_average': (int, 50, _at_least(1)),
        'contact_n': (float, 0.3, _positive),
        'hazard': (float, 0.02, _fraction),
        'sigma': (float, 0.05, _positive),
        'prior_sd': (float, 1.0, _positive),
        'max_run': (int, 100, _at_least(2)),
        'cancellous_ratio': (float, 0.5, _fraction),
        'inner_ratio': (float, 0.7, lambda v: math.isfinite(v) and 0 < v <= 2),
        'min_run': (int, 2, _at_least(1)),
        'confirm': (int, 1, _at_least(1)),
    }

    def reset(self):
        p = self.params
        self.detector = RunLengthPosterior(p['hazard'], p['sigma'], p['prior_sd'], p['max_run'])
        self.sum = 0.0
        self.count = 0
        self.blocks = 0  # blocks since contact
        self.state = 'idle'
        self.outer_level = 0.0
        self.peak_start = 0
        self.cancellous_start = 0
        self.low = math.inf
        self.above = 0
        self.level = 0.0
        self.stopped_at = None

    def push(self, t, raw_force):
        self.sum += raw_force
        self.count += 1
        if self.count < self.params['pre_average']:
            return {}
        mean = self.sum / self.count
        self.sum = 0.0
        self.count = 0
        if self.state == 'idle':
            if mean > self.params['contact_n']:
                self.detector.start(self._log(mean))
                self.state = 'outer_cortical'
                self._segment(t, mean)
        elif self.state != 'inner_cortical':
            self._segment(t, mean)
        return {'new_average': True, 'averaged_force': mean, 'feature': self.level,
                'state': self.state, 'layer_state': self.state,
                'last_key_point': KEY_POINTS[self.state], 'stop': self.state == 'inner_cortical'}

    def _log(self, mean):
        return math.log(max(mean, 0.5 * self.params['contact_n']))

    def _segment(self, t, mean):
        """One block after contact: the detector's update and the segment logic."""
        p = self.params
        self.detector.update(self._log(mean))
        self.blocks += 1
        run = self.detector.map_run()
        start = self.blocks - run  # blocks since contact before the current segment began
        self.level = math.exp(self.detector.segment_mean(run))
        if run < p['min_run']:
            self.above = 0  # a segment too short to tell a level
        elif self.state == 'outer_cortical':
            if self.level > self.outer_level:
                self.outer_level, self.peak_start = self.level, start
            elif start > self.peak_start and self.level < p['cancellous_ratio'] * self.outer_level:
                self.state, self.cancellous_start, self.low = 'cancellous', start, self.level
        elif self.state == 'cancellous':
            self.low = min(self.low, self.level)
            rises = (start > self.cancellous_start and self.level > self.low and
                     self.level > p['inner_ratio'] * self.outer_level)
            self.above = self.above + 1 if rises else 0
            if self.above >= p['confirm']:
                self.state, self.stopped_at = 'inner_cortical', t

    def stop_reason(self):
        return ('inner cortical layer reached (ChangePointRecognizer): a segment at %.3g N after '
                'the cancellous one, above %.2f x the outer level %.3g N, at t=%.3f s' % (
                    self.level, self.params['inner_ratio'], self.outer_level,
                    self.stopped_at or 0.0))


# --- the learned recognizer -----------------------------------------------------------------

FEATURES = ('block_mean_n', 'recent_mean_n', 'peak_n', 'ratio', 'recent_ratio', 'dip_ratio',
            'rise_ratio', 'slope_ratio', 'since_contact_s', 'since_peak_s')
DIP = FEATURES.index('dip_ratio')


class BlockFeatures:
    """The learned recognizer's features of a block mean, computed causally (from this block and
    the earlier ones only), None before contact (a block mean above `contact_n`): the block mean,
    the mean of the last `window` blocks, the highest block mean since contact (peak), the ratios
    of the two means to the peak, the lowest block mean since the peak over the peak (dip), the
    rise since that lowest one over the peak, the least-squares slope of the last `window` block
    means over the peak [1/block], the time since contact and since the peak [s]. The same
    object computes them for training (train_learned) and in the loop (LearnedRecognizer)."""

    def __init__(self, window, contact_n):
        self.window = int(window)
        self.contact_n = float(contact_n)
        centre = (self.window - 1) / 2.0
        spread = sum((i - centre) ** 2 for i in range(self.window)) or 1.0
        self.slope_weights = [(i - centre) / spread for i in range(self.window)]
        self.reset()

    def reset(self):
        self.recent = collections.deque(maxlen=self.window)
        self.peak = None
        self.dip = None
        self.t_contact = None
        self.t_peak = None

    def add(self, t, mean):
        if self.peak is None:
            if mean <= self.contact_n:
                return None
            self.t_contact = t
            self.peak = -math.inf
        self.recent.append(mean)
        if mean > self.peak:
            self.peak, self.dip, self.t_peak = mean, mean, t
        else:
            self.dip = min(self.dip, mean)
        recent = sum(self.recent) / len(self.recent)
        slope = 0.0
        if len(self.recent) == self.window:
            slope = sum(w * x for w, x in zip(self.slope_weights, self.recent))
        peak = self.peak
        return [mean, recent, peak, mean / peak, recent / peak, self.dip / peak,
                (mean - self.dip) / peak, slope / peak, t - self.t_contact, t - self.t_peak]


def _float32(values):
    """The values rounded to float32, as scikit-learn's trees compare them."""
    return array.array('f', values).tolist()


def _tree_sum(trees, x):
    total = 0.0
    for feature, threshold, left, right, value in trees:
        node = 0
        while left[node] >= 0:
            node = left[node] if x[feature[node]] <= threshold[node] else right[node]
        total += value[node]
    return total


class LearnedModel:
    """A classifier exported by train_learned, read from its JSON and evaluated in plain Python:
    P(inner cortical | the block's features). Kinds: `gradient_boosting` (binary log-loss
    gradient boosting, Friedman 2001: sigmoid(init + learning_rate x the sum of the trees'
    leaves; a tree goes left when float32(x[feature]) <= threshold, as scikit-learn's do) and
    `logistic` (sigmoid(intercept + coef . (x - mean) / scale)). Raises ValueError naming
    `model` when the file is missing or not such a model."""

    def __init__(self, path):
        try:
            with open(path) as handle:
                spec = json.load(handle)
        except (OSError, ValueError) as e:
            raise ValueError('model: cannot read %r: %s' % (path, e)) from None
        try:
            self._load(spec)
        except (AttributeError, KeyError, TypeError, ValueError, IndexError) as e:
            raise ValueError('model: %r is not a %s model file: %s: %s' % (
                path, MODEL_FORMAT, type(e).__name__, e)) from None
        self.path = path

    def _load(self, spec):
        if spec.get('format') != MODEL_FORMAT:
            raise ValueError('format %r' % spec.get('format'))
        names = [str(name) for name in spec['features']]
        if not names or len(set(names)) != len(names) or not set(names) <= set(FEATURES):
            raise ValueError('features %s: distinct names among %s' % (names, list(FEATURES)))
        self.columns = [FEATURES.index(name) for name in names]
        self.everything = self.columns == list(range(len(FEATURES)))
        self.kind = spec['kind']
        self.pre_average = int(spec['pre_average'])
        self.window = int(spec['window'])
        self.contact_n = float(spec['contact_n'])
        self.cancellous_ratio = float(spec['cancellous_ratio'])
        self.threshold = float(spec['threshold'])
        self.confirm = int(spec['confirm'])
        if not (self.pre_average >= 1 and self.window >= 2 and _positive(self.contact_n) and
                _fraction(self.cancellous_ratio) and _fraction(self.threshold) and
                self.confirm >= 1):
            raise ValueError('a setting out of range')
        n = len(self.columns)
        if self.kind == 'gradient_boosting':
            self.init = float(spec['init'])
            self.rate = float(spec['learning_rate'])
            self.trees = [self._tree(tree, n) for tree in spec['trees']]
        elif self.kind == 'logistic':
            self.intercept = float(spec['intercept'])
            mean, scale, coef = spec['mean'], spec['scale'], spec['coef']
            if not len(mean) == len(scale) == len(coef) == n:
                raise ValueError('%d features, %d/%d/%d means/scales/coefficients' % (
                    n, len(mean), len(scale), len(coef)))
            self.weights = [float(c) / float(s) for c, s in zip(coef, scale)]
            self.offset = self.intercept - sum(w * float(m) for w, m in zip(self.weights, mean))
        else:
            raise ValueError('kind %r (gradient_boosting or logistic)' % self.kind)

    @staticmethod
    def _tree(tree, n_features):
        feature = [int(v) for v in tree['feature']]
        threshold = [float(v) for v in tree['threshold']]
        left = [int(v) for v in tree['left']]
        right = [int(v) for v in tree['right']]
        value = [float(v) for v in tree['value']]
        size = len(feature)
        if not size or not len(threshold) == len(left) == len(right) == len(value) == size:
            raise ValueError('a tree with arrays of unequal lengths')
        for node in range(size):
            if left[node] >= 0 and not (node < left[node] < size and node < right[node] < size
                                        and 0 <= feature[node] < n_features):
                raise ValueError('a tree node out of range')
        return feature, threshold, left, right, value

    def probability(self, x):
        """P(inner cortical) of one feature vector (a list in FEATURES order)."""
        if not self.everything:
            x = [x[i] for i in self.columns]
        if self.kind == 'gradient_boosting':
            raw = self.init + self.rate * _tree_sum(self.trees, _float32(x))
        else:
            raw = self.offset + sum(w * v for w, v in zip(self.weights, x))
        if raw < -700.0:
            return 0.0
        return 1.0 / (1.0 + math.exp(-raw))


def _optional(check):
    return lambda value: value is None or check(value)


class LearnedRecognizer(Recognizer):
    """A learned recognizer: a small classifier, fitted by train_learned on the training split
    (scikit-learn; gradient-boosted trees by default, Friedman 2001, "Greedy function
    approximation: a gradient boosting machine", Ann. Statist. 29(5)), exported to the JSON file
    `model` and evaluated here in plain Python (LearnedModel), never with scikit-learn.

    Per block mean of the model's `pre_average` raw samples, the causal features of
    BlockFeatures; the model gives P(the block is in the inner cortex). The stop: the
    probability above `threshold` for `confirm` consecutive blocks after contact (both default
    to the values train_learned chose on the validation split, stored in the model). The states
    it reports (for the planner's plausibility bounds, not for the stop): idle before contact,
    then outer_cortical, cancellous once a block mean fell below the model's cancellous_ratio x
    the peak since contact, inner_cortical at the stop."""

    PARAMETERS = {
        'model': (str, None, lambda value: bool(value)),
        'threshold': (float, None, _optional(_fraction)),
        'confirm': (int, None, _optional(_at_least(1))),
    }

    def __init__(self):
        self.model = None
        super().__init__()

    def configure(self, settings):
        path = settings.get('model', self.params.get('model'))
        if not path:
            raise ValueError('model: no model file given (model=<path of the JSON that '
                             'python3 -m pd_campaign.baselines train writes>)')
        model = LearnedModel(path)
        super().configure(settings)
        self.model = model
        self.reset()

    def reset(self):
        self.sum = 0.0
        self.count = 0
        self.state = 'idle'
        self.above = 0
        self.probability = 0.0
        self.stopped_at = None
        if self.model is not None:
            self.features = BlockFeatures(self.model.window, self.model.contact_n)
            self.threshold = self.params['threshold']
            if self.threshold is None:
                self.threshold = self.model.threshold
            self.confirm = self.params['confirm'] or self.model.confirm

    def push(self, t, raw_force):
        if self.model is None:
            raise RuntimeError('LearnedRecognizer: configure(model=...) first')
        self.sum += raw_force
        self.count += 1
        if self.count < self.model.pre_average:
            return {}
        mean = self.sum / self.count
        self.sum = 0.0
        self.count = 0
        if self.state != 'inner_cortical':
            x = self.features.add(t, mean)
            if x is not None:
                self._decide(t, x)
        return {'new_average': True, 'averaged_force': mean, 'feature': self.probability,
                'state': self.state, 'layer_state': self.state,
                'last_key_point': KEY_POINTS[self.state], 'stop': self.state == 'inner_cortical'}

    def _decide(self, t, x):
        if self.state == 'idle':
            self.state = 'outer_cortical'
        if self.state == 'outer_cortical' and x[DIP] < self.model.cancellous_ratio:
            self.state = 'cancellous'
        self.probability = self.model.probability(x)
        self.above = self.above + 1 if self.probability > self.threshold else 0
        if self.above >= self.confirm:
            self.state, self.stopped_at = 'inner_cortical', t

    def stop_reason(self):
        return ('inner cortical layer reached (LearnedRecognizer, %s): P(inner) > %.2f for %d '
                'blocks, at t=%.3f s' % (self.model.kind, self.threshold, self.confirm,
                                         self.stopped_at or 0.0))

    def describe(self):
        return 'LearnedRecognizer(model=%s, kind=%s, threshold=%s, confirm=%s)' % (
            self.params['model'], self.model.kind if self.model else None,
            getattr(self, 'threshold', None), getattr(self, 'confirm', None))


# --- training -------------------------------------------------------------------------------

LEARNED_DEFAULTS = {'pre_average': 50, 'window': 4, 'contact_n': 0.3, 'cancellous_ratio': 0.6}
THRESHOLDS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
CONFIRMS = (1, 2, 3, 4)


def block_table(data, pre_average, window, contact_n):
    """(X, y, trial) of every block after contact in a split: the BlockFeatures rows, the label
    of the block's last sample (the one at which a recognizer decides) == inner cortical, and
    the trial index. Blocks are cut as the recognizer cuts them, from each trial's first
    sample."""
    rows, labels, trials = [], [], []
    features = BlockFeatures(window, contact_n)
    for item in OfflineTrials(data).trials:
        features.reset()
        t, force, layer = item['t'], item['raw_force_n'], item['layer']
        for end in range(pre_average, len(force) + 1, pre_average):
            x = features.add(t[end - 1], sum(force[end - pre_average:end]) / pre_average)
            if x is not None:
                rows.append(x)
                labels.append(int(layer[end - 1]) == INNER_CORTICAL)
                trials.append(item['trial'])
    return np.array(rows, dtype=float), np.array(labels, dtype=int), np.array(trials)


def _fit(kind, X, y, seed):
    """The fitted scikit-learn model (predict_proba) and its JSON description (no settings)."""
    if kind == 'gradient_boosting':
        from sklearn.ensemble import GradientBoostingClassifier
        fitted = GradientBoostingClassifier(n_estimators=100, max_depth=3, learning_rate=0.1,
                                            random_state=seed).fit(X, y)
        estimators = fitted.estimators_[:, 0]
        trees = [{'feature': e.tree_.feature.tolist(), 'threshold': e.tree_.threshold.tolist(),
                  'left': e.tree_.children_left.tolist(),
                  'right': e.tree_.children_right.tolist(),
                  'value': e.tree_.value[:, 0, 0].tolist()} for e in estimators]
        # The initial raw score (the prior's log-odds): the decision function less the trees.
        probe = X[:1]
        leaves = sum(float(e.predict(probe)[0]) for e in estimators)
        init = float(fitted.decision_function(probe)[0]) - fitted.learning_rate * leaves
        return fitted, {'learning_rate': fitted.learning_rate, 'trees': trees, 'init': init}
    if kind == 'logistic':
        from sklearn.linear_model import LogisticRegression
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler
        fitted = make_pipeline(StandardScaler(),
                               LogisticRegression(C=1.0, max_iter=2000, random_state=seed))
        fitted.fit(X, y)
        scaler, logistic = fitted[0], fitted[-1]
        return fitted, {'mean': scaler.mean_.tolist(), 'scale': scaler.scale_.tolist(),
                        'coef': logistic.coef_[0].tolist(),
                        'intercept': float(logistic.intercept_[0])}
    raise ValueError('kind: %r is neither gradient_boosting nor logistic' % kind)


def _write_model(path, spec):
    with atomic_write(path) as handle:
        json.dump(spec, handle, indent=1, sort_keys=True)
        handle.write('\n')


def train_learned(train_npz, validation_npz, out_json, seed=0, kind='gradient_boosting',
                  features=FEATURES, thresholds=THRESHOLDS, confirms=CONFIRMS, **settings):
    """Fits the learned recognizer's classifier on the training split (block features of
    BlockFeatures, target: the block's label is inner cortical), checks that the exported model
    gives scikit-learn's probabilities, chooses `threshold` and `confirm` on the validation
    split by offline correct stops (evaluate_offline on LearnedRecognizer itself; ties: fewer
    late stops, then the grid's order: lower thresholds, then fewer blocks), and writes the
    model, with the choice as its defaults, to `out_json` (atomically). `settings` may override
    LEARNED_DEFAULTS (pre_average, window, contact_n, cancellous_ratio). Deterministic for a
    given seed. `features`: the BlockFeatures names the model uses (default all). Returns the
    model's JSON dict."""
    unknown = set(settings) - set(LEARNED_DEFAULTS)
    if unknown:
        raise ValueError('%s: unknown setting of train_learned' % sorted(unknown)[0])
    features = list(features)
    if not features or len(set(features)) != len(features) or not set(features) <= set(FEATURES):
        raise ValueError('features: %s are not distinct names among %s' % (features, FEATURES))
    config = dict(LEARNED_DEFAULTS, **settings)
    train, validation = OfflineTrials(train_npz), OfflineTrials(validation_npz)
    X, y, _ = block_table(train, config['pre_average'], config['window'], config['contact_n'])
    X = X[:, [FEATURES.index(name) for name in features]]
    if len(set(y.tolist())) < 2:
        raise ValueError('train: the training split needs blocks in and out of the inner cortex')
    fitted, spec = _fit(kind, X, y, seed)
    spec.update(config, format=MODEL_FORMAT, kind=kind, features=features, threshold=0.5,
                confirm=1)
    with tempfile.TemporaryDirectory(prefix='learned_') as folder:
        draft = os.path.join(folder, 'model.json')
        _write_model(draft, spec)
        exported = LearnedModel(draft)
        probe = X[::max(1, len(X) // 500)]
        full = np.zeros((len(probe), len(FEATURES)))
        full[:, exported.columns] = probe
        ours = np.array([exported.probability(row) for row in full.tolist()])
        theirs = fitted.predict_proba(probe)[:, 1]
        if not np.allclose(ours, theirs, rtol=0, atol=1e-9):
            raise RuntimeError('the exported model differs from scikit-learn\'s by %.3g' %
                               float(np.max(np.abs(ours - theirs))))
        choices = []
        for threshold, confirm in itertools.product(thresholds, confirms):
            settings = {'model': draft, 'threshold': str(threshold), 'confirm': str(confirm)}
            counts, _ = evaluate_offline(
                lambda s=settings: _configured(LearnedRecognizer, s), validation)
            choices.append(((threshold, confirm), counts))
    best = min(range(len(choices)), key=lambda i: (_rank_key(choices[i][1]), i))
    (threshold, confirm), counts = choices[best]
    spec.update(threshold=threshold, confirm=confirm)
    spec['training'] = {
        'seed': seed, 'train_blocks': int(len(y)), 'train_inner_blocks': int(y.sum()),
        'train_trials': len(train), 'validation_trials': len(validation),
        'validation_counts': counts,
        'validation_grid': [{'threshold': c[0], 'confirm': c[1], 'counts': n}
                            for c, n in choices]}
    _write_model(out_json, spec)
    return spec


# --- command line ---------------------------------------------------------------------------

def load_class(name):
    """The class named <module>.<Class> (a leading python: is allowed)."""
    name = name[len('python:'):] if name.startswith('python:') else name
    module, _, cls = name.rpartition('.')
    if not module:
        raise ValueError('recognizer: expected <module>.<Class>, got %r' % name)
    return getattr(importlib.import_module(module), cls)


def _pairs(items, what):
    out = {}
    for item in items or []:
        name, sep, value = item.partition('=')
        if not sep or not name:
            raise ValueError('%s: expected name=value, got %r' % (what, item))
        out[name] = value
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(prog='python3 -m pd_campaign.baselines',
                                     description=__doc__.split('\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True)
    train = commands.add_parser('train', help='fit LearnedRecognizer\'s model')
    train.add_argument('--train', required=True)
    train.add_argument('--validation', required=True)
    train.add_argument('--out', required=True)
    train.add_argument('--seed', type=int, default=0)
    train.add_argument('--kind', default='gradient_boosting',
                       choices=('gradient_boosting', 'logistic'))
    train.add_argument('--features', default=','.join(FEATURES),
                       help='comma-separated features of the model (default: all: %(default)s)')
    evaluate = commands.add_parser('evaluate', help='offline stops of a recognizer on a split')
    evaluate.add_argument('--data', required=True)
    evaluate.add_argument('--recognizer', required=True)
    evaluate.add_argument('--param', action='append', metavar='NAME=VALUE')
    tuning = commands.add_parser('tune', help='grid search on train, chosen on validation')
    tuning.add_argument('--recognizer', required=True)
    tuning.add_argument('--train', required=True)
    tuning.add_argument('--validation', required=True)
    tuning.add_argument('--grid', action='append', required=True, metavar='NAME=V1,V2,...')
    tuning.add_argument('--param', action='append', metavar='NAME=VALUE',
                        help='fixed settings beside the grid')
    tuning.add_argument('--keep', type=int, default=5)
    args = parser.parse_args(argv)
    try:
        if args.command == 'train':
            spec = train_learned(args.train, args.validation, args.out, seed=args.seed,
                                 kind=args.kind, features=args.features.split(','))
            result = {'threshold': spec['threshold'], 'confirm': spec['confirm'],
                      'validation': spec['training']['validation_counts']}
        elif args.command == 'evaluate':
            cls, settings = load_class(args.recognizer), _pairs(args.param, 'param')
            result, _ = evaluate_offline(lambda: _configured(cls, settings), args.data)
        else:
            cls, fixed = load_class(args.recognizer), _pairs(args.param, 'param')
            grid = {name: values.split(',')
                    for name, values in _pairs(args.grid, 'grid').items()}
            grid.update({name: [value] for name, value in fixed.items()})
            result = tune(cls, grid, args.train, args.validation, keep=args.keep)
            del result['train']
    except ValueError as e:
        sys.stderr.write('pd_campaign.baselines: %s\n' % e)
        return 2
    json.dump(result, sys.stdout, indent=1)
    sys.stdout.write('\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
