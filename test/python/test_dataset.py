"""The labelled force dataset: written by campaign_dataset, read back with numpy; the
split by seed space; the labels against the ground truth; recording samples changes no trial."""
import csv
import json
import os
import subprocess

import numpy as np
import pytest

from pd_campaign import dataset
from pd_campaign.design import SEED_SPACE_BIT

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def _rows(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def test_the_splits_are_fixed_by_the_seed_space_and_the_index(small_dataset):
    splits = {name: np.load(small_dataset / (name + '.npz')) for name in dataset.SPLITS}
    assert [len(splits[s]['trial_trial_id']) for s in dataset.SPLITS] == [9, 3, 3]
    for name, z in splits.items():
        seeds = [int(s) for s in z['trial_seed']]
        evaluation = [bool(s & SEED_SPACE_BIT) for s in seeds]
        assert all(evaluation) if name == 'test' else not any(evaluation), name
        assert set(z['trial_seed_space']) == {'evaluation' if name == 'test' else 'calibration'}
        for index in z['trial_index']:
            assert dataset.split_of(
                'evaluation' if name == 'test' else 'calibration', int(index)) == name
        assert sorted(set(z['trial_case'])) == ['compensated', 'stationary', 'uncompensated']
    seeds = [{int(x) for x in splits[s]['trial_seed']} for s in dataset.SPLITS]
    assert not (seeds[0] & seeds[1]) and not (seeds[0] & seeds[2]) and not (seeds[1] & seeds[2])
    with open(small_dataset / 'split.json') as handle:
        listed = json.load(handle)
    for name, z in splits.items():
        assert [t['trial_id'] for t in listed[name]] == list(z['trial_trial_id'])


def test_the_columns_read_back_with_numpy_and_the_labels_are_the_ground_truth(small_dataset):
    z = np.load(small_dataset / 'train.npz')
    for name in dataset.SAMPLE_COLUMNS + ['trial']:
        assert name in z.files, name
    n = len(z['trial'])
    assert all(len(z[name]) == n for name in dataset.SAMPLE_COLUMNS)
    assert n > 9 * 3000  # about 30 s per trial at 1000/3 Hz
    layer, depth, trial = z['layer'], z['max_depth_cut_m'], z['trial']
    assert set(np.unique(layer)) <= set(range(len(dataset.LAYERS)))
    for k in range(len(z['trial_trial_id'])):
        rows = trial == k
        assert rows.any()
        t = z['t'][rows]
        assert np.all(np.diff(t) > 0), 'samples of a trial in time order'
        # The peak-force protocol drills through: every layer in every trial, in order.
        seen = layer[rows]
        assert list(np.unique(seen)) == [0, 1, 2, 3, 4], z['trial_trial_id'][k]
        assert np.all(np.diff(seen) >= 0), 'the deepest cut only goes deeper'
        inner_start = z['trial_inner_start_mm'][k] / 1000.0
        inner = rows & (layer == 3)
        assert np.all(depth[inner] >= inner_start - 1e-9)
        assert np.all(depth[rows & (layer <= 2)] <= inner_start + 1e-9)
        # The input of a recognizer is the sensor's view of the true thrust: close on average
        # in the cortices (tare, noise and the anti-alias filter's lag apart).
        cortical = rows & (layer == 1) & (z['contact'] == 1)
        assert abs(np.mean(z['raw_force_n'][cortical] - z['true_force_n'][cortical])) < 0.3
    assert np.all((z['breath_phase'] >= 0) & (z['breath_phase'] <= 1))
    moving = np.isin(trial, np.flatnonzero(z['trial_case'] != 'stationary'))
    assert np.ptp(z['bone_ap_m'][moving]) > 1e-3, 'the vertebra breathes in the moving cases'
    assert np.isfinite(z['tracker_x_m'][-1])


def test_the_datasheet_lists_every_field_and_the_counts(small_dataset):
    text = (small_dataset / 'DATASHEET.md').read_text()
    for name in dataset.SAMPLE_COLUMNS:
        assert '`%s`' % name in text, name
    for name, _, _, _ in dataset.TRIAL_FIELDS:
        assert '`trial_%s`' % name in text, name
    z = np.load(small_dataset / 'test.npz')
    assert '| test | 3 | %d |' % len(z['trial']) in text
    assert 'protocol: peak_forces' in text


def test_recording_the_samples_changes_no_trial(small_dataset, tmp_path):
    run = small_dataset / 'runs' / 'evaluation'
    out = tmp_path / 'plain'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario',
         os.path.join(ROOT, 'config', 'scenario_dataset.yaml'), '--seed-space', 'evaluation',
         '--trials', '1', '--rpm', '12000', '--jobs', '2', '--out', str(out)],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with_samples, plain = _rows(run / 'trials.csv'), _rows(out / 'trials.csv')
    for row in with_samples + plain:
        row.pop('wall_s')
    assert with_samples == plain
    assert not (out / 'samples').exists()


def test_bad_arguments_are_refused(tmp_path):
    result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign_dataset', '--out',
                             str(tmp_path / 'x'), '--trials', '2'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and '--trials' in result.stderr
    result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign', '--samples', '--engine',
                             'ros', '--out', str(tmp_path / 'y')],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode != 0 and '--samples' in result.stderr
