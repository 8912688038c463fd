"""campaign_compare: paired comparison of two campaigns on the same design."""
import json
import os
import random
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from pd_campaign import compare, stats  # noqa: E402

TOOL = os.path.join(ROOT, 'scripts', 'campaign_compare')


def test_the_paired_interval_is_antisymmetric_and_centred_without_discordant_pairs():
    low, high = compare.paired_difference_interval(150, 12, 3, 35)
    low_swapped, high_swapped = compare.paired_difference_interval(150, 3, 12, 35)
    assert low_swapped == pytest.approx(-high, abs=1e-12)
    assert high_swapped == pytest.approx(-low, abs=1e-12)
    assert low < 9 / 200 < high
    low0, high0 = compare.paired_difference_interval(189, 0, 0, 11)
    assert low0 == pytest.approx(-high0, abs=1e-12) and high0 > 0.0
    assert compare.paired_difference_interval(0, 0, 0, 0) == (-1.0, 1.0)


def test_the_paired_interval_covers_the_true_difference_about_95_percent_of_the_time():
    # Paired outcomes with correlated success (p_A 0.90, p_B 0.85, both 0.80): Newcombe's
    # method 10 is close to nominal (Newcombe 1998, Table III). A fixed seed: the same draws
    # every run.
    rng = random.Random(20261124)
    cells = [(0.80, 'both'), (0.10, 'only_a'), (0.05, 'only_b'), (0.05, 'neither')]
    true_difference = 0.90 - 0.85
    covered = 0
    runs = 2000
    for _ in range(runs):
        counts = {'both': 0, 'only_a': 0, 'only_b': 0, 'neither': 0}
        for _ in range(100):
            u = rng.random()
            for p, name in cells:
                if u < p:
                    counts[name] += 1
                    break
                u -= p
        low, high = compare.paired_difference_interval(
            counts['both'], counts['only_a'], counts['only_b'], counts['neither'])
        covered += low <= true_difference <= high
    assert 0.93 <= covered / runs <= 0.975


def _campaign(directory, meta, rows):
    """A campaign output folder as the campaign writes it (design.json meta, trials.csv)."""
    os.makedirs(directory)
    with open(os.path.join(directory, 'design.json'), 'w') as handle:
        json.dump({'meta': meta, 'trials': []}, handle)
    with open(os.path.join(directory, 'trials.csv'), 'w') as handle:
        handle.write('trial_id,case,rpm,index,seed,fault,engine,success,residual_mm,'
                     'breakthrough\n')
        for case, index, seed, success, residual in rows:
            handle.write('%s-12000-%03d,%s,12000,%d,%d,none,core,%s,%.2f,false\n'
                         % (case, index, case, index, seed, 'true' if success else 'false',
                            residual))


META = {'cases': ['stationary', 'compensated'], 'rpms': [12000.0], 'trials': 4, 'seed': 7,
        'bone_motion': 'model', 'model': 'linear', 'simulator': {}, 'engine': 'core',
        'compensation_profile': 'exact'}


def _pair(tmp_path, meta_b=None, rows_b=None):
    rows_a = [('stationary', i, 100 + i, True, 1.5) for i in range(4)] + \
             [('compensated', i, 100 + i, i != 3, 1.4) for i in range(4)]
    rows_b = rows_b or ([('stationary', i, 100 + i, i != 0, 1.6) for i in range(4)] +
                        [('compensated', i, 100 + i, i in (0, 3), 1.3) for i in range(4)])
    a, b = str(tmp_path / 'exact'), str(tmp_path / 'paper')
    _campaign(a, META, rows_a)
    _campaign(b, dict(META, compensation_profile='paper', **(meta_b or {})), rows_b)
    return a, b


def _run(*args, cwd):
    return subprocess.run(['/usr/bin/python3', TOOL] + list(args), capture_output=True,
                          text=True, cwd=cwd, timeout=120)


def test_pairs_by_specimen_and_writes_markdown_json_and_a_figure(tmp_path):
    a, b = _pair(tmp_path)
    result = _run(a, b, '--out', str(tmp_path / 'out'), cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    with open(tmp_path / 'out' / 'compare.json') as handle:
        report = json.load(handle)
    assert report['compared'] == {'compensation_profile': ['exact', 'paper']}
    stationary, compensated = report['groups']
    assert (stationary['case'], compensated['case']) == ('stationary', 'compensated')
    # Stationary: A all 4, B all but index 0 -> both 3, only A 1.
    assert (stationary['both'], stationary['only_a'], stationary['only_b'],
            stationary['neither']) == (3, 1, 0, 0)
    # Compensated: A indices 0-2, B indices 0 and 3 -> both 1, only A 2, only B 1, neither 0.
    assert (compensated['both'], compensated['only_a'], compensated['only_b'],
            compensated['neither']) == (1, 2, 1, 0)
    assert compensated['mcnemar_p'] == pytest.approx(stats.mcnemar_exact(2, 1))
    assert compensated['difference'] == pytest.approx(0.25)
    assert compensated['median_residual_mm_a'] == pytest.approx(1.4)
    text = (tmp_path / 'out' / 'compare.md').read_text()
    assert '| compensated | 12000 | 4 | 3/4 (75 %) | 2/4 (50 %) | 1 | 2 | 1 | 0 |' in text
    assert os.path.getsize(tmp_path / 'out' / 'compare.png') > 5000
    assert not [f for f in os.listdir(tmp_path / 'out') if '.tmp' in f]
    assert 'only exact' in result.stdout  # the table is printed too


def test_the_default_output_folder_names_both_campaigns(tmp_path):
    a, b = _pair(tmp_path)
    result = _run(a, b, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / 'compare_exact_vs_paper' / 'compare.md').is_file()


@pytest.mark.parametrize('meta_b, rows_b, named', [
    ({'seed': 8}, None, "'seed'"),
    ({'bone_motion': 'virtual_patient'}, None, "'bone_motion'"),
    ({'simulator': {'specimen': {'outer_cortical_mean_mm': 2.0}}}, None, "'simulator'"),
    (None, [('stationary', i, 200 + i, True, 1.5) for i in range(4)], 'differ in their trials'),
])
def test_different_designs_are_refused_naming_the_difference(tmp_path, meta_b, rows_b, named):
    a, b = _pair(tmp_path, meta_b, rows_b)
    result = _run(a, b, '--out', str(tmp_path / 'out'), cwd=str(tmp_path))
    assert result.returncode == 2
    assert named in result.stderr, result.stderr
    assert result.stderr.count('\n') == 1  # one line, no traceback
    assert not (tmp_path / 'out').exists()  # nothing written


def test_two_benches_compare_with_benches_only(tmp_path):
    # The same specimens on another bench: refused as a design difference, accepted with
    # --benches, which names what differs; a different seed is still refused.
    a, b = _pair(tmp_path, {'bone_motion': 'virtual_patient',
                            'engine_delays': {'command_to_arm_s': 0.035}})
    result = _run(a, b, '--benches', '--out', str(tmp_path / 'out'), cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    with open(tmp_path / 'out' / 'compare.json') as handle:
        compared = json.load(handle)['compared']
    assert compared['bone_motion'] == ['model', 'virtual_patient']
    assert compared['engine_delays'] == [None, {'command_to_arm_s': 0.035}]
    a, b = _pair(tmp_path / 'other', {'bone_motion': 'virtual_patient', 'seed': 8})
    result = _run(a, b, '--benches', '--out', str(tmp_path / 'out2'), cwd=str(tmp_path))
    assert result.returncode == 2 and "'seed'" in result.stderr


def test_a_folder_that_is_not_a_campaign_is_refused(tmp_path):
    a, _ = _pair(tmp_path)
    result = _run(a, str(tmp_path / 'nowhere'), cwd=str(tmp_path))
    assert result.returncode == 2
    assert 'nowhere' in result.stderr and 'design.json' in result.stderr
    result = _run(a, a, '--out', 'x', '--out', 'y', cwd=str(tmp_path))
    assert result.returncode == 2 and 'more than once' in result.stderr


def test_two_real_campaigns_that_differ_in_the_profile_compare(tmp_path):
    """End to end on the core engine: the same 3 specimens compensated with the paper's and the
    exact profile (a few seconds)."""
    outs = []
    for profile in ('paper', 'exact'):
        scenario = tmp_path / ('%s.yaml' % profile)
        scenario.write_text('cases: [compensated]\nrpms: [12000]\ntrials: 3\nseed: 5\n'
                            'feed_rate_mm_s: 0.5\nmax_duration_s: 60.0\n'
                            'identification_window_s: 30.0\nidentification: volunteers\n'
                            'model: linear\nbone_motion: model\ncompensation_profile: %s\n'
                            'simulator: {}\n' % profile)
        out = tmp_path / profile
        result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign', '--scenario',
                                 str(scenario), '--jobs', '2', '--out', str(out)],
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, result.stderr[-2000:]
        outs.append(str(out))
    result = _run(outs[1], outs[0], '--out', str(tmp_path / 'cmp'), cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    with open(tmp_path / 'cmp' / 'compare.json') as handle:
        report = json.load(handle)
    assert report['compared'] == {'compensation_profile': ['exact', 'paper']}
    assert report['groups'][0]['pairs'] == 3
