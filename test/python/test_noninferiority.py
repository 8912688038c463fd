"""Claims tested as they are stated: the paired non-inferiority test (inverting Newcombe's
interval), Holm's correction, and the table script that states "compensated is as good as
stationary" with its margin."""
import csv
import os
import subprocess
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from pd_campaign import compare, stats  # noqa: E402

Z95 = 1.959963984540054


@pytest.mark.parametrize('table', [(190, 6, 4, 0), (150, 12, 3, 35), (95, 0, 5, 0),
                                   (18, 1, 1, 0)])
def test_the_p_value_is_where_the_interval_meets_the_margin(table):
    margin = 0.05
    p = compare.noninferiority_p(*table, margin)
    low = compare.paired_difference_interval(*table, Z95)[0]
    # Shown at one-sided 0.025 exactly when the 95 % interval's lower bound is above -margin.
    assert (p < 0.025) == (low > -margin), (p, low)
    if 1e-12 < p < 0.5:
        # At the one-sided level p the lower bound is the margin itself.
        edge = compare.paired_difference_interval(*table, stats.normal_quantile(1.0 - p))[0]
        assert abs(edge + margin) < 1e-6, edge


def test_an_absent_difference_is_not_non_inferiority_at_a_small_sample():
    # 20 pairs, every one a success in both: no difference, but 20 trials cannot show that the
    # loss is under 5 points. 200 such pairs can.
    assert compare.noninferiority_p(20, 0, 0, 0, 0.05) > 0.1
    assert compare.noninferiority_p(200, 0, 0, 0, 0.05) < 0.001
    # A loss at the margin or worse is never shown.
    assert compare.noninferiority_p(180, 0, 10, 10, 0.05) >= 0.5


def test_holm_adjusts_step_down_and_keeps_the_order():
    assert stats.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert stats.holm([0.5]) == [0.5]
    assert stats.holm([0.001, 0.9]) == pytest.approx([0.002, 0.9])


def write_campaign(folder, outcomes):
    """A trials.csv with the given (case, rpm, seed, success) rows."""
    os.makedirs(folder)
    with open(os.path.join(folder, 'trials.csv'), 'w', newline='') as handle:
        writer = csv.writer(handle)
        writer.writerow(['trial_id', 'case', 'rpm', 'index', 'seed', 'success', 'breakthrough',
                         'error'])
        for i, (case, rpm, seed, success) in enumerate(outcomes):
            writer.writerow(['%s-%d' % (case, i), case, rpm, i, seed,
                             'true' if success else 'false', 'false', ''])


def test_the_table_states_each_bench_and_speed_with_holm(tmp_path):
    good = [(case, 12000, seed, True) for seed in range(200)
            for case in ('stationary', 'compensated')]
    small = [(case, 12000, seed, True) for seed in range(20) for case in ('stationary',
                                                                         'compensated')]
    worse = [('stationary', 12000, seed, True) for seed in range(200)] + [
        ('compensated', 12000, seed, seed >= 30) for seed in range(200)]
    write_campaign(str(tmp_path / 'campaign'), good)
    write_campaign(str(tmp_path / 'campaign_realistic'), small)
    write_campaign(str(tmp_path / 'campaign_population'), worse)
    out = subprocess.run([sys.executable, os.path.join(ROOT, 'scripts', 'dev',
                                                       'equivalence_tables.py'), str(tmp_path)],
                         capture_output=True, text=True, check=True).stdout
    lines = [line for line in out.splitlines() if line.startswith('| ')]
    assert lines[1].startswith("| paper's bench | 12000 | 200 | 200 / 200 |")
    assert lines[1].endswith('| yes |')
    assert lines[2].startswith('| realistic bench | 12000 | 20 |')
    assert lines[2].endswith('| **no** |')  # too few pairs to show it
    assert lines[3].endswith('| **no** |')  # 15 points worse
    assert ('shown on 1 of 3 bench and speed cells; not shown: realistic bench at 12000 rpm, '
            'population bench at 12000 rpm.') in out
