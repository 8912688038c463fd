"""LearnedRecognizer: a small classifier (gradient-boosted trees or logistic regression, fitted
with scikit-learn by ``train_learned``) exported to JSON and evaluated in plain Python; a baseline
recognizer of the leaderboard (`python:pd_campaign.baselines.LearnedRecognizer`)."""
import array
import collections
import itertools
import json
import math
import os
import tempfile

import numpy as np

from pd_campaign.atomic import atomic_write
from pd_campaign.checks import at_least, fraction, optional, positive
from pd_campaign.dataset import INNER_CORTICAL
from pd_campaign.offline import KEY_POINTS, OfflineTrials, configured, evaluate_offline, rank_key
from pd_campaign.recognizers import BlockMean, Recognizer

# The model file's format (its `format` key), named by the class's documented path.
MODEL_FORMAT = 'pd_campaign.baselines.LearnedRecognizer/1'


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
        if not (self.pre_average >= 1 and self.window >= 2 and positive(self.contact_n) and
                fraction(self.cancellous_ratio) and fraction(self.threshold) and
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
        'threshold': (float, None, optional(fraction)),
        'confirm': (int, None, optional(at_least(1))),
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
        self.state = 'idle'
        self.above = 0
        self.probability = 0.0
        self.stopped_at = None
        if self.model is not None:
            self.block_mean = BlockMean(self.model.pre_average)
            self.features = BlockFeatures(self.model.window, self.model.contact_n)
            self.threshold = self.params['threshold']
            if self.threshold is None:
                self.threshold = self.model.threshold
            self.confirm = self.params['confirm'] or self.model.confirm

    def push(self, t, raw_force):
        if self.model is None:
            raise RuntimeError('LearnedRecognizer: configure(model=...) first')
        mean = self.block_mean.add(raw_force)
        if mean is None:
            return {}
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
                lambda s=settings: configured(LearnedRecognizer, s), validation)
            choices.append(((threshold, confirm), counts))
    best = min(range(len(choices)), key=lambda i: (rank_key(choices[i][1]), i))
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
