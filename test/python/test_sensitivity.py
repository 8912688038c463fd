"""campaign_sensitivity: one constant at a time over its documented range, on
the nominal bench's seeds. The sweep file's checks, the table and the conclusions on synthetic
trials, and a tiny real sweep whose table is recomputed from its campaigns' trials.csv."""
import csv
import json
import os
import subprocess

import pytest
from scipy.stats import binomtest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from pd_campaign import design, sensitivity, tools  # noqa: E402
from pd_campaign.sensitivity import SweepError, runner, sweep  # noqa: E402
import test_atomic_outputs as atomic_checks  # noqa: E402  (its audit hook, not its tests)

TOOL = os.path.join(ROOT, 'scripts', 'campaign_sensitivity')
GOOD = {'name': 'simulator_params.chisel_edge_share', 'low': 0.5, 'high': 0.7, 'unit': '',
        'source': 'doc/simulator_physics.md §2b'}


def _sweep_file(tmp_path, constants, **top):
    import yaml
    path = tmp_path / 'sweep.yaml'
    path.write_text(yaml.safe_dump(dict(top, constants=constants)))
    return str(path)


# --- the sweep file -----------------------------------------------------------------------------

def test_a_constant_is_named_dotted_or_with_its_kind(tmp_path):
    entries = sensitivity.load_sweep(_sweep_file(tmp_path, [
        GOOD, dict(GOOD, name='tracker_to_pipeline_s', kind='engine_delays', low=0, high=0.02,
                   nominal=0.014)]))
    assert [(e['kind'], e['name']) for e in entries] == [
        ('simulator_params', 'chisel_edge_share'), ('engine_delays', 'tracker_to_pipeline_s')]
    assert entries[0]['nominal'] is None and entries[1]['nominal'] == 0.014
    assert entries[1]['key'] == 'engine_delays.tracker_to_pipeline_s'


@pytest.mark.parametrize('change, named', [
    ({'lo': 0.5}, ["constant 2 (simulator_params.chisel_edge_share)", "unknown key 'lo'"]),
    ({'low': 0.8}, ['constant 2', 'low 0.8 is not below high 0.7']),
    ({'low': 0.7}, ['constant 2', 'low 0.7 is not below high 0.7']),
    ({'high': 'big'}, ['constant 2', "high 'big' is not a finite number"]),
    ({'low': True}, ['constant 2', 'low True is not a finite number']),
    ({'nominal': 0.9}, ['constant 2', 'nominal 0.9 is outside [0.5, 0.7]']),
    ({'source': ''}, ['constant 2', 'source']),
    ({'unit': 3}, ['constant 2', 'unit']),
    ({'name': 'chisel_edge_share'}, ['constant 2 (chisel_edge_share)', 'kind:']),
    ({'name': 'chisel_edge_share', 'kind': 'planner_params'}, ['constant 2', 'kind:']),
    ({'kind': 'engine_delays'}, ['constant 2', "kind 'engine_delays' contradicts"]),
    ({'name': 'simulator_params.'}, ['constant 2', 'empty']),
])
def test_a_bad_entry_is_an_error_naming_it(tmp_path, change, named):
    entry = dict(GOOD, **change)
    other = dict(GOOD, name='simulator_params.force_noise_sd_n', low=0.01, high=0.05)
    with pytest.raises(SweepError) as error:
        sensitivity.load_sweep(_sweep_file(tmp_path, [other, entry]))
    for text in named:
        assert text in str(error.value), (text, str(error.value))


def test_a_missing_key_or_a_constant_listed_twice_is_an_error(tmp_path):
    missing = {k: v for k, v in GOOD.items() if k != 'high'}
    with pytest.raises(SweepError, match='constant 1 .*high missing'):
        sensitivity.load_sweep(_sweep_file(tmp_path, [missing]))
    twice = dict(GOOD, name='chisel_edge_share', kind='simulator_params')
    with pytest.raises(SweepError, match='constant 2 .*listed twice'):
        sensitivity.load_sweep(_sweep_file(tmp_path, [GOOD, twice]))


@pytest.mark.parametrize('text, named', [
    ('constants: []\n', 'non-empty list'),
    ('- name: x\n', 'not a mapping'),
    ('constants: [1]\n', 'constant 1: not a mapping'),
    ('version: 2\nconstants: [1]\n', 'version 2'),
    ('constant: []\n', "unknown key 'constant'"),
    ('constants: [name: [\n', 'cannot read'),
])
def test_a_bad_sweep_file_is_an_error(tmp_path, text, named):
    path = tmp_path / 'sweep.yaml'
    path.write_text(text)
    with pytest.raises(SweepError, match=named.replace('[', r'\[')):
        sensitivity.load_sweep(str(path))


DEFAULTS = {'simulator_params': {'chisel_edge_share': 0.6, 'tracker_noise_rms_mm': 0.25},
            'engine_delays': {'tracker_to_pipeline_s': 0.0, 'command_to_arm_s': 0.001}}


def _no_objection(name, value):
    return None


def _entries(*changes):
    out = []
    for change in changes:
        raw = dict(GOOD, **change)
        out.append(sweep._entry('sweep.yaml', len(out) + 1, raw))
    return out


def test_the_nominal_is_the_scenarios_else_the_sweep_files_else_the_default():
    entries = _entries({}, {'name': 'engine_delays.command_to_arm_s', 'low': 0.001,
                            'high': 0.12},
                       {'name': 'engine_delays.tracker_to_pipeline_s', 'low': 0, 'high': 0.02,
                        'nominal': 0.014})
    scenario = {'engine_delays': {'command_to_arm_s': 0.035}}
    sensitivity.resolve(entries, scenario, DEFAULTS, _no_objection)
    assert [(e['nominal'], e['nominal_from']) for e in entries] == [
        (0.6, 'default'), (0.035, 'scenario'), (0.014, 'sweep file')]
    nominal = sensitivity.nominal_scenario(scenario, entries)
    assert nominal['engine_delays'] == {'command_to_arm_s': 0.035, 'tracker_to_pipeline_s': 0.014}
    assert scenario == {'engine_delays': {'command_to_arm_s': 0.035}}, 'the scenario is kept'


def test_a_simulator_section_sets_the_nominal_of_a_trial_distribution_key():
    entries = _entries({'name': 'simulator_params.trial_distribution/specimen/'
                                'cancellous_fraction_mean', 'low': 0.1, 'high': 0.35})
    sensitivity.resolve(entries, {'simulator': {'specimen': {'cancellous_fraction_mean': 0.3}}},
                        DEFAULTS, _no_objection)
    assert (entries[0]['nominal'], entries[0]['nominal_from']) == (0.3, 'scenario')


@pytest.mark.parametrize('change, scenario, named', [
    ({'name': 'engine_delays.tracker_delay_s', 'low': 0, 'high': 0.02}, {},
     ["constant 1 (engine_delays.tracker_delay_s)", 'unknown engine delay']),
    ({'name': 'engine_delays.command_to_arm_s', 'low': 0.005, 'high': 0.12}, {},
     ['constant 1', 'the nominal 0.001 (default) is outside [0.005, 0.12]']),
    ({'name': 'engine_delays.command_to_arm_s', 'low': 0.001, 'high': 0.02},
     {'engine_delays': {'command_to_arm_s': 0.035}},
     ['the nominal 0.035 (scenario) is outside']),
    ({'name': 'engine_delays.command_to_arm_s', 'low': 0.001, 'high': 2}, {},
     ["high 2 s is outside the delays' [0, 1] s"]),
    ({'nominal': 0.55}, {'simulator_params': {'chisel_edge_share': 0.6}},
     ['the scenario sets 0.6, the sweep file says nominal 0.55']),
    ({'name': 'simulator_params.no_such_share'}, {},
     ['constant 1 (simulator_params.no_such_share)', 'no declared default']),
])
def test_a_constant_the_bench_cannot_take_is_an_error_naming_it(change, scenario, named):
    entries = _entries(change)
    with pytest.raises(SweepError) as error:
        sensitivity.resolve(entries, scenario, DEFAULTS, _no_objection)
    for text in named:
        assert text in str(error.value), (text, str(error.value))


def test_the_declarations_message_names_the_entry_and_the_end():
    def objects(name, value):
        return 'chisel_edge_share = %g is out of range [0, 0.9]' % value if value > 0.9 else None
    entries = _entries({'high': 0.95})
    with pytest.raises(SweepError, match=r'constant 1 \(simulator_params.chisel_edge_share\): '
                       r'high 0.95: chisel_edge_share = 0.95 is out of range'):
        sensitivity.resolve(entries, {}, DEFAULTS, objects)


def test_only_selects_by_name_or_key_and_refuses_an_unknown_one():
    entries = _entries({}, {'name': 'engine_delays.command_to_arm_s', 'low': 0.001,
                            'high': 0.12})
    assert sensitivity.select(entries, []) == entries
    assert sensitivity.select(entries, ['command_to_arm_s']) == entries[1:]
    assert sensitivity.select(entries, ['simulator_params.chisel_edge_share']) == entries[:1]
    with pytest.raises(SweepError, match='--only chisel: no such constant'):
        sensitivity.select(entries, ['chisel'])


def test_an_end_at_the_nominal_value_uses_the_nominal_campaign(tmp_path):
    entries = _entries({'name': 'simulator_params.tracker_noise_rms_mm', 'low': 0.052,
                        'high': 0.25})
    sensitivity.resolve(entries, {}, DEFAULTS, _no_objection)
    benches = sensitivity.conditions(entries, {'trials': 3}, str(tmp_path))
    assert [b['id'] for b in benches] == ['nominal', 'simulator_params.tracker_noise_rms_mm-low',
                                          'simulator_params.tracker_noise_rms_mm-high']
    low, high = benches[1], benches[2]
    assert low['scenario'] == {'trials': 3, 'simulator_params': {'tracker_noise_rms_mm': 0.052}}
    assert high['scenario'] is None and high['dir'] == benches[0]['dir']


def test_the_shipped_sweep_names_declared_constants_with_sourced_ranges():
    """config/sensitivity.yaml against the real declarations (the built tools): every name is a
    Simulator parameter or an engine delay, every end is taken, the nominal of the paper's bench
    lies in every range, every source names a document."""
    from pd_campaign.scenario import DEFAULT_SCENARIO, load_scenario
    entries = sensitivity.load_sweep(sensitivity.DEFAULT_SWEEP)
    scenario = load_scenario(DEFAULT_SCENARIO)
    sensitivity.resolve(entries, scenario, sensitivity.declared_defaults())
    assert len(entries) >= 8
    for entry in entries:
        assert entry['source'].startswith(('doc/simulator_physics.md', 'doc/bench_sources.md')), \
            entry
    realistic = load_scenario(os.path.join(ROOT, 'config', 'scenario_realistic.yaml'))
    sensitivity.resolve(sensitivity.load_sweep(sensitivity.DEFAULT_SWEEP), realistic,
                        sensitivity.declared_defaults())
    # The realistic bench's own sweep: its imperfections around the scenario's values.
    own = sensitivity.load_sweep(os.path.join(ROOT, 'config', 'sensitivity_realistic.yaml'))
    sensitivity.resolve(own, realistic, sensitivity.declared_defaults())
    assert len(own) >= 5
    for entry in own:
        assert entry['source'].startswith(('doc/simulator_physics.md', 'doc/bench_sources.md')), \
            entry
    # The population bench's distributions around the scenario's (the Simulator's defaults).
    population = load_scenario(os.path.join(ROOT, 'config', 'scenario_population.yaml'))
    own = sensitivity.load_sweep(os.path.join(ROOT, 'config', 'sensitivity_population.yaml'))
    sensitivity.resolve(own, population, sensitivity.declared_defaults())
    assert len(own) >= 6
    for entry in own:
        assert entry['source'].startswith('doc/simulator_physics.md section 6'), entry


def test_the_declaration_refuses_an_unknown_simulator_parameter():
    message = sensitivity.check_simulator_setting('chisel_edge_shar', 0.5)
    assert "unknown parameter 'chisel_edge_shar'" in message
    assert sensitivity.check_simulator_setting('chisel_edge_share', 0.5) is None
    assert 'must divide' in sensitivity.check_simulator_setting('force_sensor_rate_hz', 300)


# --- the table and the conclusions on synthetic trials ------------------------------------------

def _rows(case, rpm, outcomes, kinds=None):
    """Trial rows of one case and speed: outcome i on seed i (the same seeds in every case)."""
    return [{'case': case, 'rpm': float(rpm), 'seed': i, 'success': bool(ok), 'error': '',
             'failure_kind': ('success' if ok else (kinds or {}).get(i, 'stopped_shallow'))}
            for i, ok in enumerate(outcomes)]


def _bench(rpm_outcomes):
    """{rpm: (stationary, uncompensated, compensated) outcomes} as the rows of one bench."""
    rows = []
    for rpm, cases in rpm_outcomes.items():
        for case, outcomes in zip(design.CASES, cases):
            rows += _rows(case, rpm, outcomes)
    return rows


def test_compensated_equals_stationary_fails_only_on_a_significant_difference():
    same = _bench({12000: ([1] * 20, [0] * 20, [1] * 19 + [0])})
    verdict = sensitivity.compensated_equals_stationary(same, [12000.0])
    assert verdict['holds'] is True and 'compensated 19/20, stationary 20/20' in verdict['detail']
    # 6 discordant pairs, all one way: McNemar p = 2 / 2^6 = 0.031
    worse = _bench({12000: ([1] * 20, [0] * 20, [1] * 14 + [0] * 6)})
    assert sensitivity.compensated_equals_stationary(worse, [12000.0])['holds'] is False
    # 5 one way: p = 0.0625, not significant
    five = _bench({12000: ([1] * 20, [0] * 20, [1] * 15 + [0] * 5)})
    assert sensitivity.compensated_equals_stationary(five, [12000.0])['holds'] is True
    # Every speed must hold.
    both = _bench({12000: ([1] * 20, [0] * 20, [1] * 20), 16000: ([1] * 20, [0] * 20,
                                                                  [1] * 14 + [0] * 6)})
    verdict = sensitivity.compensated_equals_stationary(both, [12000.0, 16000.0])
    assert verdict['holds'] is False and '16000 rpm' in verdict['detail']
    missing = sensitivity.compensated_equals_stationary(same, [12000.0, 16000.0])
    assert missing['holds'] is None


def test_compensated_beats_uncompensated_needs_a_significant_difference_its_way():
    beats = _bench({12000: ([1] * 10, [0] * 10, [1] * 10)})
    assert sensitivity.compensated_beats_uncompensated(beats, [12000.0])['holds'] is True
    small = _bench({12000: ([1] * 10, [1] * 6 + [0] * 4, [1] * 10)})  # p = 0.125
    assert sensitivity.compensated_beats_uncompensated(small, [12000.0])['holds'] is False
    reverse = _bench({12000: ([1] * 10, [1] * 10, [0] * 10)})  # significant, the other way
    assert sensitivity.compensated_beats_uncompensated(reverse, [12000.0])['holds'] is False


def test_the_best_speed_verdicts():
    def bench(k12, k16, n=20):
        return _bench({12000: ([1] * n, [0] * n, [1] * k12 + [0] * (n - k12)),
                       16000: ([1] * n, [0] * n, [1] * k16 + [0] * (n - k16))})
    rpms = [12000.0, 16000.0]
    flat = bench(20, 20)
    assert sensitivity.best_speed_not_beaten(flat, rpms)['holds'] is True
    assert sensitivity.best_speed_significantly(flat, rpms)['holds'] is False
    drop = bench(18, 8)  # Fisher p = 0.003
    assert sensitivity.best_speed_not_beaten(drop, rpms)['holds'] is True
    assert sensitivity.best_speed_significantly(drop, rpms)['holds'] is True
    rise = bench(8, 18)
    assert sensitivity.best_speed_not_beaten(rise, rpms)['holds'] is False
    assert sensitivity.best_speed_significantly(rise, rpms)['holds'] is False
    slight = bench(17, 19)  # 16000 rpm higher, not significantly
    assert sensitivity.best_speed_not_beaten(slight, rpms)['holds'] is True
    one_speed = _bench({12000: ([1] * 5, [0] * 5, [1] * 5)})
    assert sensitivity.best_speed_not_beaten(one_speed, [12000.0])['holds'] is None
    no_12000 = _bench({16000: ([1] * 5, [0] * 5, [1] * 5), 20000: ([1] * 5, [0] * 5, [1] * 5)})
    assert sensitivity.best_speed_significantly(no_12000, [16000.0, 20000.0])['holds'] is None


def test_errored_trials_are_left_out_of_every_count():
    rows = _bench({12000: ([1] * 10, [0] * 10, [1] * 10)})
    for row in rows:
        if row['case'] == 'compensated' and row['seed'] < 6:
            row.update(success=False, error='engine died')
    cell = sensitivity.success_cell([r for r in rows if r['case'] == 'compensated'])
    assert (cell['successes'], cell['trials'], cell['errors']) == (4, 4, 6)
    verdict = sensitivity.compensated_equals_stationary(rows, [12000.0])
    assert verdict['holds'] is True and 'compensated 4/4, stationary 4/4' in verdict['detail']


def test_a_row_gives_both_ends_against_the_nominal_and_the_kinds_that_moved():
    entry = dict(_entries({})[0], nominal=0.6, nominal_from='default')
    nominal = _rows('uncompensated', 12000, [1] * 6 + [0] * 4,
                    {6: 'breakthrough_before_stop', 7: 'breakthrough_before_stop'})
    low = _rows('uncompensated', 12000, [1] * 10)
    high = _rows('uncompensated', 12000, [1] * 2 + [0] * 8,
                 {i: 'breakthrough_before_stop' for i in range(2, 10)})
    row = sensitivity.constant_row(entry, nominal, {'low': low, 'high': high})
    assert (row['low_cell']['successes'], row['nominal_cell']['successes'],
            row['high_cell']['successes']) == (10, 6, 2)
    assert row['swing'] == pytest.approx(0.8)
    assert row['low_test'] == {'pairs': 10, 'only_end': 4, 'only_nominal': 0,
                               'mcnemar_p': pytest.approx(0.125)}
    assert row['high_test']['only_nominal'] == 4 and row['high_test']['only_end'] == 0
    assert row['low_moved'] == {'breakthrough_before_stop': [2, 0], 'stopped_shallow': [2, 0]}
    assert row['high_moved'] == {'breakthrough_before_stop': [2, 8], 'stopped_shallow': [2, 0]}


def _conclusions(results):
    """The conclusions, by id, of a sweep of chisel_edge_share and command_to_arm_s (whose low
    end is the nominal bench) over `results`, {bench id: trial rows}, at 12000 rpm."""
    entries = _entries({}, {'name': 'engine_delays.command_to_arm_s', 'low': 0.001,
                            'high': 0.12})
    sensitivity.resolve(entries, {}, DEFAULTS, _no_objection)
    benches = sensitivity.conditions(entries, {}, '/nowhere')
    return {c['id']: c for c in sensitivity.conclusions(results, benches, [12000.0])}


def test_the_conclusions_list_the_ends_where_they_fail():
    good = _bench({12000: ([1] * 10, [0] * 10, [1] * 10)})
    bad = _bench({12000: ([1] * 10, [0] * 10, [0] * 10)})
    found = _conclusions({'nominal': good, 'simulator_params.chisel_edge_share-low': good,
                          'simulator_params.chisel_edge_share-high': bad,
                          'engine_delays.command_to_arm_s-low': good,
                          'engine_delays.command_to_arm_s-high': bad})
    equal = found['compensated_equals_stationary']
    assert equal['nominal']['holds'] is True and equal['holds_over_range'] is False
    assert len(equal['ends']) == 3, 'the low end of command_to_arm_s is the nominal bench'
    assert [(e['key'], e['end']) for e in equal['fails_at']] == [
        ('simulator_params.chisel_edge_share', 'high'), ('engine_delays.command_to_arm_s', 'high')]
    assert found['best_speed']['holds_over_range'] is None
    text = sensitivity.conclusions_markdown(list(found.values()))
    assert 'fails at 2 of 3 swept ends' in text
    assert '`simulator_params.chisel_edge_share` = 0.7 (high)' in text
    assert sensitivity.overall({'holds': True}, [{'holds': True}]) is True
    assert sensitivity.overall({'holds': True}, [{'holds': None}]) is None
    assert sensitivity.overall({'holds': None}, [{'holds': False}]) is False


def test_an_end_whose_every_trial_errored_is_not_evaluated_not_failed():
    good = _bench({12000: ([1] * 10, [0] * 10, [1] * 10)})
    errored = _bench({12000: ([0] * 10, [0] * 10, [0] * 10)})
    for row in errored:
        row['error'] = 'the planner failed the trial (statuses: moving_to_pose failed)'
    verdict = sensitivity.compensated_beats_uncompensated(errored, [12000.0])
    assert verdict['holds'] is None
    assert 'no compensated and uncompensated pair without an error' in verdict['detail']
    assert 'moving_to_pose failed' in verdict['detail']
    found = _conclusions({'nominal': good, 'simulator_params.chisel_edge_share-low': good,
                          'simulator_params.chisel_edge_share-high': good,
                          'engine_delays.command_to_arm_s-high': errored})
    beats = found['compensated_beats_uncompensated']
    assert beats['fails_at'] == [] and beats['holds_over_range'] is None
    text = sensitivity.conclusions_markdown([beats])
    assert 'holds at every one of the 2 evaluated ends** (of 3)' in text
    assert 'not evaluated: `engine_delays.command_to_arm_s` = 0.12 (high)' in text


def test_with_sets_a_labs_companion_setting_at_the_swept_ends_only():
    entries = _entries({}, {'name': 'engine_delays.command_to_arm_s', 'low': 0.001,
                            'high': 0.12, 'with': {'planner_params': {
                                'controller_watch/arm_desired_tolerance_rad': 0.035}}})
    sensitivity.resolve(entries, {}, DEFAULTS, _no_objection)
    benches = {b['id']: b for b in sensitivity.conditions(entries, {}, '/nowhere')}
    high = benches['engine_delays.command_to_arm_s-high']
    assert high['scenario']['engine_delays'] == {'command_to_arm_s': 0.12}
    assert high['scenario']['planner_params'] == {
        'controller_watch/arm_desired_tolerance_rad': 0.035}
    assert 'with planner_params.controller_watch/arm_desired_tolerance_rad = 0.035' in \
        sensitivity.label(high)
    # The low end is the nominal value: the nominal campaign, without the companion setting.
    assert benches['engine_delays.command_to_arm_s-low']['scenario'] is None
    assert 'planner_params' not in benches['nominal']['scenario']
    for bad in ({'recognizer': {'x': 1}}, {'planner_params': {}}, ['planner_params']):
        with pytest.raises(sensitivity.SweepError, match='with must map'):
            _entries({}, {'name': 'engine_delays.command_to_arm_s', 'low': 0.001,
                          'high': 0.12, 'with': bad})


# --- the tool ----------------------------------------------------------------------------------

TINY = [{'name': 'simulator_params.chisel_edge_share', 'low': 0.5, 'high': 0.7, 'unit': '',
         'source': 'doc/simulator_physics.md §2b'},
        {'name': 'engine_delays.tracker_to_pipeline_s', 'low': 0.0, 'high': 0.02, 'unit': 's',
         'source': 'doc/bench_sources.md item 1'}]
PROGRESS = 'campaign_sensitivity: ['
BENCHES = ('engine_delays.tracker_to_pipeline_s-high', 'nominal',
           'simulator_params.chisel_edge_share-high', 'simulator_params.chisel_edge_share-low')
TINY_ARGS = ['--rpm', '12000', '--trials', '2', '--seed', '5', '--jobs', '2']


def _run(*args):
    return subprocess.run(['/usr/bin/python3', TOOL] + list(args), capture_output=True,
                          text=True)


def _run_hooked(log, out, *args):
    """The tool under the audit hook of test_atomic_outputs.py: (result, the files under `out`
    it opened for writing itself; its campaigns are other processes)."""
    env = dict(os.environ, ATOMIC_WATCH=out, ATOMIC_LOG=log)
    result = subprocess.run(['/usr/bin/python3', '-c', atomic_checks.HOOKED, TOOL] + list(args),
                            capture_output=True, text=True, env=env)
    with open(log) as handle:
        return result, json.load(handle)


@pytest.fixture(scope='module')
def tiny_sweep(tmp_path_factory):
    """A tiny real sweep: two constants (one end of the second at its nominal value), two trials
    per case at 12000 rpm; run twice, the second run keeping every finished campaign."""
    folder = tmp_path_factory.mktemp('sensitivity')
    sweep = _sweep_file(folder, TINY)
    out = str(folder / 'out')
    os.makedirs(out)
    first, written = _run_hooked(str(folder / 'first.json'), out, '--sweep', sweep, '--out', out,
                                 *TINY_ARGS)
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    with open(os.path.join(out, 'sensitivity.csv')) as handle:
        table = handle.read()
    again, written_again = _run_hooked(str(folder / 'again.json'), out, '--sweep', sweep,
                                       '--out', out, *TINY_ARGS)
    return {'out': out, 'first': first, 'again': again, 'table': table,
            'written': written, 'written_again': written_again}


def _trials(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return list(csv.DictReader(handle))


def _cell(rows, case):
    mine = [r for r in rows if r['case'] == case and not r['error']]
    return sum(r['success'] == 'true' for r in mine), len(mine)


def _mcnemar(end, nominal, case):
    by_seed = {r['seed']: r['success'] == 'true' for r in nominal if r['case'] == case}
    only_end = only_nominal = 0
    for row in end:
        if row['case'] == case:
            ok = row['success'] == 'true'
            only_end += ok and not by_seed[row['seed']]
            only_nominal += by_seed[row['seed']] and not ok
    n = only_end + only_nominal
    return 1.0 if n == 0 else binomtest(only_end, n, 0.5).pvalue


def test_the_tiny_sweep_runs_one_campaign_per_end_and_prints_one_line_each(tiny_sweep):
    out = tiny_sweep['out']
    lines = [l for l in tiny_sweep['first'].stdout.splitlines() if l.startswith(PROGRESS)]
    assert len(lines) == 4 and all('finished' in l for l in lines), lines
    assert '\r' not in tiny_sweep['first'].stdout
    assert sorted(d for d in os.listdir(out) if os.path.isdir(os.path.join(out, d))) == [
        'engine_delays.tracker_to_pipeline_s-high', 'identification', 'nominal',
        'simulator_params.chisel_edge_share-high', 'simulator_params.chisel_edge_share-low']
    # Table II identified once for the sweep: every campaign took it, none drew figures.
    with open(os.path.join(out, 'identification', 'table2.md')) as handle:
        table2 = handle.read()
    for bench in BENCHES:
        folder = os.path.join(out, bench)
        with open(os.path.join(folder, 'campaign.log')) as handle:
            assert 'identifying the five virtual volunteers' not in handle.read(), bench
        assert not os.path.exists(os.path.join(folder, 'identification', 'data')), bench
        with open(os.path.join(folder, 'table2.md')) as handle:
            assert handle.read() == table2, bench
        assert not [n for n in os.listdir(folder) if n.endswith('.png')], bench
    for name in ('sensitivity.md', 'sensitivity.csv', 'sensitivity.json', 'sensitivity.png'):
        assert os.path.getsize(os.path.join(out, name)) > 100, name
    assert not [n for n in os.listdir(out) if '.tmp' in n]
    with open(os.path.join(out, 'simulator_params.chisel_edge_share-low', 'design.json')) as h:
        meta = json.load(h)['meta']
    assert meta['simulator_params'] == {'chisel_edge_share': 0.5} and meta['engine_delays'] == {}
    with open(os.path.join(out, 'engine_delays.tracker_to_pipeline_s-high', 'design.json')) as h:
        assert json.load(h)['meta']['engine_delays'] == {'tracker_to_pipeline_s': 0.02}


def test_every_campaign_of_the_sweep_drills_the_same_seeds(tiny_sweep):
    out = tiny_sweep['out']
    keys = {}
    for name in BENCHES:
        if os.path.isdir(os.path.join(out, name)):
            keys[name] = sorted((r['case'], r['rpm'], r['seed']) for r in _trials(
                os.path.join(out, name)))
    expected = sorted((case, '12000', str(design.trial_seed(5, 12000, i, 'evaluation')))
                      for case in design.CASES for i in range(2))
    assert all(k == expected for k in keys.values()), keys


def test_the_table_is_what_the_campaigns_trials_give(tiny_sweep):
    out = tiny_sweep['out']
    nominal = _trials(os.path.join(out, 'nominal'))
    with open(os.path.join(out, 'sensitivity.csv')) as handle:
        table = list(csv.DictReader(handle))
    assert len(table) == 3 * len(TINY)
    with open(os.path.join(out, 'sensitivity.md')) as handle:
        markdown = handle.read()
    for row in table:
        key, case = row['constant'], row['case']
        ends = {}
        for end in ('low', 'high'):
            folder = os.path.join(out, '%s-%s' % (key, end))
            ends[end] = _trials(folder) if os.path.isdir(folder) else nominal
        k, n = _cell(nominal, case)
        assert (int(row['successes_nominal']), int(row['trials_nominal'])) == (k, n)
        rates = [k / n]
        for end, trials in ends.items():
            k, n = _cell(trials, case)
            assert (int(row['successes_' + end]), int(row['trials_' + end])) == (k, n), row
            assert float(row['mcnemar_p_' + end]) == pytest.approx(
                _mcnemar(trials, nominal, case), rel=1e-5)
            rates.append(k / n)
            assert '%d/%d (' % (k, n) in markdown
        assert float(row['swing']) == pytest.approx(max(rates) - min(rates), abs=1e-6)
    assert float(next(r for r in table if r['constant'].startswith('engine') and
                      r['case'] == 'stationary')['low']) == 0.0
    assert 'Conclusions over the range' in markdown
    assert '`engine_delays.tracker_to_pipeline_s` | 0 (nominal) / 0 / 0.02 s' in markdown


def test_the_conclusions_are_those_of_the_campaigns_trials(tiny_sweep):
    out = tiny_sweep['out']
    with open(os.path.join(out, 'sensitivity.json')) as handle:
        found = {c['id']: c for c in json.load(handle)['conclusions']}
    equal = found['compensated_equals_stationary']
    assert len(equal['ends']) == 3  # the tracker delay's low end is the nominal bench
    for end in equal['ends'] + [dict(equal['nominal'], id='nominal')]:
        trials = _trials(os.path.join(out, end['id']))
        p = _mcnemar([dict(r, case='x') for r in trials if r['case'] == 'compensated'],
                     [dict(r, case='x') for r in trials if r['case'] == 'stationary'], 'x')
        assert end['holds'] is (p >= 0.05), end
    assert found['best_speed']['nominal']['holds'] is None  # one speed


def test_every_output_is_written_through_a_temporary_file(tiny_sweep):
    temporary = atomic_checks.TEMPORARY
    direct = [p for p in tiny_sweep['written'] if not temporary.match(os.path.basename(p))]
    # The campaigns' live logs are the one deliberate exception (# not atomic in the source).
    assert direct and all(os.path.basename(p) == 'campaign.log' for p in direct), direct
    assert len(direct) == 4
    names = {os.path.basename(p).split('.tmp')[0] for p in tiny_sweep['written_again']}
    assert names == {'.sensitivity.md', '.sensitivity.csv', '.sensitivity.json',
                     '.sensitivity.png'}, names
    assert all(temporary.match(os.path.basename(p)) for p in tiny_sweep['written_again'])


def test_a_second_run_keeps_the_finished_campaigns_and_gives_the_same_table(tiny_sweep):
    again = tiny_sweep['again']
    assert again.returncode == 0, again.stderr[-2000:]
    lines = [l for l in again.stdout.splitlines() if l.startswith(PROGRESS)]
    assert len(lines) == 4 and all('complete already, kept' in l for l in lines), lines
    with open(os.path.join(tiny_sweep['out'], 'sensitivity.csv')) as handle:
        assert handle.read() == tiny_sweep['table']


def test_a_sweep_reusing_the_trials_takes_them_all_and_gives_the_same_table(tiny_sweep,
                                                                          tmp_path):
    """--reuse-trials: every campaign of the same sweep into another folder takes all its trials
    from the first one's (the same build and engine options), and the table is the same."""
    out = str(tmp_path / 'out')
    result = _run('--sweep', _sweep_file(tmp_path, TINY), '--out', out,
                  '--reuse-trials', tiny_sweep['out'], *TINY_ARGS)
    assert result.returncode == 0, result.stderr[-2000:]
    for bench in BENCHES:
        with open(os.path.join(out, bench, 'campaign.log')) as handle:
            assert '6 trials (full design), 6 taken from finished campaigns' in handle.read(), \
                bench
    with open(os.path.join(out, 'sensitivity.csv')) as handle:
        assert handle.read() == tiny_sweep['table']
    result = _run('--sweep', _sweep_file(tmp_path, TINY), '--out', out,
                  '--reuse-trials', str(tmp_path / 'absent'), *TINY_ARGS)
    assert result.returncode == 2 and '--reuse-trials' in result.stderr


def test_a_campaign_run_by_another_build_is_run_again_not_kept(tiny_sweep, tmp_path):
    """Each finished campaign records the build that ran it (build.json: tools.build_id); a
    second run keeps it only when that is today's build, so a code change that moves outcomes
    cannot leave stale campaigns in a resumed sweep."""
    import shutil
    out = str(tmp_path / 'out')
    shutil.copytree(tiny_sweep['out'], out)
    folders = sorted(d for d in os.listdir(out) if os.path.isdir(os.path.join(out, d)))
    builds = {sensitivity.built_by(os.path.join(out, d)) for d in folders
              if d != sensitivity.IDENTIFICATION_DIR}
    assert builds == {tools.build_id()} and None not in builds, builds
    stale = os.path.join(out, 'simulator_params.chisel_edge_share-low')
    with open(os.path.join(stale, sensitivity.BUILD_FILE), 'w') as handle:
        json.dump({'build_id': 'an-older-build'}, handle)
    sweep = _sweep_file(tmp_path, TINY)
    result = subprocess.run([TOOL, '--sweep', sweep, '--out', out] + TINY_ARGS,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = [l for l in result.stdout.splitlines() if l.startswith(PROGRESS)]
    assert len(lines) == 4, lines
    rerun = [l for l in lines if 'finished' in l]
    assert len(rerun) == 1 and 'chisel_edge_share' in rerun[0] and 'low' in rerun[0], lines
    assert sensitivity.built_by(stale) == tools.build_id()
    with open(os.path.join(out, 'sensitivity.csv')) as handle:
        assert handle.read() == tiny_sweep['table']  # the same build: the same trials


def test_the_tool_refuses_a_bad_sweep_before_running_anything(tmp_path):
    out = tmp_path / 'out'
    bad = _sweep_file(tmp_path, [TINY[0], dict(TINY[0], name='simulator_params.chisel_edge_shar')])
    result = _run('--sweep', bad, '--out', str(out), *TINY_ARGS)
    assert result.returncode == 2
    assert 'constant 2 (simulator_params.chisel_edge_shar)' in result.stderr
    assert "unknown parameter 'chisel_edge_shar'" in result.stderr
    assert not out.exists()
    result = _run('--sweep', _sweep_file(tmp_path, TINY), '--only', 'no_such', '--out', str(out),
                  *TINY_ARGS)
    assert result.returncode == 2 and '--only no_such' in result.stderr
    result = _run('--sweep', _sweep_file(tmp_path, TINY), '--rpm', '99', '--out', str(out))
    assert result.returncode == 2 and '--rpm' in result.stderr
    result = _run('--sweep', _sweep_file(tmp_path, TINY), '--jobs', '0', '--out', str(out))
    assert result.returncode == 2 and '--jobs' in result.stderr
    assert not out.exists()


def test_the_scenarios_cases_are_the_sweeps(tmp_path):
    """A scenario of one case (config/scenario_speed.yaml's kind) is swept on that case alone:
    no sub-campaign drills the others."""
    scenario = tmp_path / 'one_case.yaml'
    scenario.write_text('cases: [compensated]\nrpms: [12000]\ntrials: 1\nseed: 5\n'
                        'seed_space: evaluation\n')
    sweep = _sweep_file(tmp_path, TINY[:1])
    out = str(tmp_path / 'out')
    result = _run('--scenario', str(scenario), '--sweep', sweep, '--out', out, '--jobs', '2')
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    for name in ('nominal', 'simulator_params.chisel_edge_share-low',
                 'simulator_params.chisel_edge_share-high'):
        assert {r['case'] for r in _trials(os.path.join(out, name))} == {'compensated'}, name


def _fake_benches(n):
    return [{'id': 'b%d' % k, 'dir': '/nonexistent/b%d' % k, 'scenario': {}, 'entry': None,
             'end': None} for k in range(n)]


def test_a_refusal_starts_no_further_campaign_and_is_a_sweep_error(monkeypatch):
    """Up to --jobs campaigns at once; after one refuses its scenario (exit 2) none starts, the
    running ones finish, and the sweep says which one refused (no traceback)."""
    import threading
    started, lock = [], threading.Lock()
    gate = threading.Event()

    def fake(condition, argv, expected, base_path, build=None):
        with lock:
            started.append(condition['id'])
        if condition['id'] == 'b1':
            return 'ran', 2
        gate.wait(5)  # b0 runs until the refusal has been seen
        return 'ran', 0

    monkeypatch.setattr(runner, 'run_condition', fake)
    monkeypatch.setattr(runner, 'built_by', lambda directory: None)
    monkeypatch.setattr(runner, 'label', lambda condition: condition['id'])
    monkeypatch.setattr(runner, '_log_tail', lambda directory: 'refused: bad scenario')
    lines = []

    class Stream:
        def write(self, text):
            lines.append(text)
            if '[1/' in text:
                gate.set()

        def flush(self):
            pass

    with pytest.raises(sensitivity.SweepError, match='refused b1'):
        sensitivity.run_all(_fake_benches(6), [], {}, 'x.yaml', Stream(), jobs=2)
    assert sorted(started) == ['b0', 'b1'], started  # nothing after the refusal
    assert len(lines) == 2


def test_a_stopped_campaign_stops_the_sweep(monkeypatch):
    monkeypatch.setattr(runner, 'run_condition',
                        lambda c, *a, **k: ('ran', 130 if c['id'] == 'b0' else 0))
    monkeypatch.setattr(runner, 'built_by', lambda directory: None)
    monkeypatch.setattr(runner, 'label', lambda condition: condition['id'])

    class Stream:
        def write(self, text):
            pass

        def flush(self):
            pass

    with pytest.raises(KeyboardInterrupt):
        sensitivity.run_all(_fake_benches(3), [], {}, 'x.yaml', Stream(), jobs=1)
