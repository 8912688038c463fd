"""The recognizer leaderboard: tuning on the training split only, the choice on the
validation split, closed-loop campaigns on the test split's specimens, paired tests with the
paper's recognizer; its rules on synthetic scores."""
import csv
import json
import os
import subprocess

import numpy as np
import pytest
import yaml

from pd_campaign import leaderboard

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def _counts(correct, early=0, late=0, none=0):
    return {'correct': correct, 'shallow': 0, 'early': early, 'late': late, 'none': none}


def test_the_choice_is_the_best_on_validation_among_the_best_on_train():
    points = [{'x': str(k)} for k in range(6)]
    train = [_counts(5), _counts(9), _counts(8), _counts(9, late=1), _counts(2), _counts(7)]
    validation = [None, _counts(3), _counts(6), _counts(4), None, None]
    best, top = leaderboard.select(points, train, validation)
    assert top == [1, 3, 2]  # 9 correct (fewer late first), then 8
    assert best == 2  # the best of those on validation, though not the best on train
    # Ties on validation: the better on train, then the earlier in the grid.
    validation = [None, _counts(6), _counts(6), _counts(6), None, None]
    assert leaderboard.select(points, train, validation)[0] == 1


def test_a_stop_is_judged_by_the_label_of_its_sample():
    labels = np.array([0, 0, 1, 1, 2, 2, 3, 3, 4])
    assert [leaderboard.outcome_of(i, labels) for i in (None, 1, 4, 6, 7, 8)] == [
        'none', 'early', 'early', 'correct', 'correct', 'late']
    with pytest.raises(leaderboard.LeaderboardError):
        leaderboard.outcome_of(9, labels)
    # In the inner cortex with more than 2 mm of it left: shallow, a failure of the task.
    residual = np.array([9, 9, 8, 7, 6, 5, 2.5, 2.0, -0.1])
    assert [leaderboard.outcome_of(i, labels, residual) for i in (6, 7, 8)] == [
        'shallow', 'correct', 'late']


def test_a_bad_configuration_is_refused_by_name(tmp_path):
    path = tmp_path / 'lb.yaml'
    path.write_text('benches: {paper: scenario_paper.yaml}\nreference: paper\nentries:\n'
                    '  - {name: paper, recognizer: pedicle_drilling/PaperRecognizer}\n'
                    '  - {name: paper, recognizer: pedicle_drilling/PaperRecognizer}\n')
    with pytest.raises(leaderboard.LeaderboardError, match="'paper' named twice"):
        leaderboard.load_config(str(path))
    path.write_text('benches: {paper: scenario_paper.yaml}\nreference: nobody\nentries:\n'
                    '  - {name: paper, recognizer: pedicle_drilling/PaperRecognizer}\n')
    with pytest.raises(leaderboard.LeaderboardError, match='reference'):
        leaderboard.load_config(str(path))
    config = leaderboard.load_config(os.path.join(ROOT, 'config', 'leaderboard.yaml'))
    assert len(config['entries']) >= 5


def run_board(dataset, config, tmp_path):
    """campaign_leaderboard on `dataset` with the board configuration `config`; its output
    folder (the command must succeed)."""
    config_path = tmp_path / 'leaderboard.yaml'
    config_path.write_text(yaml.safe_dump(config))
    out = tmp_path / 'board'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign_leaderboard', '--dataset', str(dataset),
         '--out', str(out), '--config', str(config_path), '--jobs', '2'],
        capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    return out


def test_the_board_tunes_on_train_and_runs_the_test_specimens_in_closed_loop(small_dataset,
                                                                           tmp_path):
    dataset = small_dataset
    config = {
        'benches': {'paper': 'scenario_paper.yaml'}, 'cases': ['stationary', 'compensated'],
        'rpms': [12000], 'reference': 'paper',
        'entries': [
            {'name': 'paper', 'recognizer': 'pedicle_drilling/PaperRecognizer'},
            {'name': 'kalman', 'recognizer': 'pedicle_drilling/ForceDifferenceRecognizer',
             'params': {'stop_at_entry': '2'},
             'tune': {'rearm_rise_n': ['0.04', '0.12'], 'rise_confirm': ['3']}},
            {'name': 'threshold',
             'recognizer': 'python:pd_campaign.recognizers.ThresholdRecognizer',
             'tune': {'cortical_n': ['2.2'], 'cancellous_n': ['1.0', '1.6']}},
        ]}
    out = run_board(dataset, config, tmp_path)
    with open(out / 'tuning.json') as handle:
        tuning = json.load(handle)
    assert tuning['kalman']['params']['stop_at_entry'] == '2'
    assert tuning['kalman']['params']['rearm_rise_n'] in ('0.04', '0.12')
    assert tuning['kalman']['grid_size'] == 2 and tuning['threshold']['grid_size'] == 2
    # Scores are over the training (9 trials) and validation (3 trials) splits.
    for name in ('paper', 'kalman', 'threshold'):
        assert sum(tuning[name]['train'].values()) == 9
        assert sum(tuning[name]['validation'].values()) == 3
    with open(out / 'leaderboard.json') as handle:
        board = json.load(handle)
    rows = board['boards']['paper']
    assert {(r['entry'], r['case']) for r in rows} == {
        (e, c) for e in ('paper', 'kalman', 'threshold') for c in ('stationary', 'compensated')}
    for row in rows:
        assert row['n'] == 1 and row['errors'] == 0
        assert (row['vs_reference'] is None) == (row['entry'] == 'paper')
        # The same trial again with the plan's depth limit: the system's no penetration.
        limited = row['with_depth_limit']
        assert limited['n'] == 1 and limited['no_penetration'] in (0, 1)
        assert 0 <= limited['limit_first'] <= 1
    # The closed loop drilled the test split's specimens: the same seeds as test.npz.
    test_seeds = {int(s) for s in np.load(dataset / 'test.npz')['trial_seed']}
    for name in ('paper', 'kalman', 'threshold'):
        with open(out / 'closed_loop' / 'paper' / name / 'trials.csv') as handle:
            seeds = {int(row['seed']) for row in csv.DictReader(handle)}
        assert seeds <= test_seeds and seeds
    for name in ('paper', 'kalman', 'threshold'):
        with open(out / 'closed_loop_depth_limit' / 'paper' / name / 'trials.csv') as handle:
            limited = list(csv.DictReader(handle))
        assert {int(row['seed']) for row in limited} <= test_seeds and limited
        # The limit was active: it estimated the depth once the drill touched the bone.
        assert any(row['depth_estimate_error_mm'] not in ('', None) for row in limited)
    with open(out / 'closed_loop_depth_limit' / 'paper' / 'scenario_depth_limit.yaml') as handle:
        assert yaml.safe_load(handle)['depth_limit'] is True
    text = (out / 'leaderboard.md').read_text()
    assert '| kalman | compensated | 12000 |' in text and 'McNemar' in text
    assert 'with the depth limit: no penetration (limit first)' in text
    assert (out / 'leaderboard.png').stat().st_size > 10000


def test_the_board_ranks_stratifies_and_shows_the_hidden_conditions_and_new_baselines(
        small_dataset, tmp_path):
    """The two 2026 baselines tuned and run beside the paper's recognizer; the board's rank
    intervals, strata and hidden-condition board, stamped with the dataset's version and build."""
    config = {
        'benches': {'paper': 'scenario_paper.yaml'}, 'cases': list(leaderboard.design.CASES),
        'rpms': [12000], 'reference': 'paper',
        'entries': [
            {'name': 'paper', 'recognizer': 'pedicle_drilling/PaperRecognizer'},
            {'name': 'gaussian_process',
             'recognizer': 'python:pd_campaign.baselines.GaussianProcessRecognizer',
             'tune': {'z': ['2.5', '3.5'], 'confirm': ['1', '2']}},
            {'name': 'force_drop',
             'recognizer': 'python:pd_campaign.baselines.ForceDropRecognizer',
             'tune': {'stop_on': ['drop', 'recovery'], 'recovery_ratio': ['0.7', '0.85']}},
        ]}
    out = run_board(small_dataset, config, tmp_path)
    with open(small_dataset / 'split.json') as handle:
        split = json.load(handle)
    with open(out / 'leaderboard.json') as handle:
        board = json.load(handle)
    names = ('paper', 'gaussian_process', 'force_drop')
    assert board['stamp']['dataset_version'] == split['meta']['dataset_version']
    assert board['stamp']['dataset_build_id'] == split['meta']['build_id']
    assert board['tuning']['gaussian_process']['grid_size'] == 4
    assert board['tuning']['force_drop']['params']['stop_on'] in ('drop', 'recovery')
    ranks = board['ranks']['paper']
    assert set(ranks) == set(names)
    for name in names:
        for key in ('all',) + tuple(leaderboard.design.CASES):
            low, high = ranks[name][key]['interval']
            assert 1 <= low <= ranks[name][key]['rank'] <= high <= 3
        assert ranks[name]['all']['trials'] == 3
    strata = board['strata']['paper']
    assert {r['stratum'] for r in strata} == {'bone density', 'inner cortex thickness', 'speed'}
    assert {r['entry'] for r in strata} == set(names)
    # The hidden-condition board's specimens are the dataset's hidden test specimens.
    hidden = board['hidden']['paper']
    assert {int(s['seed']) for s in hidden['specimens']} == {
        int(t['seed']) for t in split.get('test_hidden', [])}
    assert {(r['entry'], r['case']) for r in hidden['board']} == {
        (e, c) for e in names for c in leaderboard.design.CASES}
    text = (out / 'leaderboard.md').read_text()
    for needle in ('Dataset version `%s`' % split['meta']['dataset_version'],
                   '### Ranks on the paper bench', 'rank (95 % interval)',
                   '### Strata on the paper bench', '| bone density |',
                   '| inner cortex thickness |', '| speed | 12000 rpm |',
                   '### Hidden-condition board on the paper bench',
                   '| gaussian_process | compensated | 12000 |', '| force_drop | stationary |'):
        assert needle in text, needle
