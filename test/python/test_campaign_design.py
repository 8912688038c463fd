"""Campaign design, statistics and report (no ROS graph needed)."""
import csv
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))

from pd_campaign import aggregate, cli, design, report, stats, trials_csv  # noqa: E402


def test_wilson_interval_known_values():
    # 19/20: 0.7639-0.9911 and 0/10: 0-0.2775, worked by hand from Wilson (1927) with z = 1.96.
    low, high = stats.wilson_interval(19, 20)
    assert low == pytest.approx(0.7639, abs=1e-3)
    assert high == pytest.approx(0.9911, abs=1e-3)
    low, high = stats.wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-3)
    assert stats.wilson_interval(0, 0) == (0.0, 1.0)
    # All succeeded: the upper bound is exactly 1 (a rounded 0.9999999 made a negative error bar).
    for n in range(1, 40):
        assert stats.wilson_interval(n, n)[1] == 1.0
        assert stats.wilson_interval(0, n)[0] == 0.0


def test_exact_tests_known_values():
    # Worked by hand. McNemar: 0 vs 5 discordant pairs, two-sided binomial p = 2 / 2^5.
    assert stats.mcnemar_exact(0, 5) == pytest.approx(0.0625)
    assert stats.mcnemar_exact(0, 0) == 1.0
    # Fisher: 3/3 vs 0/3 -> the only table as extreme on each side has p = 1 / C(6, 3) = 0.05.
    assert stats.fisher_exact(3, 3, 0, 3) == pytest.approx(0.1)
    assert stats.fisher_exact(5, 10, 5, 10) == pytest.approx(1.0)
    rows_a = [{'seed': s, 'success': ok} for s, ok in [(1, True), (2, True), (3, False), (4, True)]]
    rows_b = [{'seed': s, 'success': ok} for s, ok in [(1, True), (2, False), (3, False), (5, True)]]
    assert stats.paired_counts(rows_a, rows_b, key=lambda r: r['seed']) == (3, 1, 1, 0, 1)


def test_seeds_are_paired_across_cases_and_stable():
    d = design.build_design(design.CASES, [12000, 16000], 3, 7)
    assert len(d) == 18
    by_key = {}
    for trial in d:
        by_key.setdefault((trial['rpm'], trial['index']), set()).add(trial['seed'])
    assert all(len(seeds) == 1 for seeds in by_key.values())
    assert len({next(iter(s)) for s in by_key.values()}) == 6
    assert design.trial_seed(7, 12000, 0) == design.trial_seed(7, 12000, 0)
    assert design.trial_seed(7, 12000, 0) != design.trial_seed(8, 12000, 0)


def test_trial_counts_per_speed_keep_every_seed():
    # 200/100/100 per speed: the same trials as 200 at every speed, minus the tail, same seeds.
    full = design.build_design(design.CASES, [12000, 16000, 20000], 6, 3)
    part = design.build_design(design.CASES, [12000, 16000, 20000], [6, 3, 2], 3)
    assert len(part) == 3 * (6 + 3 + 2)
    by_id = {t['trial_id']: t for t in full}
    for trial in part:
        assert by_id[trial['trial_id']] == trial
    assert max(t['index'] for t in part if t['rpm'] == 20000) == 1
    with pytest.raises(ValueError):
        design.build_design(design.CASES, [12000, 16000], [1, 2, 3], 3)


def test_shards_partition_the_design():
    d = design.build_design(design.CASES, [12000], 5, 1)
    parts = [design.shard(d, k, 4) for k in range(1, 5)]
    ids = [t['trial_id'] for p in parts for t in p]
    assert sorted(ids) == sorted(t['trial_id'] for t in d)
    assert len(set(ids)) == len(ids)
    with pytest.raises(ValueError):
        design.parse_shard('5/4')
    with pytest.raises(ValueError):
        design.parse_shard('x')


def _rows(d):
    rows = []
    for i, trial in enumerate(d):
        row = dict(trial)
        row.update(success=(i % 3 != 1), residual_mm=0.5 + 0.1 * (i % 7), f_out_n=3.0 + 0.01 * i,
                   f_in_n=2.8, stop_reason='key_point_4', stop_source='state_recognizer',
                   tracking_rms_mm=0.1, error='')
        rows.append(trials_csv.normalise_row({k: str(v) for k, v in row.items()}))
    return rows


TABLE2_CSV = ('volunteer,model,axis,wavelet,q1,q2,q0,r2,rmse,q1_true,q2_true,q1_rel_err\n'
              + ''.join('%d,%s,%s,coif4,0.01,0,0,%.3f,0.1,0.01,0,0\n' % (v, m, a, 0.9 + 0.01 * v)
                        for v in range(1, 6) for m in ('linear', 'hysteresis')
                        for a in ('ap', 'si', 'lr')))
TABLE2_MD = '| volunteer | R2 AP |\n|---|---|\n| 1 | 0.91 |\n'


def _campaign_dir(path, rows, meta, with_table2=True):
    """A campaign output directory as `campaign` leaves it (Table II copied in first)."""
    from pd_campaign import cli
    path.mkdir()
    if with_table2:
        (path / 'table2.csv').write_text(TABLE2_CSV)
        (path / 'table2.md').write_text(TABLE2_MD)
    cli.write_outputs(rows, meta, str(path))
    (path / 'design.json').write_text(json.dumps({'meta': meta}))
    return str(path)


def _shards(tmp_path, d, rows, meta, count):
    dirs = []
    for k in range(1, count + 1):
        part_ids = {t['trial_id'] for t in design.shard(d, k, count)}
        dirs.append(_campaign_dir(tmp_path / ('shard%d' % k),
                                  [r for r in rows if r['trial_id'] in part_ids], meta))
    return dirs


def test_merged_shards_give_the_same_report(tmp_path):
    d = design.build_design(design.CASES, [12000, 16000], 4, 3)
    rows = _rows(d)
    from pd_campaign import cli
    meta = {'cases': list(design.CASES), 'rpms': [12000.0, 16000.0], 'trials': 4, 'seed': 3,
            'design_size': len(d)}
    single = tmp_path / 'single'
    _campaign_dir(single, rows, meta)
    merged = tmp_path / 'merged'
    assert cli.run_merge(_shards(tmp_path, d, rows, meta, 2) + ['--out', str(merged)]) == 0
    for name in ('trials.csv', 'summary.json', 'report.md', 'table2.csv', 'table2.md'):
        assert (merged / name).read_text() == (single / name).read_text(), name
    report_text = (merged / 'report.md').read_text()
    assert 'Table II' in report_text and (merged / 'table2.png').stat().st_size > 1000


def test_merge_with_a_missing_shard_exits_1(tmp_path):
    d = design.build_design(design.CASES, [12000], 4, 3)
    rows = _rows(d)
    from pd_campaign import cli
    meta = {'cases': list(design.CASES), 'rpms': [12000.0], 'trials': 4, 'seed': 3,
            'design_size': len(d)}
    shard_dirs = _shards(tmp_path, d, rows, meta, 3)
    merged = tmp_path / 'merged'
    assert cli.run_merge(shard_dirs[:2] + ['--out', str(merged)]) == 1
    with open(merged / 'trials.csv') as handle:
        assert len(list(csv.DictReader(handle))) == len(d) - len(design.shard(d, 3, 3))


def test_report_counts_errored_trials_and_states_the_shortfall(tmp_path):
    d = design.build_design(['stationary', 'compensated'], [12000], 10, 5)
    rows = []
    for trial in d:
        row = dict(trial)
        compensated = trial['case'] == 'compensated'
        row.update(success=not compensated or trial['index'] < 2, residual_mm=1.0,
                   f_out_n=3.0, f_in_n=2.0 if compensated else 2.8, max_depth_mm=4.0,
                   inner_start_mm=6.0 if compensated and trial['index'] >= 2 else 3.0,
                   stop_reason='key_point_4', stop_source='state_recognizer',
                   tracking_rms_mm=0.3 if compensated else 0.04,
                   error='timeout' if compensated and trial['index'] == 9 else '')
        rows.append(trials_csv.normalise_row({k: str(v) for k, v in row.items()}))
    summary = aggregate.summarise(rows)
    compensated = [g for g in summary if g['case'] == 'compensated'][0]
    assert compensated['trials'] == 9 and compensated['errors'] == 1
    path = tmp_path / 'report.md'
    meta = {'cases': ['stationary', 'compensated'], 'rpms': [12000.0], 'trials': 10, 'seed': 5}
    report.write_report_md(summary, meta, [], str(path))
    text = path.read_text()
    assert '2/9 (+1 errored, not counted)' in text
    assert 'compensated, 12000 rpm: 2/9' in text
    assert 'clearly below it' in text
    assert '7 of 7 failures: stopped before the inner cortical layer' in text
    assert 'F_in -0.80 N' in text


def test_summary_counts_and_schema(tmp_path):
    d = design.build_design(['stationary'], [12000], 6, 1)
    rows = _rows(d)
    summary = aggregate.summarise(rows)
    assert len(summary) == 1
    group = summary[0]
    assert group['trials'] == 6 and group['successes'] == sum(r['success'] for r in rows)
    low, high = group['wilson95']
    assert 0 <= low <= group['success_rate'] <= high <= 1
    path = tmp_path / 'trials.csv'
    trials_csv.write_trials_csv(rows, str(path))
    with open(path) as handle:
        header = next(csv.reader(handle))
    assert header == trials_csv.TRIAL_COLUMNS
    assert len(trials_csv.read_trials_csv(str(path))) == 6


def test_appended_trials_csv_is_complete_after_each_row_and_matches_the_final_file(tmp_path):
    """While a campaign runs, trials.csv gains one line per trial (constant cost per trial); after
    every append the file reads back as the rows so far, and the final sorted rewrite holds the
    same rows as the appended file."""
    d = design.build_design(['stationary', 'compensated'], [12000], 4, 3)
    rows = _rows(d)
    path = tmp_path / 'trials.csv'
    appender = trials_csv.TrialsAppender(str(path))
    for n, row in enumerate(reversed(rows), start=1):
        appender.append(row)
        read = trials_csv.read_trials_csv(str(path))
        assert len(read) == n
        assert read[-1]['trial_id'] == row['trial_id']
    appender.close()
    appended = sorted(trials_csv.read_trials_csv(str(path)), key=trials_csv.sort_key)
    final = tmp_path / 'final.csv'
    trials_csv.write_trials_csv(rows, str(final))
    assert appended == trials_csv.read_trials_csv(str(final))


@pytest.mark.parametrize('args, named', [
    (['--case', 'sideways'], '--case'),
    (['--rpm', 'fast'], '--rpm'),
    (['--rpm', '500'], '--rpm'),
    (['--trials', '0'], '--trials'),
    (['--jobs', '0'], '--jobs'),
    (['--shard', '3/2'], '--shard'),
    (['--scenario', '/nonexistent.yaml'], '--scenario'),
    (['--engine', 'warp'], '--engine'),
    (['--seed', '-1'], '--seed'),
    (['--rpm', '12000', '--rpm', '16000'], '--rpm given more than once'),
    (['--trials', '5,x'], '--trials'),
    (['--rpm', '12000,16000', '--trials', '5,5,5'], '--trials'),
])
def test_campaign_bad_arguments_exit_2(args, named):
    out = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign')] + args,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert named in out.stderr


@pytest.mark.parametrize('text, named', [
    ('trials: 3\nspeed_of_light: 3e8\n', ['speed_of_light']),   # unknown key
    ('trials: 1\nbone_motion: wobbly\n', ['bone_motion', 'wobbly']),
    ('trials: [3, 0, 3]\n', ['trials']),
    ('trials: three\n', ['trials']),
    ('trials: 1\nfaults: [gremlins]\n', ['faults', 'gremlins']),
    ('trials: 1\nfaults: [none, none]\n', ['faults']),
    ('trials: 1\nfaults: [none]\nfault_params: {spike: 3}\n', ['fault_params.spike']),
    ('trials: 1\nfaults: [none]\nfault_params: {spike_n: big}\n', ['fault_params.spike_n']),
    # Corrupt, truncated, empty or of another version: exit 2, nothing written.
    ('', ['holds no setting']),
    ('# a scenario whose settings were cut off\n# cases: [compensated]\n', ['holds no setting']),
    ('cases: [stationary, compen', ['cannot read']),
    ('trials: 3\nrpms: [12000\nseed: 1\n', ['cannot read']),
    ('version: 2\ntrials: 3\n', ['version 2 is not supported']),
    ('version: one\ntrials: 3\n', ['version']),
    ('\x00\x01binary', ['--scenario']),
    ('trials: 1\nprotocol: breakthrough\n', ['protocol', 'breakthrough']),
    ('trials: 1\nsimulator_params: {no_such_rate: 1}\n', ["unknown parameter 'no_such_rate'"]),
    ('trials: 1\nsimulator_params: {force_sensor_rate_hz: 300}\n', ['force_sensor_rate_hz']),
    ('trials: 1\nplanner_params: {no_such_hold: 1}\n', ["unknown parameter 'no_such_hold'"]),
    ('trials: 1\nplanner_params: {stop_hold_s: -1}\n', ['stop_hold_s']),
    ('trials: 1\nplanner_params: [stop_hold_s]\n', ['planner_params']),
    ('trials: 1\nplanner_params: {segment_profile: exact}\n', ['compensation_profile']),
    ('trials: 1\nengine_delays: {command_delay: 0.1}\n', ['engine_delays.command_delay']),
    ('trials: 1\nengine_delays: {command_to_arm_s: 2}\n', ['engine_delays.command_to_arm_s']),
])
def test_bad_scenario_is_an_error_naming_the_key(tmp_path, text, named):
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text)
    out_dir = tmp_path / 'out'
    out = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'),
                          '--scenario', str(bad), '--out', str(out_dir)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    for name in named:
        assert name in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) <= 2, out.stderr  # an error, not a traceback
    assert not out_dir.exists(), 'a refused scenario left output behind'


def test_a_scenario_of_this_version_is_accepted(tmp_path):
    scenario = tmp_path / 'v1.yaml'
    scenario.write_text('version: 1\ncases: [stationary]\nrpms: [12000]\ntrials: 1\n')
    from pd_campaign.scenario import load_scenario
    assert load_scenario(str(scenario))['trials'] == 1


@pytest.mark.parametrize('section, named', [
    ('{patients: {amplitude_scale_sd: 0.1}}', 'simulator.patients'),
    ('{patient: {amplitude_sd: 0.1}}', 'simulator.patient.amplitude_sd'),
    ('{patient: {amplitude_scale_sd: lots}}', 'simulator.patient.amplitude_scale_sd'),
    ('{arm: 0.1}', 'simulator.arm'),
])
def test_scenario_simulator_section_is_checked_against_the_simulator_keys(tmp_path, section,
                                                                          named):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('trials: 1\nsimulator: %s\n' % section)
    out = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'),
                          '--scenario', str(bad), '--out', str(tmp_path / 'out')],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert named in out.stderr



@pytest.mark.parametrize('name', sorted(n for n in os.listdir(os.path.join(ROOT, 'config'))
                                         if n.startswith('scenario_')))
def test_shipped_scenarios_pass_the_campaign_checks(name):
    from pd_campaign.scenario import BONE_MOTIONS, load_scenario
    scenario = load_scenario(os.path.join(ROOT, 'config', name))
    assert scenario.get('bone_motion') in BONE_MOTIONS, name


def _row(trial_id, success, residual, depth=8.0, inner=7.0, breakthrough=False):
    return {'trial_id': trial_id, 'success': success, 'residual_mm': residual,
            'max_depth_mm': depth, 'inner_start_mm': inner, 'breakthrough': breakthrough,
            'error': ''}


def test_agreement_pairs_by_trial_and_counts_outcomes():
    from pd_campaign import agreement
    a = [_row('c-1', True, 1.5), _row('c-2', False, 5.0, depth=3.0), _row('c-3', False, 0.0,
                                                                             breakthrough=True)]
    b = [_row('c-2', False, 4.0, depth=2.5), _row('c-1', True, 1.4), _row('c-9', True, 1.0)]
    pairs, figures = agreement.compare(a, b)
    assert [p[0]['trial_id'] for p in pairs] == ['c-1', 'c-2']  # c-3 and c-9 unpaired
    assert figures['paired'] == 2 and figures['same_success'] == 2
    assert figures['same_outcome'] == 2
    assert figures['median_residual_diff_mm'] == pytest.approx(1.0)
    assert agreement.outcome(a[2]) == 'breakthrough'
    assert agreement.outcome(a[1]) == 'before inner layer'
    text = agreement.markdown(pairs, figures, 'ros', 'core')
    assert 'the same success in 2 of 2' in text
    with pytest.raises(ValueError):
        agreement.compare(a, [_row('x', True, 1.0)])


def test_fault_names_are_the_engines():
    """design.FAULTS is what trial_engine injects (core::FaultKind), in the same order."""
    from pd_campaign.design import FAULTS
    out = subprocess.run(['rosrun', 'pedicle_drilling', 'trial_engine', '--list-faults'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert tuple(out.stdout.split()) == FAULTS


def test_fault_design_pairs_every_fault_with_the_fault_free_trial_of_the_same_seed():
    from pd_campaign.design import build_design
    design = build_design(['compensated'], [12000], 3, 7, ['none', 'force_nan', 'command_lost'])
    assert len(design) == 9
    by_index = {}
    for trial in design:
        by_index.setdefault(trial['index'], set()).add(trial['seed'])
    assert all(len(seeds) == 1 for seeds in by_index.values())
    assert len({t['trial_id'] for t in design}) == 9
    plain = build_design(['compensated'], [12000], 3, 7)
    assert [t['seed'] for t in plain] == [t['seed'] for t in design if t['fault'] == 'none']
    assert all('fault' not in t for t in plain)


@pytest.mark.parametrize('text, named', [
    ('trials: 1\nprotocol: peak_forces\n', 'peak_forces'),
    ('trials: 1\nsimulator_params: {no_such_rate: 1}\n', 'no_such_rate'),
    ('trials: 1\nsimulator_params: {breath_sensor_rate_hz: -64}\n', 'breath_sensor_rate_hz'),
    ('trials: 1\nplanner_params: {stop_hold_s: 1}\n', 'planner_params'),
    ('trials: 1\nengine_delays: {stop_to_planner_s: 0.05}\n', 'stop_to_planner_s'),
    ('trials: 1\nengine_delays: {command_to_arm_s: 0.05, force_to_recognizer_s: 0.1}\n',
     'force_to_recognizer_s'),
])
def test_core_engine_settings_and_bad_simulator_params_are_refused_by_the_ros_engine(tmp_path, text,
                                                                                   named):
    scenario = tmp_path / 'peaks.yaml'
    scenario.write_text(text)
    out = subprocess.run(['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'),
                          '--scenario', str(scenario), '--out', str(tmp_path / 'out'),
                          '--engine', 'ros'], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert named in out.stderr
    assert not (tmp_path / 'out').exists()


def test_peak_forces_are_read_up_to_the_stop():
    """F_out before the inner layer's entry, F_in after it, both up to the first stop (the
    recognizer's averaged force after the stop is not the paper's reading)."""
    from pd_campaign.analysis import peak_forces
    truth = [(0.0, 'outer_cortical'), (1.0, 'cancellous'), (2.0, 'inner_cortical')]
    states = [(0.5, 3.0), (1.5, 1.0), (2.5, 2.5), (3.0, 2.8), (3.5, 9.0)]
    assert peak_forces(states, truth) == (3.0, 9.0)
    assert peak_forces(states, truth, t_stop=3.0) == (3.0, 2.8)
    assert peak_forces(states, truth, t_stop=1.8) == (3.0, None)  # stopped before the layer
    assert peak_forces(states, [(0.0, 'outer_cortical')]) == (9.0, None)


def test_report_tests_the_compensated_counts_against_fig15_at_every_speed(tmp_path):
    """Fig. 15's compensated rates (90 / 50 / 40 %, read as 9/10, 5/10, 4/10) against the
    campaign's counts at each speed by Fisher's exact test; speeds the campaign did not run are
    not listed."""
    d = design.build_design(['compensated'], [12000, 16000], 20, 5)
    rows = []
    for trial in d:
        row = dict(trial)
        row.update(success=trial['index'] < (20 if trial['rpm'] == 12000 else 10),
                   residual_mm=1.0, f_out_n=3.0, f_in_n=2.8, max_depth_mm=4.0,
                   inner_start_mm=3.0, stop_reason='key_point_4', stop_source='state_recognizer',
                   tracking_rms_mm=0.04, error='')
        rows.append(trials_csv.normalise_row({k: str(v) for k, v in row.items()}))
    summary = aggregate.summarise(rows)
    path = tmp_path / 'report.md'
    meta = {'cases': ['compensated'], 'rpms': [12000.0, 16000.0], 'trials': 20, 'seed': 5}
    report.write_report_md(summary, meta, [], str(path))
    text = path.read_text()
    assert '## Paper, success against spindle speed (Fig. 15)' in text
    # Two-sided p of [[20, 0], [9, 1]] (0.333) and [[10, 10], [5, 5]] (1), worked by hand.
    assert '| compensated | 12000 | 9/10 | 20/20 | 0.33 |' in text
    assert '| compensated | 16000 | 5/10 | 10/20 | 1 |' in text
    assert '| compensated | 20000 |' not in text


def test_seed_spaces_are_disjoint_by_construction():
    # Calibration and evaluation seeds never meet, whatever the base seeds: bit 62
    # tells them apart, and each seed says which space it is from.
    calibration = {design.trial_seed(b, r, i, 'calibration')
                   for b in range(5) for r in (12000, 20000) for i in range(50)}
    evaluation = {design.trial_seed(b, r, i, 'evaluation')
                  for b in range(5) for r in (12000, 20000) for i in range(50)}
    assert len(calibration) == len(evaluation) == 500
    assert not calibration & evaluation
    assert all(design.seed_space_of(s) == 'calibration' for s in calibration)
    assert all(design.seed_space_of(s) == 'evaluation' for s in evaluation)
    assert all(0 <= s < 2 ** 63 for s in calibration | evaluation)
    # The same base seed draws different specimens in the two spaces.
    assert design.trial_seed(1, 12000, 0, 'calibration') != design.trial_seed(1, 12000, 0)
    with pytest.raises(ValueError, match='seed space'):
        design.trial_seed(1, 12000, 0, 'tuning')


def test_design_draws_from_the_space_it_is_given():
    d = design.build_design(design.CASES, [12000], 4, 3, space='calibration')
    assert {design.seed_space_of(t['seed']) for t in d} == {'calibration'}
    d = design.build_design(design.CASES, [12000], 4, 3)
    assert {design.seed_space_of(t['seed']) for t in d} == {'evaluation'}


def test_shipped_scenarios_publish_on_evaluation_seeds():
    import yaml
    import glob
    for path in glob.glob(os.path.join(ROOT, 'config', 'scenario_*.yaml')):
        with open(path) as handle:
            assert yaml.safe_load(handle).get('seed_space') == 'evaluation', path


def test_report_has_the_failure_kinds_metrics_and_h1_stops_per_volunteer(tmp_path):
    # The report counts every failure kind, the field's metrics, and the H1 stops per
    # virtual volunteer with the position error they reported.
    d = design.build_design(['stationary', 'compensated'], [12000], 4, 5)
    rows = []
    for trial in d:
        row = dict(trial)
        compensated = trial['case'] == 'compensated'
        h1 = compensated and trial['index'] >= 2
        row.update(success=not h1, breakthrough=False, residual_mm=1.2,
                   failure_kind='safety_h1' if h1 else 'success',
                   h1_error_mm=1.25 + 0.1 * trial['index'] if h1 else '',
                   stop_residual_mm=1.2, overshoot_mm=0.9, detection_latency_ms=1800.0,
                   volunteer_id=1 + trial['index'] % 2, stop_reason='x', stop_source='x',
                   f_out_n=3.0, f_in_n=2.8, tracking_rms_mm=0.1, error='')
        rows.append(trials_csv.normalise_row({k: str(v) for k, v in row.items()}))
    summary = aggregate.summarise(rows)
    compensated = [g for g in summary if g['case'] == 'compensated'][0]
    assert compensated['failure_kinds'] == {'safety_h1': 2, 'success': 2}
    assert compensated['no_penetration'] == 4
    assert compensated['quartiles_detection_latency_ms'][1] == pytest.approx(1800.0)
    groups = aggregate.h1_by_volunteer(rows)
    by_volunteer = {g['volunteer_id']: g for g in groups if g['case'] == 'compensated'}
    # Index 2 is volunteer 1 (error 1.45 mm), index 3 volunteer 2 (1.55 mm).
    assert by_volunteer['1']['h1_stops'] == 1 and by_volunteer['2']['h1_stops'] == 1
    assert by_volunteer['2']['max_h1_error_mm'] == pytest.approx(1.55)
    path = tmp_path / 'report.md'
    meta = {'cases': ['stationary', 'compensated'], 'rpms': [12000.0], 'trials': 4, 'seed': 5,
            'seed_space': 'calibration'}
    report.write_report_md(summary, meta, [], str(path), rows=rows)
    text = path.read_text()
    assert '(calibration seeds)' in text
    assert '## Failure kinds and the field\'s metrics' in text
    assert '| compensated | 12000 | 2/4 (' in text and 'safety_h1 2' in text
    assert '## Safety stops H1 per virtual volunteer' in text
    assert '| compensated | 12000 | 2 | 2 | 1 | 50 % | 1.55 [1.55, 1.55] / 1.55 |' in text


@pytest.mark.parametrize('text, named', [
    ('seed_space: tuning\n', 'seed_space'),
])
def test_a_bad_seed_space_in_a_scenario_is_refused_naming_the_key(tmp_path, text, named):
    from pd_campaign.scenario import UsageError, load_scenario
    path = tmp_path / 'scenario.yaml'
    path.write_text('cases: [stationary]\n' + text)
    with pytest.raises(UsageError, match=named):
        load_scenario(str(path))


def test_a_bad_seed_space_option_is_refused():
    from pd_campaign.arguments import parse_args
    from pd_campaign.scenario import UsageError
    with pytest.raises(UsageError, match='--seed-space'):
        parse_args(['--seed-space', 'tuning'])
    args = parse_args(['--seed-space', 'calibration', '--trials', '2'])[0]
    assert args.seed_space == 'calibration'


def test_the_retare_check_is_recorded_apart_from_the_stops():
    """The ROS monitor publishes its re-tare check on its own topic after the retreat: the
    recorder keeps it apart from the trial's stops (the outcome is the drilling's), and the row
    has it as drift_detected with the offset."""
    import types
    from pd_campaign.analysis import retare_columns
    from pd_campaign.recorder import TrialRecorder

    def check(t, offset, drift, done=True):
        stamp = types.SimpleNamespace(to_sec=lambda: t)
        return types.SimpleNamespace(header=types.SimpleNamespace(stamp=stamp), done=done,
                                     samples=83, offset_n=offset, limit_n=0.3, drift=drift,
                                     message='force_offset: ...' if drift else '')
    recorder = TrialRecorder()
    recorder.on_retare(check(14.0, 0.0, False, done=False))  # no sample: nothing to say
    assert recorder.retare is None
    recorder.on_retare(check(14.0, 0.612, True))
    assert recorder.stops == []
    assert retare_columns(recorder.retare) == {'retare_offset_n': 0.612, 'drift_detected': True}
    assert retare_columns(None) == {'retare_offset_n': None, 'drift_detected': False}
    assert retare_columns({'offset_n': 0.01, 'drift': False}) == {
        'retare_offset_n': 0.01, 'drift_detected': False}


def test_the_record_of_a_trial_ends_at_done_whatever_arrives_after():
    """The ROS engine's simulator runs on after DONE while the worker analyses the trial: once
    end_at() closed the record, what rospy's threads deliver later is not added (before, a
    ground truth appended after the cut moved sim_duration_s and the last truth run to run)."""
    import types
    from pd_campaign.recorder import TrialRecorder

    def truth(t):
        stamp = types.SimpleNamespace(to_sec=lambda: t)
        return types.SimpleNamespace(header=types.SimpleNamespace(stamp=stamp), specimen_layer=0,
                                     max_depth_cut_m=t * 1e-3, residual_inner_cortical_m=1e-3,
                                     breakthrough=False, relative_ap_m=0.0, contact=False,
                                     contact_loss_count=0)
    recorder = TrialRecorder()
    recorder.clear(100.0, 101.0)
    for t in (99.95, 100.0, 100.05, 100.1, 100.15, 100.2):
        recorder.on_truth(truth(t))
    recorder.end_at(100.07)
    assert [r[0] for r in recorder.truth] == [100.0, 100.05, 100.1]
    recorder.on_truth(truth(100.25))
    assert recorder.truth[-1][0] == 100.1 and recorder.last_truth.max_depth_cut_m == 100.1e-3
    recorder.clear(200.0)  # the next trial records again
    recorder.on_truth(truth(200.0))
    assert [r[0] for r in recorder.truth] == [200.0]


def test_a_ros_trials_time_zero_is_its_place_in_the_design():
    """ResetSimulation.time_zero from the trial's place in the campaign's design (whole seconds:
    on the simulator's 0.1 s grid), not from the worker that runs it; the bench's second reset of
    a trial half a spacing later; none without a place (the simulator's default)."""
    from pd_campaign.scenario import SCENARIO_KEYS
    from pd_campaign.worker import TRIAL_SPACING_S, time_zero
    assert time_zero({'design_position': 0}) == TRIAL_SPACING_S
    assert time_zero({'design_position': 7}) == 8 * TRIAL_SPACING_S
    assert time_zero({'design_position': 7}, second=True) == 8.5 * TRIAL_SPACING_S
    assert isinstance(time_zero({'design_position': 7}, second=True), int)
    assert time_zero({'seed': 3}) is None
    # Half a spacing is more than a reset can be from the next: the hold (pre_trial_s, at most
    # 60 s, ResetSimulation's bound), a breath (60 s at 1 bpm; slower still, the simulator falls
    # back to the next 0.1 s), the longest trial a scenario may ask for, and two minutes of
    # run-on after DONE.
    longest_trial_s = SCENARIO_KEYS['max_duration_s'].high
    assert TRIAL_SPACING_S // 2 > 60 + 60 + longest_trial_s + 120


def test_the_ros_pipelines_pace_and_lockstep_options():
    """--engine ros runs as fast as the lockstep lets it unless a bag is recorded;
    --lockstep-every-step is the ROS pipeline's, refused with the core engine; a bad real-time
    factor is refused naming the option."""
    from pd_campaign.arguments import parse_args
    from pd_campaign.scenario import UsageError
    assert parse_args(['--engine', 'ros'])[0].real_time_factor == 0.0
    assert parse_args(['--engine', 'ros', '--bags'])[0].real_time_factor == 5.0
    assert parse_args(['--engine', 'ros', '--real-time-factor', '2'])[0].real_time_factor == 2
    assert parse_args(['--engine', 'ros', '--lockstep-every-step'])[0].lockstep_every_step
    with pytest.raises(UsageError, match='--lockstep-every-step'):
        parse_args(['--lockstep-every-step'])
    for bad in ['-1', 'nan', '1001']:
        with pytest.raises(UsageError, match='--real-time-factor'):
            parse_args(['--engine', 'ros', '--real-time-factor', bad])


def test_the_profile_is_the_core_engines():
    from pd_campaign.arguments import parse_args
    from pd_campaign.scenario import UsageError
    assert parse_args(['--profile'])[0].profile
    with pytest.raises(UsageError, match='--profile'):
        parse_args(['--engine', 'ros', '--profile'])


class _Pipe:
    """A process's stdin as TrialFeed writes it; `broken` after `limit` lines."""

    def __init__(self, limit=None):
        self.lines, self.closed, self.limit = [], False, limit

    def write(self, text):
        if self.limit is not None and len(self.lines) >= self.limit:
            raise BrokenPipeError()
        self.lines.append(json.loads(text))

    def flush(self):
        pass

    def close(self):
        self.closed = True


class _Process:
    def __init__(self, limit=None):
        self.stdin = _Pipe(limit)


def test_the_trial_feed_hands_each_trial_once_in_design_order_and_closes_when_out():
    from pd_campaign import engine_core
    trials = [{'trial_id': 't%d' % k, 'seed': k} for k in range(7)]
    feed = engine_core.TrialFeed(trials)
    a, b = _Process(), _Process()
    feed.start(a)
    feed.start(b)  # each holds two: the one it runs and the next
    assert [t['trial_id'] for t in a.stdin.lines] == ['t0', 't1']
    assert [t['trial_id'] for t in b.stdin.lines] == ['t2', 't3']
    for process in (b, b, a, a, b):  # each finished trial brings the next to its process
        feed.next(process)
    assert [t['trial_id'] for t in b.stdin.lines] == ['t2', 't3', 't4', 't5']
    assert [t['trial_id'] for t in a.stdin.lines] == ['t0', 't1', 't6']
    assert a.stdin.closed and b.stdin.closed  # out of trials: end of input for both
    # A process whose pipe broke (it ended) takes nothing: its trials go to a running one.
    feed = engine_core.TrialFeed(trials[:3])
    dead, alive = _Process(limit=0), _Process()
    feed.start(dead)
    feed.start(alive)
    feed.next(alive)
    assert [t['trial_id'] for t in alive.stdin.lines] == ['t0', 't1', 't2']
    feed.next(alive)
    assert alive.stdin.closed


def test_ros_workers_are_pinned_one_per_cpu_of_the_allowed_set():
    """campaign --pin-workers: one ROS worker per CPU of the process's CPU set (a Slurm
    allocation's, not the machine's), round robin only when asked, never when off."""
    assert cli.worker_cpus(2, 'auto', {0, 1}) == [0, 1]
    assert cli.worker_cpus(1, 'auto', {3, 5}) == [3]
    assert cli.worker_cpus(3, 'auto', {0, 1}) == [None, None, None]  # more workers than CPUs
    assert cli.worker_cpus(3, 'on', {4, 2}) == [2, 4, 2]
    assert cli.worker_cpus(2, 'off', {0, 1}) == [None, None]


def test_worker_runs_on_the_cpu_it_is_given_under_batch_scheduling(tmp_path):
    """The worker pins itself and takes SCHED_BATCH before it starts its master and launch
    (they inherit both)."""
    trials = tmp_path / 'none.json'
    trials.write_text('[]')
    cpu = min(os.sched_getaffinity(0))
    script = ('import os, sys\n'
              'from pd_campaign import worker\n'
              'class Stop(Exception):\n'
              '    pass\n'
              'def popen(*a, **k):\n'
              '    print(sorted(os.sched_getaffinity(0)))\n'
              '    print(os.sched_getscheduler(0) == os.SCHED_BATCH)\n'
              '    raise Stop()\n'
              'worker.subprocess.Popen = popen\n'
              'try:\n'
              '    worker.main(sys.argv[1:])\n'
              'except Stop:\n'
              '    pass\n')
    result = subprocess.run(
        [sys.executable, '-c', script, '--port', '14990', '--trials', str(trials), '--out',
         str(tmp_path / 'out'), '--default-model', 'unused.yaml', '--cpu', str(cpu)],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split('\n')[:2] == ['[%d]' % cpu, 'True'], result.stdout
