"""pd_campaign.api and campaign_submit: a campaign from keywords gives the command line's trials,
a refused keyword is named, a dataset split and the offline and closed-loop scores come back as
tables, an entry from outside the package reaches the board with its result file, and the
example notebook runs under nbconvert and draws its figure."""
import csv
import importlib
import json
import os
import re
import shutil
import subprocess
import textwrap

import numpy as np
import pytest

from pd_campaign import api, dataset

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
NOTEBOOK = os.path.join(ROOT, 'doc', 'notebooks', 'campaign_api.ipynb')

# A submitter's recognizer and its training, written outside the package: the block mean
# rising `rise_n` over its lowest value since contact is the stop; `fit` sets the contact
# threshold from the training split's outer-cortex samples and keeps it in a file of its own.
MODULE = textwrap.dedent('''
    import json
    import os

    import numpy as np

    from pd_campaign.atomic import atomic_write
    from pd_campaign.recognizers import BlockMean, Recognizer


    class MeanRise(Recognizer):
        PARAMETERS = {'pre_average': (int, 50, lambda v: v > 0),
                      'contact_n': (float, 1.0, lambda v: v > 0),
                      'rise_n': (float, 1.0, lambda v: v > 0)}

        def reset(self):
            self.block = BlockMean(self.params['pre_average'])
            self.low, self.state = None, 'idle'

        def push(self, t, raw_force):
            mean = self.block.add(raw_force)
            if mean is None:
                return {}
            if self.state == 'idle' and mean > self.params['contact_n']:
                self.state, self.low = 'outer_cortical', mean
            elif self.state != 'idle':
                self.low = min(self.low, mean)
                if mean > self.low + self.params['rise_n']:
                    self.state = 'inner_cortical'
            return {'new_average': True, 'averaged_force': mean, 'state': self.state,
                    'stop': self.state == 'inner_cortical'}


    def fit(train, validation, out):
        assert train.name == 'train' and validation.name == 'validation'
        outer = train.samples[train.samples['layer'] == 1]['raw_force_n']
        contact = 0.5 * float(np.median(outer))
        with atomic_write(os.path.join(out, 'mean_rise_fit.json')) as handle:
            json.dump({'contact_n': contact, 'trials': len(train.trials)}, handle)
        return {'contact_n': contact}
''')


def write_entry(folder, **changes):
    """The submitter's module and entry YAML in `folder` (no package path holds it); the YAML's
    path."""
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, 'mean_rise.py'), 'w') as handle:
        handle.write(MODULE)
    entry = dict({'name': 'mean_rise', 'module': 'mean_rise.py', 'class': 'MeanRise',
                  'source': 'a block-mean rise after the cancellous minimum',
                  'tune': {'rise_n': [0.6, 1.2]}, 'fit': 'fit'}, **changes)
    path = os.path.join(folder, 'entry.yaml')
    with open(path, 'w') as handle:
        json.dump(entry, handle)  # JSON is YAML
    return path


def test_a_campaign_from_keywords_is_the_command_lines(tmp_path):
    keywords = dict(case=['stationary', 'compensated'], rpm=[12000, 16000], trials=1, seed=3,
                    recognizer_params={'pre_average_s': 0.12})
    campaign = api.run_campaign(out=str(tmp_path / 'api'), **keywords)
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--out', str(tmp_path / 'cli'), '--case',
         'stationary,compensated', '--rpm', '12000,16000', '--trials', '1', '--seed', '3',
         '--recognizer-param', 'pre_average_s=0.12', '--no-figures'],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    with open(tmp_path / 'cli' / 'trials.csv') as handle:
        expected = list(csv.DictReader(handle))
    with open(tmp_path / 'api' / 'trials.csv') as handle:
        assert list(csv.DictReader(handle)) == expected
    assert campaign.status == 0 and len(campaign.rows) == 4
    assert list(campaign.rows['trial_id']) == [row['trial_id'] for row in expected]
    with open(tmp_path / 'cli' / 'design.json') as handle:
        assert json.load(handle)['meta']['recognizer_params'] == {'pre_average_s': '0.12'}
    for trial_id, trace in campaign.traces().items():
        with open(tmp_path / 'cli' / 'traces' / ('%s.json' % trial_id)) as handle:
            assert list(trace['force']) == json.load(handle)['force']
    trial = api.run_trial(case='stationary', rpm=12000, seed=3, out=str(tmp_path / 'one'))
    assert trial.row['trial_id'] == 'stationary-12000-000'
    assert trial.row['seed'] == campaign.rows['seed'][0] and len(trial.trace) > 0


@pytest.mark.parametrize('keywords, named', [
    ({'trials': 0}, 'keyword trials'), ({'rpm': 70000}, 'keyword rpm'),
    ({'seed_space': 'holdout'}, 'keyword seed_space'), ({'case': 'upside_down'}, 'keyword case'),
    ({'rmp': 12000}, 'rmp: not a keyword'), ({'samples': 'yes'}, 'samples:'),
    ({'recognizer_params': ['pre_average_s']}, 'recognizer_params:'),
    ({'scenario': {'feed_rate_mm_s': 9.0}}, 'feed_rate_mm_s'),
])
def test_a_refused_keyword_is_named(tmp_path, keywords, named):
    with pytest.raises(api.ApiError, match=named):
        api.run_campaign(out=str(tmp_path / 'out'), **keywords)
    assert not os.path.exists(tmp_path / 'out' / 'trials.csv')


def test_a_split_and_its_offline_scores(small_dataset, tmp_path):
    train = api.load_split(small_dataset, 'train')
    with np.load(small_dataset / 'train.npz') as z:
        assert len(train.samples) == len(z['t'])
        assert list(train.trials['trial_id']) == list(z['trial_trial_id'])
        assert np.array_equal(train.trial(1)['raw_force_n'].to_numpy(),
                              z['raw_force_n'][z['trial'] == 1])
    assert list(train.samples.columns) == dataset.SAMPLE_COLUMNS + ['trial']
    with pytest.raises(api.ApiError, match='split'):
        api.load_split(small_dataset, 'holdout')
    with pytest.raises(api.ApiError, match='dataset'):
        api.load_split(tmp_path, 'train')
    validation = api.load_split(small_dataset, 'validation')
    scores = api.score_offline('pedicle_drilling/PaperRecognizer', small_dataset, 'validation')
    assert sum(scores.values()) == len(validation.trials)
    folder = tmp_path / 'mine'
    write_entry(folder)
    name = api.add_module(folder / 'mean_rise.py')
    mine = api.score_offline('python:%s.MeanRise' % name, small_dataset, 'train',
                             params={'rise_n': 0.6})
    assert sum(mine.values()) == len(train.trials)
    tuned = api.tune_offline('python:%s.MeanRise' % name, small_dataset,
                             {'rise_n': [0.6, 1.2]})
    assert tuned['grid_size'] == 2 and tuned['params']['rise_n'] in ('0.6', '1.2')
    with pytest.raises(api.ApiError, match='recognizer'):
        api.score_offline('python:%s.NoSuchClass' % name, small_dataset, 'validation')


def check_result(out, small_dataset, trials):
    """result.json and the board of a submission of mean_rise on the paper bench."""
    with open(os.path.join(out, 'result.json')) as handle:
        result = json.load(handle)
    with open(small_dataset / 'split.json') as handle:
        meta = json.load(handle)['meta']
    assert result['dataset']['version'] == meta['dataset_version']
    assert result['stamp']['dataset_version'] == meta['dataset_version']
    assert result['stamp']['dataset_build_id'] == meta['build_id']
    assert result['stamp']['board_build_id'] and result['dataset']['base_seed'] == meta[
        'base_seed']
    test_seeds = {int(s) for s in np.load(small_dataset / 'test.npz')['trial_seed']}
    seeds = result['seeds']['paper']
    assert len(seeds) == 3 * trials and {s['seed'] for s in seeds} <= test_seeds
    rows = [r for r in result['board_rows'] if r['entry'] == 'mean_rise']
    assert {r['case'] for r in rows} == {'stationary', 'uncompensated', 'compensated'}
    assert all(r['n'] == trials and r['vs_reference'] is not None for r in rows)
    with open(os.path.join(out, 'mean_rise_fit.json')) as handle:
        fitted = json.load(handle)
    assert result['entry']['params']['contact_n'] == str(fitted['contact_n'])
    assert result['entry']['params']['rise_n'] in ('0.6', '1.2')
    with open(os.path.join(out, 'leaderboard.md')) as handle:
        assert '| mean_rise | stationary | 12000 |' in handle.read()
    leftovers = [name for _, _, names in os.walk(out) for name in names if '.tmp' in name]
    assert not leftovers
    return result


def test_an_entry_from_outside_the_package_reaches_the_board(small_dataset, tmp_path):
    entry = write_entry(tmp_path / 'submitter')
    out = tmp_path / 'submission'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign_submit', '--entry', entry, '--dataset',
         str(small_dataset), '--out', str(out), '--bench', 'paper'],
        capture_output=True, text=True, timeout=600, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    check_result(str(out), small_dataset, 1)
    # The same through the API, its training given as a function of the notebook.
    folder = tmp_path / 'api_submitter'
    write_entry(folder)
    name = api.add_module(folder / 'mean_rise.py')
    module = importlib.import_module(name)
    submission = api.submit({'name': 'mean_rise', 'module': str(folder / 'mean_rise.py'),
                             'class': 'MeanRise', 'tune': {'rise_n': [0.6, 1.2]}},
                            small_dataset, str(tmp_path / 'api_submission'), fit=module.fit,
                            bench='paper')
    check_result(submission.out, small_dataset, 1)
    assert set(submission.rows['entry']) == {'paper', 'mean_rise'}


@pytest.mark.parametrize('changes, named', [
    ({'colour': 'red'}, 'unknown key colour'), ({'class': 'Nope'}, 'class: .* has no class Nope'),
    ({'module': 'missing.py'}, 'module: .*missing.py'), ({'name': 'a b'}, 'name:'),
    ({'fit': 'train_me'}, 'fit:'), ({'tune': {'rise_n': 0.6}}, 'tune: rise_n'),
    ({'files': ['model']}, 'files: model is not one of the params'),
])
def test_a_bad_entry_is_refused_by_name(tmp_path, changes, named):
    entry = write_entry(tmp_path / 'submitter', **changes)
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign_submit', '--entry', entry, '--dataset',
         str(tmp_path / 'no_dataset'), '--out', str(tmp_path / 'out')],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert re.search(named, result.stderr), result.stderr
    assert not os.path.exists(tmp_path / 'out')


def test_the_example_notebook_runs_and_draws_its_figure(tmp_path):
    shutil.copy(NOTEBOOK, tmp_path)
    result = subprocess.run(
        ['jupyter', 'nbconvert', '--to', 'notebook', '--execute', 'campaign_api.ipynb',
         '--output', 'executed.ipynb'],
        capture_output=True, text=True, timeout=300, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    with open(tmp_path / 'executed.ipynb') as handle:
        cells = json.load(handle)['cells']
    outputs = [o for c in cells if c['cell_type'] == 'code' for o in c['outputs']]
    assert not [o for o in outputs if o['output_type'] == 'error']
    assert any('image/png' in o.get('data', {}) for o in outputs)
    with open(tmp_path / 'campaign_api.png', 'rb') as handle:
        assert handle.read(8) == b'\x89PNG\r\n\x1a\n'
    with open(tmp_path / 'campaign_api_out' / 'trials.csv') as handle:
        assert len(list(csv.DictReader(handle))) == 4
