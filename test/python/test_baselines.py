"""Baseline recognizers for the labelled dataset (pd_campaign.baselines): the offline
harness on traces with a known answer; the change-point and the learned recognizer stop inside
the inner cortex of synthetic three-layer force profiles at two force scales; parameter errors
name the parameter; train_learned on a small campaign_dataset writes a deterministic model that
LearnedRecognizer evaluates without scikit-learn; tune picks the best grid point."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from pd_campaign.change_point import ChangePointRecognizer
from pd_campaign.dataset import INNER_CORTICAL
from pd_campaign.learned import CONFIRMS, THRESHOLDS, LearnedRecognizer, train_learned
from pd_campaign.offline import evaluate_offline, offline_stop, plausibility_stop, tune
from pd_campaign.recognizers import Recognizer, ThresholdRecognizer

RATE_HZ = 1000.0 / 3.0  # the simulated DAQ's rate
STATES = {'idle', 'outer_cortical', 'outer_punctured', 'cancellous', 'inner_cortical',
          'breakthrough'}
KEYS = {'state', 'layer_state', 'new_average', 'averaged_force', 'feature', 'last_key_point',
        'stop'}


# --- synthetic force profiles ---------------------------------------------------------------

def synthetic_trial(scale, rng, outer_s=4.0, cancellous_s=7.0, inner_s=4.0):
    """(t, raw force, layer) of a synthetic trial: 3 s of air; the outer cortex (a 1.5 s ramp to
    3 N x scale, then flat); the cancellous bone (a 1 s fall to 1 N x scale, then a slow 15 %
    wobble); the inner cortex (a 1.5 s rise back to 3 N x scale, then flat); 2 s of canal; white
    sensor noise of 0.05 N throughout."""
    def ramp(u, seconds):
        return np.minimum(u / seconds, 1.0)

    pieces = [(3.0, 0, lambda u: 0.0 * u),
              (outer_s, 1, lambda u: 3.0 * ramp(u, 1.5)),
              (cancellous_s, 2, lambda u: 3.0 - 2.0 * ramp(u, 1.0) +
               0.15 * np.sin(2.0 * math.pi * u / 2.5) * (u > 1.0)),
              (inner_s, 3, lambda u: 1.0 + 2.0 * ramp(u, 1.5)),
              (2.0, 4, lambda u: 0.0 * u)]
    force, layer = [], []
    for seconds, label, shape in pieces:
        u = np.arange(int(round(seconds * RATE_HZ))) / RATE_HZ
        force.append(scale * shape(u))
        layer.append(np.full(len(u), label))
    force, layer = np.concatenate(force), np.concatenate(layer)
    force = force + rng.normal(0.0, 0.05, len(force))
    return 1.0 + np.arange(len(force)) / RATE_HZ, force, layer


def synthetic_split(trials):
    """A split's arrays (the columns evaluate_offline and train_learned read) of the trials
    [(t, force, layer)]."""
    return {'t': np.concatenate([t for t, _, _ in trials]),
            'raw_force_n': np.concatenate([f for _, f, _ in trials]),
            'layer': np.concatenate([lay for _, _, lay in trials]),
            'trial': np.concatenate([np.full(len(t), k) for k, (t, _, _) in enumerate(trials)]),
            'trial_trial_id': np.array(['synthetic-%d' % k for k in range(len(trials))])}


def jittered_trials(seed, scales):
    rng = np.random.default_rng(seed)
    return [synthetic_trial(scale, rng, outer_s=rng.uniform(3.5, 4.5),
                            cancellous_s=rng.uniform(5.0, 9.0), inner_s=rng.uniform(3.5, 5.0))
            for scale in scales]


@pytest.fixture(scope='module')
def synthetic_model(tmp_path_factory):
    """A LearnedRecognizer model trained and selected on synthetic profiles of many scales."""
    folder = tmp_path_factory.mktemp('synthetic')
    scales = [0.4, 0.5, 0.7, 0.85, 1.0, 1.2, 1.4, 1.6]
    train = synthetic_split(jittered_trials(1, scales + scales))
    validation = synthetic_split(jittered_trials(2, scales))
    path = str(folder / 'model.json')
    train_learned(train, validation, path, seed=0)
    return path


class StopAbove(Recognizer):
    """Stops at the first raw sample above `force_n` (a recognizer with a known answer)."""
    PARAMETERS = {'force_n': (float, 1.0, lambda v: v > 0)}

    def reset(self):
        self.stopped = False

    def push(self, t, raw_force):
        self.stopped = self.stopped or raw_force > self.params['force_n']
        return {'stop': self.stopped}


def stop_label(recognizer, trial):
    t, force, layer = trial
    stop = offline_stop(recognizer, t, force)
    return None if stop is None else int(layer[stop])


# --- the offline harness --------------------------------------------------------------------

def test_offline_stop_is_the_first_sample_that_stops_and_evaluate_counts_the_labels():
    recognizer = StopAbove()
    force = np.array([0.0, 0.5, 2.0, 0.1, 3.0])
    assert offline_stop(recognizer, np.arange(5.0), force) == 2
    assert offline_stop(recognizer, [0.0, 1.0], [0.2, 0.3]) is None  # reset: not latched
    # Four trials whose first sample above 1 N lies in the inner cortex, in the cancellous bone,
    # in the canal and nowhere.
    layer = np.array([0, 1, 2, 3, 4])
    forces = [[0, 0, 0, 2, 2], [0, 0, 2, 0, 0], [0, 0, 0, 0, 5], [0, 0, 0, 0, 0]]
    trials = [(np.arange(5.0), np.array(f, dtype=float), layer) for f in forces]
    data = synthetic_split(trials)
    counts, per_trial = evaluate_offline(StopAbove, data)
    assert counts == {'correct': 1, 'early': 1, 'late': 1, 'none': 1, 'trials': 4, 'shallow': 0,
                      'implausible': 0}
    assert [p['outcome'] for p in per_trial] == ['correct', 'early', 'late', 'none']
    assert [p['stop_index'] for p in per_trial] == [3, 2, 4, None]
    assert [p['label'] for p in per_trial] == [3, 2, 4, None]
    assert [p['trial_id'] for p in per_trial] == ['synthetic-%d' % k for k in range(4)]
    subset = evaluate_offline(StopAbove, data, trials=[1, 3])
    assert subset[0]['trials'] == 2 and [p['trial'] for p in subset[1]] == [1, 3]
    # Trials whose rows interleave are cut into the same trials.
    order = np.lexsort((data['trial'], np.tile(np.arange(5), 4)))
    interleaved = {k: (v[order] if k != 'trial_trial_id' else v) for k, v in data.items()}
    assert list(interleaved['trial'][:4]) == [0, 1, 2, 3]
    again = evaluate_offline(StopAbove, interleaved)
    assert again[0] == counts and again[1] == per_trial


def test_the_residual_of_a_correct_stop_is_read_from_the_depths():
    layer = np.array([1, 2, 3, 3, 4])
    data = synthetic_split([(np.arange(5.0), np.array([0, 0, 2.0, 2, 2]), layer),
                            (np.arange(5.0), np.array([0, 0, 0, 2.0, 2]), layer)])
    data.update(max_depth_cut_m=np.array([1, 2, 3, 4.5, 6] * 2) * 1e-3,
                trial_inner_start_mm=np.array([3.0, 3.0]),
                trial_inner_cortical_mm=np.array([3.0, 3.0]))
    counts, per_trial = evaluate_offline(StopAbove, data)
    assert counts['correct'] == 2 and counts['shallow'] == 1  # 3 mm left, then 1.5 mm
    assert [p['residual_mm'] for p in per_trial] == pytest.approx([3.0, 1.5])


def test_the_planner_plausibility_bound_is_replayed_offline():
    # 100 samples per second; the cut goes 0.01 mm deeper per sample (1 mm/s).
    t, depth = np.arange(1000) / 100.0, np.arange(1000) * 0.01
    bound = plausibility_stop
    # The outer layer left after 2.9 mm, the cancellous bone's 8.3 mm never reached: no trip.
    assert bound([(10, 'outer_cortical'), (300, 'cancellous')], t, depth) is None
    # Outer for 5.9 mm: its 3.5 mm bound passed at sample 360, the trip 1.5 s later.
    assert bound([(10, 'outer_cortical'), (600, 'cancellous')], t, depth) in (510, 511)
    # The cancellous bound from its first report (sample 10): passed at 840, the trip at 990,
    # unless the recognizer reported another layer before.
    changes = [(5, 'outer_cortical'), (10, 'cancellous')]
    assert bound(changes, t, depth) in (990, 991)
    assert bound(changes + [(900, 'inner_cortical')], t, depth) is None
    assert bound(changes, t[:950], depth[:950]) is None  # the recognizer stopped at 950
    assert bound([], t, depth) is None


# --- the recognizers on synthetic profiles ---------------------------------------------------

@pytest.mark.parametrize('scale', [1.0, 0.5])
def test_the_change_point_recognizer_stops_inside_the_inner_cortex(scale):
    recognizer = ChangePointRecognizer()
    recognizer.configure({})
    for seed in range(3):
        trial = synthetic_trial(scale, np.random.default_rng(seed))
        assert stop_label(recognizer, trial) == INNER_CORTICAL, (scale, seed)


@pytest.mark.parametrize('scale', [1.0, 0.5])
def test_the_learned_recognizer_stops_inside_the_inner_cortex(synthetic_model, scale):
    recognizer = LearnedRecognizer()
    recognizer.configure({'model': synthetic_model})
    for seed in range(10, 13):
        trial = synthetic_trial(scale, np.random.default_rng(seed))
        assert stop_label(recognizer, trial) == INNER_CORTICAL, (scale, seed)


def test_a_profile_with_no_inner_cortex_brings_no_stop(synthetic_model):
    rng = np.random.default_rng(5)
    t, force, layer = synthetic_trial(1.0, rng, inner_s=0.0)
    learned = LearnedRecognizer()
    learned.configure({'model': synthetic_model})
    for recognizer in (ChangePointRecognizer(), learned):
        assert offline_stop(recognizer, t, force) is None, type(recognizer).__name__


def test_the_outputs_keep_the_contract(synthetic_model):
    learned = LearnedRecognizer()
    learned.configure({'model': synthetic_model})
    t, force, _ = synthetic_trial(1.0, np.random.default_rng(3))
    for recognizer in (ChangePointRecognizer(), learned):
        recognizer.reset()
        states, averages = [], 0
        for ti, fi in zip(t.tolist(), force.tolist()):
            out = recognizer.push(ti, fi)
            assert set(out) <= KEYS, out
            if out:
                averages += 1
                assert out['new_average'] is True and out['state'] in STATES
                assert out['last_key_point'] in (0, 1, 3, 4)
                states.append(out['state'])
        assert averages == len(t) // 50
        seen = [s for k, s in enumerate(states) if k == 0 or s != states[k - 1]]
        assert seen == ['idle', 'outer_cortical', 'cancellous', 'inner_cortical'], seen
        assert 'inner cortical' in recognizer.stop_reason()
        assert type(recognizer).__name__ in recognizer.describe()


# --- parameters and model files --------------------------------------------------------------

@pytest.mark.parametrize('name,value', [('hazard', '1.5'), ('sigma', 'abc'), ('max_run', '1'),
                                        ('inner_ratio', 'nan'), ('pre_average', '0'),
                                        ('cancellous_ratio', '1'), ('confirm', '0'),
                                        ('no_such_parameter', '1')])
def test_a_bad_change_point_parameter_is_named(name, value):
    recognizer = ChangePointRecognizer()
    with pytest.raises(ValueError) as error:
        recognizer.configure({name: value})
    assert str(error.value).startswith(name + ':'), error.value
    assert recognizer.params == ChangePointRecognizer().params  # nothing half-set


def test_a_bad_learned_parameter_is_named(synthetic_model):
    for settings, name in (({'model': synthetic_model, 'threshold': '1.5'}, 'threshold'),
                           ({'model': synthetic_model, 'confirm': 'x'}, 'confirm'),
                           ({'model': synthetic_model, 'window': '3'}, 'window'),
                           ({}, 'model'), ({'model': ''}, 'model')):
        with pytest.raises(ValueError) as error:
            LearnedRecognizer().configure(settings)
        assert str(error.value).startswith(name + ':'), error.value
    recognizer = LearnedRecognizer()
    recognizer.configure({'model': synthetic_model, 'threshold': '0.95', 'confirm': '3'})
    assert 'threshold=0.95, confirm=3' in recognizer.describe()


def test_a_missing_or_broken_model_file_is_a_value_error_naming_model(synthetic_model,
                                                                      tmp_path):
    with open(synthetic_model) as handle:
        good = json.load(handle)
    broken = {'not_json.json': '{"format": ',
              'other_format.json': json.dumps(dict(good, format='something else')),
              'no_trees.json': json.dumps({k: v for k, v in good.items() if k != 'trees'}),
              'bad_tree.json': json.dumps(dict(good, trees=[dict(good['trees'][0],
                                                                 left=[5, -1])])),
              'bad_feature.json': json.dumps(dict(good, features=['block_mean_n', 'nope'])),
              'bad_threshold.json': json.dumps(dict(good, threshold=2.0)),
              'list.json': '[1, 2]'}
    paths = [str(tmp_path / 'missing.json')]
    for name, text in broken.items():
        (tmp_path / name).write_text(text)
        paths.append(str(tmp_path / name))
    for path in paths:
        with pytest.raises(ValueError) as error:
            LearnedRecognizer().configure({'model': path})
        assert str(error.value).startswith('model:'), (path, error.value)
        assert path in str(error.value)


# --- training on the small dataset -----------------------------------------------------------

def test_train_learned_writes_a_deterministic_model_that_runs_without_sklearn(small_dataset,
                                                                             tmp_path):
    first, second = str(tmp_path / 'first.json'), str(tmp_path / 'second.json')
    spec = train_learned(str(small_dataset / 'train.npz'), str(small_dataset / 'validation.npz'),
                         first, seed=0)
    result = subprocess.run(
        [sys.executable, '-m', 'pd_campaign.baselines', 'train', '--train',
         str(small_dataset / 'train.npz'), '--validation', str(small_dataset / 'validation.npz'),
         '--out', second, '--seed', '0'], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(first) as a, open(second) as b:
        assert a.read() == b.read(), 'the same seed writes the same model'
    assert json.loads(result.stdout)['threshold'] == spec['threshold']
    assert spec['threshold'] in THRESHOLDS and spec['confirm'] in CONFIRMS
    assert spec['training']['train_trials'] == 9 and spec['training']['validation_trials'] == 3
    # In a fresh interpreter (as the C++ side embeds one): the model loads, runs and gives the
    # same outputs twice, with scikit-learn never imported.
    script = '\n'.join([
        'import json, sys', 'import numpy as np',
        'from pd_campaign.baselines import LearnedRecognizer',
        'z = np.load(sys.argv[2])', 'rows = z["trial"] == 0',
        'runs = []', 'recognizer = LearnedRecognizer()',
        'recognizer.configure({"model": sys.argv[1]})',
        'for _ in range(2):',
        '    recognizer.reset()',
        '    runs.append([recognizer.push(t, f) for t, f in',
        '                 zip(z["t"][rows].tolist(), z["raw_force_n"][rows].tolist())])',
        'assert runs[0] == runs[1]',
        'assert "sklearn" not in sys.modules, "scikit-learn imported in the loop"',
        'print(json.dumps({"averages": sum(bool(o) for o in runs[0]),',
        '                  "probabilities": len({o["feature"] for o in runs[0] if o})}))'])
    result = subprocess.run([sys.executable, '-c', script, first,
                             str(small_dataset / 'validation.npz')],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    counts = json.loads(result.stdout)
    assert counts['averages'] > 100 and counts['probabilities'] > 10, counts


def test_the_offline_harness_reads_the_dataset(small_dataset):
    counts, per_trial = evaluate_offline(ChangePointRecognizer, str(small_dataset / 'train.npz'))
    assert counts['trials'] == 9 == len(per_trial)
    assert sum(counts[k] for k in ('correct', 'early', 'late', 'none')) == 9
    assert {p['case'] for p in per_trial} == {'stationary', 'uncompensated', 'compensated'}
    # The stationary trials are easy: every recognizer here stops in their inner cortex.
    stationary = [p for p in per_trial if p['case'] == 'stationary']
    assert all(p['outcome'] == 'correct' for p in stationary), stationary
    assert all(0 < p['residual_mm'] < 3.5 for p in stationary), stationary


# --- tuning ---------------------------------------------------------------------------------

def test_tune_picks_the_grid_point_a_synthetic_scoring_makes_best():
    # Correct stops peak at a=2, b=y on train; validation prefers (2, y) over the runner-up (3, y)
    # only through fewer late stops.
    def score(make, data):
        params = make().params
        a, b = params['a'], params['b']
        correct = 10 - abs(a - 2) - (b != 'y') * 3
        if data == 'validation':
            correct = 10 - (a == 1) * 5 - (b != 'y') * 3
        late = a if data == 'validation' else 0
        return {'correct': correct, 'early': 0, 'late': late, 'none': 0, 'trials': 10}, []

    class Grid(Recognizer):
        PARAMETERS = {'a': (int, 0, lambda v: True), 'b': (str, 'x', lambda v: True)}

    result = tune(Grid, {'a': [1, 2, 3], 'b': ['x', 'y']}, 'train', 'validation', keep=3,
                  evaluate=score)
    assert result['chosen'] == {'a': '2', 'b': 'y'}
    assert [t['settings'] for t in result['top']] == [
        {'a': '2', 'b': 'y'}, {'a': '1', 'b': 'y'}, {'a': '3', 'b': 'y'}]
    assert len(result['train']) == 6 and result['train'][0][0] == {'a': '1', 'b': 'x'}


def test_tune_on_synthetic_profiles_finds_the_thresholds_that_work():
    train = synthetic_split(jittered_trials(3, [1.0, 1.0, 1.0]))
    validation = synthetic_split(jittered_trials(4, [1.0, 1.0]))
    grid = {'cortical_n': ['5.0', '0.9', '2.2'], 'cancellous_n': ['1.6'], 'confirm': ['1', '2']}
    result = tune(ThresholdRecognizer, grid, train, validation, keep=2)
    # 5 N is never reached; 0.9 N is below the cancellous bone's force (an early stop).
    assert [counts['correct'] for _, counts in result['train']] == [0, 0, 0, 0, 3, 3]
    assert result['chosen'] == {'cortical_n': '2.2', 'cancellous_n': '1.6', 'confirm': '1'}
    assert result['top'][0]['validation']['correct'] == 2


def test_one_positive_check_refuses_inf_and_nan():
    """The plugins' one `positive` check (pd_campaign.checks): a finite number above 0, for the
    threshold baseline as for the change-point one."""
    from pd_campaign.checks import positive
    assert positive(0.5) and positive(3)
    assert not any(positive(v) for v in (0, -1.0, float('inf'), float('nan')))
    for recognizer in (ThresholdRecognizer(), ChangePointRecognizer()):
        name = 'cortical_n' if isinstance(recognizer, ThresholdRecognizer) else 'sigma'
        with pytest.raises(ValueError, match=name):
            recognizer.configure({name: 'inf'})
