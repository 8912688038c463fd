"""campaign_robustness: each compensator's success and tracking against the size of a model
error, on paired seeds. The sweep file's refusals, the 95 % range on hand-made counts, the
csv and markdown writers on a fake campaign layout, and one tiny real run."""
import csv
import os
import subprocess

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from pd_campaign import robustness, stats, trials_csv  # noqa: E402
from pd_campaign.robustness import ConfigError  # noqa: E402

TOOL = os.path.join(ROOT, 'scripts', 'campaign_robustness')
SLOPE = {'name': 'slope', 'parameter': 'trial_distribution/patient/gain_error', 'unit': '',
         'label': 'slope factor', 'points': [0.8, 1.0]}
RATE = {'name': 'breathing_rate', 'parameter': 'ventilator/rate_bpm', 'offset': True,
        'unit': '/min', 'label': 'rate error', 'points': [-2.0, 0.0, 2.0]}
COMPENSATORS = ['pedicle_drilling/PaperCompensator', 'pedicle_drilling/AdaptiveModelCompensator']


def _sweep(tmp_path, errors=(SLOPE,), **top):
    data = dict({'version': 1, 'scenario': 'config/scenario_realistic.yaml',
                 'compensators': COMPENSATORS[:1], 'errors': list(errors)}, **top)
    path = tmp_path / 'sweep.yaml'
    path.write_text(yaml.safe_dump(data))
    return str(path)


# --- the sweep file -----------------------------------------------------------------------------

def test_the_shipped_sweep_loads_with_its_defaults():
    config = robustness.load_config(robustness.DEFAULT_SWEEP)
    assert config['case'] == 'compensated' and config['rpm'] == 12000.0
    assert config['trials'] == 100 and config['compensators'] == COMPENSATORS
    assert config['scenario'].endswith(os.path.join('config', 'scenario_realistic.yaml'))
    assert [e['name'] for e in config['errors']] == ['slope', 'lag', 'breathing_rate']
    assert all(len(e['points']) == 7 for e in config['errors'])


@pytest.mark.parametrize('change, named', [
    ({'speed': 12000}, "unknown key 'speed'"),
    ({'version': 2}, 'version 2'),
    ({'case': 'moving'}, "case 'moving'"),
    ({'rpm': 99}, 'rpm 99'),
    ({'trials': 0}, 'trials 0'),
    ({'scenario': 'config/no_such.yaml'}, 'scenario config/no_such.yaml'),
    ({'compensators': []}, 'compensators'),
    ({'compensators': COMPENSATORS[:1] * 2}, 'compensators: pedicle_drilling/PaperCompensator'),
    ({'errors': []}, 'errors must be'),
])
def test_a_bad_top_level_key_is_an_error_naming_it(tmp_path, change, named):
    with pytest.raises(ConfigError, match='sweep.yaml') as caught:
        robustness.load_config(_sweep(tmp_path, **change))
    assert named in str(caught.value)


@pytest.mark.parametrize('change, named', [
    ({'points': []}, 'points is empty'),
    ({'points': [1.0, 'x']}, "points: 'x'"),
    ({'points': [1.0, 1.0]}, 'points: a size is given twice'),
    ({'size': 1}, "unknown key 'size'"),
    ({'name': 'a b'}, 'name must be'),
    ({'label': ''}, 'label'),
    ({'offset': 'yes'}, 'offset'),
    ({'needs_bone_motion': 'spms'}, 'needs_bone_motion'),
])
def test_a_bad_error_is_an_error_naming_the_entry_and_the_key(tmp_path, change, named):
    with pytest.raises(ConfigError) as caught:
        robustness.load_config(_sweep(tmp_path, [RATE, dict(SLOPE, **change)]))
    assert 'errors, entry 2' in str(caught.value) and named in str(caught.value)


def test_a_missing_key_or_an_error_named_twice_is_an_error(tmp_path):
    broken = {k: v for k, v in SLOPE.items() if k != 'unit'}
    with pytest.raises(ConfigError, match=r'entry 1 \(slope\): unit missing'):
        robustness.load_config(_sweep(tmp_path, [broken]))
    with pytest.raises(ConfigError, match="the name 'slope' is given twice"):
        robustness.load_config(_sweep(tmp_path, [SLOPE, SLOPE]))


def test_only_selects_by_name_and_refuses_an_unknown_one():
    errors = [dict(SLOPE), dict(RATE)]
    assert [e['name'] for e in robustness.select(errors, [])] == ['slope', 'breathing_rate']
    assert [e['name'] for e in robustness.select(errors, ['breathing_rate'])] == [
        'breathing_rate']
    with pytest.raises(ConfigError, match='--only lag'):
        robustness.select(errors, ['lag'])


def _resolve(tmp_path, errors, scenario=None, check=lambda name, value: None, **top):
    config = robustness.load_config(_sweep(tmp_path, errors, **top))
    defaults = {SLOPE['parameter']: 1.0, RATE['parameter']: 12.0,
                'trial_distribution/patient/lag_error_s': 0.0}
    return robustness.resolve(config, config['errors'], scenario or {}, defaults, check,
                              lambda name, scenario: None)


def test_an_offset_is_added_to_the_benchs_value_else_the_point_is_the_value(tmp_path):
    slope, rate = _resolve(tmp_path, [SLOPE, RATE])
    assert slope['settings'] == [0.8, 1.0] and slope['nominal_from'] == 'the default'
    assert rate['settings'] == [10.0, 12.0, 14.0] and rate['nominal'] == 12.0
    (rate,) = _resolve(tmp_path, [RATE], {'simulator_params': {'ventilator/rate_bpm': 14}})
    assert rate['settings'] == [12.0, 14.0, 16.0] and rate['nominal_from'] == 'the scenario\'s'


def test_the_points_must_include_the_nominal_one(tmp_path):
    with pytest.raises(ConfigError, match=r'slope .*points must include the nominal point 1'):
        _resolve(tmp_path, [dict(SLOPE, points=[0.8, 0.9])])


def test_the_bone_motion_an_error_needs_is_checked(tmp_path):
    lag = dict(SLOPE, name='lag', parameter='trial_distribution/patient/lag_error_s',
               points=[0.0, 0.05], needs_bone_motion='virtual_patient')
    with pytest.raises(ConfigError, match='lag .*needs_bone_motion virtual_patient'):
        _resolve(tmp_path, [lag], {'bone_motion': 'model'})


def test_a_refused_compensator_is_an_error_naming_it(tmp_path):
    config = robustness.load_config(_sweep(tmp_path))
    with pytest.raises(ConfigError, match='compensators: pedicle_drilling/PaperCompensator: no'):
        robustness.resolve(config, config['errors'], {}, {SLOPE['parameter']: 1.0},
                           lambda name, value: None, lambda name, scenario: 'no')


def test_a_point_the_declaration_refuses_is_an_error_naming_it(tmp_path, bin_dir):
    """The Simulator's own declaration (trial_engine --check-simulator, as
    campaign_sensitivity checks its ends): the gain error's range is [0.3, 3]."""
    with pytest.raises(ConfigError) as caught:
        _resolve(tmp_path, [dict(SLOPE, points=[1.0, 5.0])],
                 check=robustness.sensitivity.check_simulator_setting)
    assert 'errors, slope (trial_distribution/patient/gain_error): points: 5' in \
        str(caught.value) and 'out of range' in str(caught.value)
    with pytest.raises(ConfigError, match="unknown parameter 'no_such'"):
        _resolve(tmp_path, [dict(SLOPE, parameter='no_such')],
                 check=robustness.sensitivity.check_simulator_setting)


# --- the 95 % range -------------------------------------------------------------------------------

def _cells(*counts):
    return [{'successes': k, 'trials': n} for k, n in counts]


def test_the_range_is_the_contiguous_run_around_the_nominal_point():
    cells = _cells((80, 100), (95, 100), (100, 100), (99, 100), (94, 100), (100, 100))
    assert robustness.range_95(cells, 2) == (1, 3)  # 95/100 in, 94/100 out; 100 beyond it not
    assert robustness.range_95(_cells((19, 20), (20, 20), (18, 20)), 1) == (0, 1)  # 19/20 in


def test_no_point_at_95_percent_is_none():
    assert robustness.range_95(_cells((90, 100), (94, 100), (50, 100)), 1) is None
    assert robustness.range_95(_cells((100, 100), (94, 100), (100, 100)), 1) is None
    assert robustness.range_95(_cells((0, 0), (0, 0)), 0) is None  # no trial: not reached


def test_the_nominal_point_alone():
    assert robustness.range_95(_cells((90, 100), (96, 100), (10, 100)), 1) == (1, 1)


def test_a_range_bounded_on_one_side():
    assert robustness.range_95(_cells((99, 100), (100, 100), (97, 100), (60, 100)), 1) == (0, 2)
    assert robustness.range_95(_cells((60, 100), (100, 100), (97, 100)), 1) == (1, 2)


def _curve(values, counts, nominal):
    return [{'value': v, 'successes': k, 'trials': n, 'nominal': v == nominal}
            for v, (k, n) in zip(values, counts)]


def test_the_ranges_line():
    values = [-0.05, 0.0, 0.05, 0.1]
    text = robustness.range_text(_curve(values, [(50, 100), (99, 100), (97, 100), (90, 100)],
                                        0.0), 's')
    assert text == 'at or above 95 % from 0 s to 0.05 s; below at -0.05 s and 0.1 s'
    text = robustness.range_text(_curve(values, [(96, 100), (99, 100), (97, 100), (90, 100)],
                                        0.0), 's')
    assert text == ('at or above 95 % from -0.05 s (the smallest size run) to 0.05 s; below at '
                    '0.1 s')
    text = robustness.range_text(_curve(values, [(96, 100)] * 4, 0.0), 's')
    assert text == 'at or above 95 % at every size run, -0.05 s to 0.1 s (it may go further)'
    text = robustness.range_text(_curve(values, [(0, 100), (96, 100), (0, 100), (0, 100)], 0.0),
                                 '')
    assert text == 'at or above 95 % at the nominal point (0) only; below at -0.05 and 0.05'
    text = robustness.range_text(_curve(values, [(100, 100), (94, 100)] * 2, 0.0), '')
    assert text == 'below 95 % at the nominal point itself (0: 94/100)'


# --- the writers on a fake campaign layout --------------------------------------------------------

def _fake_campaign(directory, outcomes):
    """A trials.csv with the columns trials_csv.read_trials_csv and the counts need: one row per
    (success, first stop kind, breakthrough, tracking RMS)."""
    os.makedirs(directory)
    with open(os.path.join(directory, 'trials.csv'), 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=[
            'trial_id', 'case', 'rpm', 'index', 'seed', 'success', 'first_stop_kind',
            'failure_kind', 'breakthrough', 'tracking_rms_mm', 'error'])
        writer.writeheader()
        for index, (success, stop, broke, rms) in enumerate(outcomes):
            writer.writerow({'trial_id': 'compensated-12000-%03d' % index, 'case': 'compensated',
                             'rpm': '12000', 'index': index, 'seed': 1000 + index,
                             'success': 'true' if success else 'false', 'first_stop_kind': stop,
                             'failure_kind': 'success' if success else stop,
                             'breakthrough': 'true' if broke else 'false',
                             'tracking_rms_mm': rms, 'error': ''})
        writer.writerow({'trial_id': 'stationary-12000-000', 'case': 'stationary',
                         'rpm': '12000', 'index': 0, 'seed': 1000, 'success': 'false',
                         'breakthrough': 'true', 'tracking_rms_mm': 9.0, 'error': ''})


OK = (True, '', False, 0.2)
H1 = (False, 'safety_h1', False, 0.6)
BROKE = (False, 'breakthrough_after_stop', True, 0.8)


def test_the_writers_on_a_fake_campaign_layout(tmp_path):
    error = dict(SLOPE, points=[0.8, 1.0, 1.2], settings=[0.8, 1.0, 1.2], nominal=1.0,
                 nominal_from='the default', offset=False)
    out = str(tmp_path)
    runs = {('A', 0.8): [OK, H1, H1, BROKE], ('A', 1.0): [OK] * 4, ('A', 1.2): [OK, OK, OK, H1],
            ('B', 0.8): [OK] * 4, ('B', 1.0): [OK] * 4, ('B', 1.2): [OK] * 4}
    points = []
    for (compensator, value), outcomes in sorted(runs.items()):
        directory = os.path.join(out, compensator, 'slope_%g' % value)
        _fake_campaign(directory, outcomes)
        points.append({'dir': directory, 'compensator': 'x/' + compensator, 'error': error,
                       'point': value, 'value': value, 'nominal': value == 1.0,
                       'order': (0, compensator, value)})
    results = robustness.read_results(points, 'compensated', 12000.0)
    setup = {'out': out, 'scenario': 'config/scenario_realistic.yaml', 'sweep': 'sweep.yaml',
             'case': 'compensated', 'rpm': 12000.0, 'trials': 4, 'seed': 1,
             'seed_space': 'calibration'}
    ranges = robustness.write_outputs(setup, [error], results, {'A/slope_0.8': 1})
    with open(os.path.join(out, 'robustness.csv')) as handle:
        rows = list(csv.DictReader(handle))
    assert [(r['compensator'], r['value'], r['nominal']) for r in rows] == [
        ('x/A', '0.8', 'false'), ('x/A', '1', 'true'), ('x/A', '1.2', 'false'),
        ('x/B', '0.8', 'false'), ('x/B', '1', 'true'), ('x/B', '1.2', 'false')]
    first = rows[0]
    assert (first['trials'], first['successes'], first['h1_stops'], first['breakthroughs']) == (
        '4', '1', '2', '1')
    assert float(first['median_tracking_rms_mm']) == pytest.approx(0.6)
    low, high = stats.wilson_interval(1, 4)
    assert (float(first['wilson_low']), float(first['wilson_high'])) == (
        pytest.approx(low, rel=1e-5), pytest.approx(high, rel=1e-5))
    assert rows[2]['successes'] == '3' and rows[2]['h1_stops'] == '1'
    with open(os.path.join(out, 'robustness.md')) as handle:
        text = handle.read()
    assert '## slope: slope factor' in text and '![slope](robustness_slope.png)' in text
    assert '| `x/A` | 0.8 | 0.8 | 1/4 |' in text and '| `x/A` | 1 (nominal) | 1 | 4/4 |' in text
    assert '- `x/A`: at or above 95 % at the nominal point (1) only; below at 0.8 and 1.2.' \
        in text
    assert '- `x/B`: at or above 95 % at every size run, 0.8 to 1.2 (it may go further).' in text
    assert '`A/slope_0.8` (exit 1)' in text
    assert ranges.splitlines()[0].startswith('x/A, slope: at or above 95 %')
    assert os.path.getsize(os.path.join(out, 'robustness_slope.png')) > 1000
    assert not [n for n in os.listdir(out) if '.tmp' in n]


def test_the_tool_refuses_a_bad_sweep_before_running_anything(tmp_path, bin_dir):
    out = tmp_path / 'out'
    for errors, named in (([dict(SLOPE, points=[])], 'errors, entry 1 (slope): points is empty'),
                          ([dict(SLOPE, points=[1.0, 5.0])],
                           'errors, slope (trial_distribution/patient/gain_error): points: 5')):
        result = subprocess.run(['/usr/bin/python3', TOOL, '--sweep', _sweep(tmp_path, errors),
                                 '--out', str(out)], capture_output=True, text=True, timeout=120)
        assert result.returncode == 2 and named in result.stderr, result.stderr
    result = subprocess.run(['/usr/bin/python3', TOOL, '--sweep', _sweep(tmp_path), '--only',
                             'lag', '--out', str(out)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2 and '--only lag' in result.stderr, result.stderr
    assert not out.exists()


# --- one tiny real run ----------------------------------------------------------------------------

TINY_ARGS = ['--trials', '2', '--seed', '5', '--seed-space', 'calibration', '--jobs', '2']


@pytest.fixture(scope='module')
def tiny_run(tmp_path_factory):
    """One compensator, one error at two sizes, two trials per point, calibration seeds; run
    twice, the second run keeping both campaigns."""
    folder = tmp_path_factory.mktemp('robustness')
    sweep = _sweep(folder, trials=100)  # --trials 2 overrides it
    out = str(folder / 'out')
    runs = [subprocess.run(['/usr/bin/python3', TOOL, '--sweep', sweep, '--out', out] + TINY_ARGS,
                           capture_output=True, text=True, timeout=900) for _ in range(2)]
    return {'out': out, 'first': runs[0], 'again': runs[1]}


def test_the_tiny_run_writes_one_row_per_point_on_the_same_seeds(tiny_run):
    out, first = tiny_run['out'], tiny_run['first']
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    for name in ('robustness.csv', 'robustness.md', 'robustness_slope.png'):
        assert os.path.getsize(os.path.join(out, name)) > 100, name
    with open(os.path.join(out, 'robustness.csv')) as handle:
        rows = list(csv.DictReader(handle))
    assert [(r['compensator'], r['error'], r['value'], r['nominal'], r['trials'])
            for r in rows] == [
        ('pedicle_drilling/PaperCompensator', 'slope', '0.8', 'false', '2'),
        ('pedicle_drilling/PaperCompensator', 'slope', '1', 'true', '2')]
    seeds = []
    for value in ('0.8', '1'):
        folder = os.path.join(out, 'pedicle_drilling.PaperCompensator', 'slope_' + value)
        trials = trials_csv.read_trials_csv(os.path.join(folder, 'trials.csv'))
        assert {(r['case'], r['rpm'], r['seed_space']) for r in trials} == {
            ('compensated', 12000.0, 'calibration')}
        seeds.append(sorted(r['seed'] for r in trials))
        successes = sum(r['success'] for r in trials)
        row = rows[('0.8', '1').index(value)]
        assert int(row['successes']) == successes
        with open(os.path.join(folder, 'scenario.yaml')) as handle:
            params = yaml.safe_load(handle).get('simulator_params') or {}
        assert params.get(SLOPE['parameter']) == (0.8 if value == '0.8' else None)
    assert seeds[0] == seeds[1] and len(seeds[0]) == 2  # paired
    progress = [l for l in first.stderr.splitlines() if l.startswith('campaign_robustness: [')]
    assert len(progress) == 2 and all('finished' in l and 'ETA' in l for l in progress), progress
    assert os.path.isfile(os.path.join(out, 'identification', 'table2.md'))


def test_a_second_run_keeps_the_finished_campaigns(tiny_run):
    again = tiny_run['again']
    assert again.returncode == 0, again.stderr[-3000:]
    progress = [l for l in again.stderr.splitlines() if l.startswith('campaign_robustness: [')]
    assert len(progress) == 2 and all('kept' in l for l in progress), progress
