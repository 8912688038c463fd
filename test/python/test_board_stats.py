"""The leaderboard's statistics (pd_campaign.board_stats): bootstrapped rank intervals over
specimens, the strata, the hidden-condition board; and the dataset's hidden conditions
(pd_campaign.dataset, dataset_build): a calibration trial under one is in no split, an
evaluation one stays in the test split."""
import csv
import json
import os

import numpy as np
import pytest

from pd_campaign import board_stats, dataset, dataset_build

CASES = ('stationary', 'uncompensated', 'compensated')
REFERENCES = [[12000.0, 3.16], [16000.0, 2.99], [20000.0, 2.88]]


def rows(successes, volunteer=1, density_n=3.16, thickness=2.1, rpm=12000.0, seeds=None):
    """Trial rows of one entry: successes[specimen][case] (1/0) on specimens seeded 100, 101..."""
    out = []
    for k, by_case in enumerate(successes):
        for case, success in zip(CASES, by_case):
            out.append({'case': case, 'rpm': rpm, 'seed': (seeds or {}).get(k, 100 + k),
                        'success': bool(success), 'error': '', 'volunteer_id': volunteer,
                        'f_out_truth_n': density_n if case != 'uncompensated' else 5.0,
                        'inner_cortical_mm': thickness})
    return out


# --- ranks ----------------------------------------------------------------------------------

def test_a_clear_winner_has_the_rank_interval_one_to_one():
    rng = np.random.default_rng(0)
    winner = np.ones(30)
    others = (rng.random((3, 30)) < 0.4).astype(float)
    ranks = board_stats.bootstrap_ranks(np.vstack([others, winner]))
    assert ranks[3] == (1, 1, 1)
    assert all(low >= 2 for _, low, _ in ranks[:3])


def test_two_equal_entries_overlap_and_the_resamples_are_seeded():
    rng = np.random.default_rng(1)
    a = (rng.random(40) < 0.7).astype(float)
    b = np.roll(a, 1)  # the same successes on other specimens: equal in total
    worse = (rng.random(40) < 0.2).astype(float)
    ranks = board_stats.bootstrap_ranks(np.vstack([a, b, worse]))
    (ra, la, ha), (rb, lb, hb) = ranks[0], ranks[1]
    assert ra == rb == 1  # tied on all specimens: the better rank, shared
    assert la == lb == 1 and ha == hb == 2  # each is first or second: the intervals overlap
    assert ranks[2][1] == 3
    assert board_stats.bootstrap_ranks(np.vstack([a, b, worse])) == ranks
    assert board_stats.ranks_of([3, 5, 5, 1]).tolist() == [3, 1, 1, 4]


def test_the_rank_table_pairs_the_specimens_across_entries_and_cases():
    by_entry = {'good': rows([(1, 1, 1)] * 10), 'bad': rows([(1, 0, 1)] * 10),
                'same': rows([(1, 1, 1)] * 10)}
    table = board_stats.rank_table(by_entry, CASES, resamples=200)
    assert table['good']['all'] == {'rank': 1, 'interval': [1, 1], 'correct': 30,
                                    'trials': 30, 'specimens': 10}
    assert table['bad']['all']['interval'] == [3, 3]
    assert table['bad']['stationary']['rank'] == 1  # every entry succeeds there
    assert table['bad']['uncompensated']['rank'] == 3
    assert 'good | 30/30 | 1 (1-1) |' in '\n'.join(board_stats.ranks_markdown(table, CASES))


# --- strata ---------------------------------------------------------------------------------

def test_the_strata_cut_density_thickness_and_speed_at_the_training_edges():
    by_entry = {'a': rows([(1, 1, 1)], density_n=3.0, thickness=1.8, seeds={0: 1})
                + rows([(1, 0, 1)], density_n=3.3, thickness=2.5, seeds={0: 2})
                + rows([(0, 0, 0)], rpm=16000.0, density_n=2.99, seeds={0: 3})}
    edges = {'bone density': [0.97, 1.02], 'inner cortex thickness': [2.0, 2.2],
             'references': REFERENCES}
    table = board_stats.strata_table(by_entry, edges)
    cell = {(r['stratum'], r['band']): (r['correct'], r['n']) for r in table}
    assert cell[('bone density', '1 low (< 0.970 x the reference)')] == (3, 3)  # 3.0 / 3.16
    assert cell[('bone density', '2 middle (0.970-1.020 x the reference)')] == (0, 3)  # 16000
    assert cell[('bone density', '3 high (>= 1.020 x the reference)')] == (2, 3)  # 3.3 / 3.16
    assert cell[('inner cortex thickness', '1 low (< 2.00 mm)')] == (3, 3)
    assert cell[('inner cortex thickness', '3 high (>= 2.20 mm)')] == (2, 3)
    assert cell[('speed', '12000 rpm')] == (5, 6) and cell[('speed', '16000 rpm')] == (0, 3)
    assert '| bone density | 1 low' in '\n'.join(board_stats.strata_markdown(table))


def test_the_density_of_a_specimen_ignores_the_breathing_thrust():
    found = dataset.specimen_densities(rows([(1, 1, 1)], density_n=3.16 * 1.1), REFERENCES)
    assert found == {(12000.0, 100): pytest.approx(1.1)}
    found = dataset.specimen_densities(rows([(1, 1, 1)], rpm=14000.0, density_n=3.075),
                                       REFERENCES)
    assert found == {(14000.0, 100): pytest.approx(1.0)}  # halfway between 12000 and 16000
    # Without references: the median of the rows' own specimens per speed.
    own = rows([(1, 1, 1)], density_n=3.0, seeds={0: 1}) + rows(
        [(1, 1, 1)], density_n=3.3, seeds={0: 2}) + rows([(1, 1, 1)], density_n=3.2, seeds={0: 3})
    assert dataset.density_references(dataset.specimen_peaks(own)) == [[12000.0, 3.2]]
    assert dataset.specimen_densities(own)[(12000.0, 1)] == pytest.approx(3.0 / 3.2)
    assert board_stats.tertile_edges([1.0, 2.0]) is None


# --- hidden conditions ----------------------------------------------------------------------

def test_the_hidden_board_separates_hidden_breathing_and_density():
    seen = rows([(1, 1, 1)], seeds={0: 1})
    breathing = rows([(0, 0, 0)], volunteer=4, seeds={0: 2})
    dense = rows([(1, 0, 0)], density_n=3.5, seeds={0: 3})
    board, reasons = board_stats.hidden_board({'a': seen + breathing + dense},
                                              dataset.hidden_rule(REFERENCES))
    assert reasons == {(12000.0, 2): 'breathing of volunteer 4',
                       (12000.0, 3): 'density 1.108 x the reference'}
    uncompensated = [r for r in board if r['case'] == 'uncompensated'][0]
    assert (uncompensated['hidden']['correct'], uncompensated['hidden']['n']) == (0, 2)
    assert (uncompensated['seen']['correct'], uncompensated['seen']['n']) == (1, 1)
    assert board_stats.hidden_board({'a': seen}, None) == (None, {})
    assert 'no hidden-condition board' in board_stats.hidden_markdown(None, {})[0]


def _campaign(folder, space, specimens):
    """A campaign's trials.csv and samples files: specimens [(index, volunteer, f_out)]."""
    os.makedirs(os.path.join(folder, 'samples'))
    fields = ['trial_id', 'case', 'rpm', 'index', 'seed', 'seed_space', 'volunteer_id',
              'f_out_truth_n', 'error']
    with open(os.path.join(folder, 'trials.csv'), 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fields)
        writer.writeheader()
        for index, volunteer, f_out in specimens:
            for case in CASES:
                trial_id = '%s-12000-%03d' % (case, index)
                writer.writerow({'trial_id': trial_id, 'case': case, 'rpm': '12000',
                                 'index': index, 'seed': 1000 + index, 'seed_space': space,
                                 'volunteer_id': volunteer, 'f_out_truth_n': f_out, 'error': ''})
                open(os.path.join(folder, 'samples', trial_id + '.npy'), 'w').close()


def test_hidden_conditions_are_kept_out_of_the_training_and_validation_splits(tmp_path):
    calibration, evaluation = str(tmp_path / 'calibration'), str(tmp_path / 'evaluation')
    # Calibration (the reference, their median: 3.16 N): index 0 seen, 1 breathes as volunteer
    # 4, 2 too dense, 3 (validation) seen, 7 (validation) too light.
    _campaign(calibration, 'calibration', [(0, 1, 3.16), (1, 4, 3.16), (2, 2, 3.5),
                                           (3, 3, 3.1), (7, 5, 2.8)])
    _campaign(evaluation, 'evaluation', [(0, 4, 3.16), (1, 1, 3.2), (2, 1, 3.45)])
    tables, hidden = dataset_build._trial_rows([calibration, evaluation])
    ids = {split: {(row['index'], row['case']) for row, _ in items}
           for split, items in tables.items()}
    assert {index for index, _ in ids['train']} == {'0'}
    assert {index for index, _ in ids['validation']} == {'3'}
    assert {index for index, _ in ids['test']} == {'0', '1', '2'}  # the test split keeps them
    assert sorted({(i[-3:], r) for i, _, r in hidden['hidden']}) == [
        ('001', 'breathing of volunteer 4'), ('002', 'density 1.108 x the reference'),
        ('007', 'density 0.886 x the reference')]
    assert {(i[-3:], r) for i, _, r in hidden['test_hidden']} == {
        ('000', 'breathing of volunteer 4'), ('002', 'density 1.092 x the reference')}
    assert hidden['references'] == [[12000.0, 3.16]]  # from the calibration specimens only
    # The rule recorded in split.json is the one the leaderboard applies.
    rule = json.loads(json.dumps(dataset.hidden_rule(hidden['references'])))
    assert rule['volunteers'] == [4] and rule['density_reference_n'] == [[12000.0, 3.16]]
