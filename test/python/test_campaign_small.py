"""Regression test of the campaign: a small campaign on the real pipeline (simulator and all
nodelets), and the consistency of its outputs."""
import csv
import json
import os
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


@pytest.mark.parametrize('engine', ['core', 'ros'])
def test_small_campaign_outputs_are_consistent(tmp_path, engine):
    out = tmp_path / 'campaign'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'all', '--rpm', '12000',
         '--trials', '1', '--jobs', '1', '--seed', '3', '--out', str(out),
         '--base-port', '12700', '--engine', engine],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert [r['case'] for r in rows] == ['stationary', 'uncompensated', 'compensated']
    assert {r['engine'] for r in rows} == {engine}
    assert len({r['seed'] for r in rows}) == 1, 'cases must share the specimen (paired design)'
    for row in rows:
        assert row['error'] == '', row['error']
        assert row['success'] in ('true', 'false')
        assert row['stop_reason'], 'every trial ends with a recorded reason'
        residual = float(row['residual_mm'])
        assert residual >= 0.0
        success = row['success'] == 'true'
        # success is exactly the paper's criterion on the ground truth
        entered = float(row['max_depth_mm']) > float(row['inner_start_mm'])
        assert success == (row['stop_source'].endswith('state_recognizer') and entered
                           and row['breakthrough'] == 'false' and 0.0 < residual <= 2.0)
        assert float(row['f_out_n']) > 0.0
    with open(out / 'summary.json') as handle:
        summary = json.load(handle)
    assert summary['meta']['design_size'] == 3
    for group in summary['groups']:
        matching = [r for r in rows if r['case'] == group['case']]
        assert group['trials'] == len(matching) == 1
        assert group['successes'] == sum(r['success'] == 'true' for r in matching)
        low, high = group['wilson95']
        assert 0.0 <= low <= group['success_rate'] <= high <= 1.0
    report = (out / 'report.md').read_text()
    assert 'Table III' in report and 'Wilson' in report
    for name in ('table3.png', 'fig15_success_vs_speed.png', 'fig16_peak_forces.png',
                 'fig17_force_traces.png', 'fig18_residual_thickness.png', 'table2.png'):
        assert (out / name).stat().st_size > 1000, name
    for row in rows:
        with open(out / 'traces' / (row['trial_id'] + '.json')) as handle:
            trace = json.load(handle)
        assert len(trace['t']) == len(trace['force']) > 10


def test_bags_keep_each_trial_for_replay(tmp_path):
    out = tmp_path / 'bags_campaign'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'stationary', '--rpm', '12000',
         '--trials', '1', '--jobs', '1', '--seed', '4', '--bags', '--out', str(out),
         '--base-port', '12900', '--engine', 'ros'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    bag = out / 'bags' / 'stationary-12000-000.bag'
    assert bag.exists()
    import rosbag
    with rosbag.Bag(str(bag)) as handle:
        topics = handle.get_type_and_topic_info().topics
    for topic in ('/ft_sensor/wrench', '/simulator/ground_truth', '/drilling_state', '/tf',
                  '/spindle/command', '/ventilator/settings', '/diagnostics'):
        assert topic in topics and topics[topic].message_count > 0, topic
    assert '/clock' not in topics  # rosbag play --clock makes the clock from the recorded times
    # The recording says what it lost, beside the bag and in trials.csv (whatever the machine's
    # load made the recorder drop, the report must agree with the bag).
    with open(str(bag) + '.json') as handle:
        check = json.load(handle)
    assert check['force_samples'] == topics['/ft_sensor/wrench'].message_count
    with open(out / 'trials.csv') as handle:
        row = next(csv.DictReader(handle))
    assert row['bag_lost'] == (check['summary'] or 'nothing')


def test_scenario_simulator_section_reaches_the_trials(tmp_path):
    """A scenario's `simulator:` spreads are drawn per trial (recorded in trials.csv); an
    out-of-range one is refused by the simulator with exit 2, naming the parameter."""
    scenario = tmp_path / 'spread.yaml'
    scenario.write_text(
        'cases: [uncompensated]\nrpms: [12000]\ntrials: 2\nseed: 21\n'
        'identification: online\nidentification_window_s: 10.0\nmax_duration_s: 40.0\n'
        'simulator:\n'
        '  patient: {amplitude_scale_sd: 0.2}\n'
        '  ventilator: {rate_sd_bpm: 2.0}\n'
        '  arm: {stiffness_scale_sd: 0.2}\n'
        '  sensor: {noise_scale_sd: 0.3}\n'
        '  specimen: {inner_cortical_thickness_mean_mm: 2.5, inner_cortical_thickness_sd_mm: 0}\n')
    out = tmp_path / 'spread'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(scenario), '--jobs', '1',
         '--out', str(out), '--base-port', '13100', '--engine', 'ros'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2
    for row in rows:
        assert row['error'] == '', row['error']
        assert abs(float(row['inner_cortical_mm']) - 2.5) < 1e-9
        assert 0.4 <= float(row['amplitude_scale']) <= 1.6
        assert 6.0 <= float(row['ventilator_rate_bpm']) <= 18.0
        assert 0.4 <= float(row['arm_stiffness_scale']) <= 1.6
    for column in ('amplitude_scale', 'ventilator_rate_bpm', 'arm_stiffness_scale',
                   'force_noise_sd_n'):
        assert rows[0][column] != rows[1][column], column

    bad = tmp_path / 'bad_spread.yaml'
    bad.write_text('cases: [stationary]\nrpms: [12000]\ntrials: 1\n'
                   'simulator: {patient: {amplitude_scale_sd: 0.9}}\n')
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(bad), '--jobs', '1',
         '--out', str(tmp_path / 'bad'), '--base-port', '13300', '--engine', 'ros'],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr[-3000:]
    assert 'trial_distribution/patient/amplitude_scale_sd' in result.stderr


def test_scenario_simulator_section_reaches_the_core_engine(tmp_path):
    """The same section on the core engine: passed as the Simulator's declared parameters
    (trial_engine --simulator-param) and refused before anything runs when out of range."""
    scenario = tmp_path / 'spread_core.yaml'
    scenario.write_text(
        'cases: [uncompensated]\nrpms: [12000]\ntrials: 2\nseed: 21\nmax_duration_s: 40.0\n'
        'simulator:\n'
        '  patient: {amplitude_scale_sd: 0.2}\n'
        '  specimen: {inner_cortical_thickness_mean_mm: 2.5, inner_cortical_thickness_sd_mm: 0}\n')
    out = tmp_path / 'spread_core'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(scenario), '--jobs', '1',
         '--out', str(out), '--engine', 'core'], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2
    for row in rows:
        assert row['error'] == '', row['error']
        assert abs(float(row['inner_cortical_mm']) - 2.5) < 1e-9
    assert rows[0]['amplitude_scale'] != rows[1]['amplitude_scale']

    bad = tmp_path / 'bad_spread_core.yaml'
    bad.write_text('cases: [stationary]\nrpms: [12000]\ntrials: 1\n'
                   'simulator: {patient: {amplitude_scale_sd: 0.9}}\n')
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(bad), '--jobs', '1',
         '--out', str(tmp_path / 'bad_core'), '--engine', 'core'],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr[-3000:]
    assert 'trial_distribution/patient/amplitude_scale_sd' in result.stderr
    assert not (tmp_path / 'bad_core').exists()


def test_the_peak_forces_protocol_reads_both_peaks_in_every_trial(tmp_path):
    """protocol: peak_forces (paper Sec. V-D) on the core engine: the recognizer observes, every
    trial goes through the inner layer and is stopped there by the protocol, F_out and F_in are
    defined in every trial (the recognizer's and the ground truth's), and the report is the
    peak-force report (no success table)."""
    scenario = tmp_path / 'peaks.yaml'
    scenario.write_text('cases: [stationary, uncompensated]\nrpms: [12000]\ntrials: 3\n'
                        'seed: 77\nbone_motion: model\nprotocol: peak_forces\n')
    out = tmp_path / 'peaks'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario', str(scenario), '--jobs', '2',
         '--out', str(out), '--engine', 'core'], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6
    for row in rows:
        assert row['error'] == '', row['error']
        assert row['protocol'] == 'peak_forces'
        assert row['stop_source'] == '/protocol'
        assert row['breakthrough'] == 'true' and row['success'] == 'false'
        for column in ('f_out_n', 'f_in_n', 'f_out_truth_n', 'f_in_truth_n'):
            assert float(row[column]) > 1.0, (column, row[column])
    stationary = [r for r in rows if r['case'] == 'stationary']
    for row in stationary:  # the stationary force law (doc/simulator_physics.md): about 3 N
        assert 2.3 < float(row['f_out_n']) < 4.0 and 2.0 < float(row['f_in_n']) < 4.0
    report = (out / 'report.md').read_text()
    assert 'Peak forces (Fig. 16)' in report and 'Table III' not in report
    with open(out / 'design.json') as handle:
        assert json.load(handle)['meta']['protocol'] == 'peak_forces'


def test_ctrl_c_stops_cleanly_and_keeps_finished_trials(tmp_path):
    """SIGINT to the campaign's process group (a Ctrl-C in its terminal) once a trial has
    finished: exit status 130, the finished trials kept in trials.csv and the report, the
    workers (each with its own ROS master) gone."""
    import signal
    import time
    out = tmp_path / 'interrupted'
    port = 13500
    campaign = subprocess.Popen(
        ['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'), '--case', 'stationary',
         '--rpm', '12000', '--trials', '6', '--jobs', '1', '--seed', '9', '--out', str(out),
         '--base-port', str(port), '--engine', 'ros'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        # A terminal's Ctrl-C reaches a process whose SIGINT is at its default; a test run
        # started as a background job (nohup ... &) inherits it ignored, and Python then keeps
        # ignoring it: restore the default, as a terminal has it.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 400.0
    finished = 0
    while time.time() < deadline and campaign.poll() is None and finished == 0:
        time.sleep(1.0)
        if (out / 'trials.csv').exists():
            with open(out / 'trials.csv') as handle:
                finished = len(list(csv.DictReader(handle)))
    assert campaign.poll() is None, 'the campaign ended before it could be interrupted'
    assert finished >= 1, 'no trial finished in time'
    os.killpg(campaign.pid, signal.SIGINT)
    _, stderr = campaign.communicate(timeout=120)
    assert campaign.returncode == 130, stderr[-3000:]
    assert 'interrupted' in stderr
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert finished <= len(rows) < 6
    assert all(r['error'] == '' for r in rows)
    report_text = (out / 'report.md').read_text()
    assert '%d/%d' % (sum(r['success'] == 'true' for r in rows), len(rows)) in report_text
    workers = subprocess.run(['pgrep', '-f', 'pd_campaign.worker.*%s' % out],
                             capture_output=True, text=True)
    assert workers.stdout.strip() == '', 'workers left running: %s' % workers.stdout


def _trials_without_wall_time(path):
    with open(path) as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        row.pop('wall_s')
    return rows


def test_core_engine_gives_the_same_trials_whatever_the_job_count(tmp_path):
    """One seed, one trial, bit for bit: --jobs 1 and --jobs 2 write the same trials.csv (apart
    from wall time) and the same summary, traces included; the issue's own design (30 trials
    per case, 90 trials per run, about 15 s each). The second run takes the first's Table II
    identification (--identification, as campaign_sensitivity's campaigns do) and draws no
    figure (--no-figures)."""
    outputs = []
    for jobs in ('1', '2'):
        out = tmp_path / ('jobs%s' % jobs)
        reuse = ['--identification', str(outputs[0] / 'identification'), '--no-figures'] \
            if outputs else []
        result = subprocess.run(
            ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'all', '--rpm', '12000',
             '--trials', '30', '--jobs', jobs, '--seed', '4242', '--out', str(out)] + reuse,
            capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, result.stderr[-3000:]
        outputs.append(out)
    # Not identified again: the given table and models copied, nothing else.
    assert not (outputs[1] / 'identification' / 'data').exists()
    for name in ('table2.csv', 'models/volunteer_2_linear.yaml',
                 'models/volunteer_5_hysteresis.yaml'):
        assert (outputs[1] / 'identification' / name).read_bytes() == \
            (outputs[0] / 'identification' / name).read_bytes(), name
    assert (outputs[1] / 'table2.md').read_bytes() == (outputs[0] / 'table2.md').read_bytes()
    assert sorted(p.name for p in outputs[0].glob('*.png'))  # the figures ...
    assert not list(outputs[1].glob('*.png'))  # ... not with --no-figures
    assert (outputs[1] / 'report.md').stat().st_size > 1000
    first, second = (_trials_without_wall_time(o / 'trials.csv') for o in outputs)
    assert len(first) == 90
    assert all(r['error'] == '' for r in first), [r['error'] for r in first]
    assert first == second
    for row in first:
        name = row['trial_id'] + '.json'
        assert (outputs[0] / 'traces' / name).read_bytes() == \
            (outputs[1] / 'traces' / name).read_bytes(), name
    with open(outputs[0] / 'summary.json') as a, open(outputs[1] / 'summary.json') as b:
        assert json.load(a)['groups'] == json.load(b)['groups']


def test_an_incomplete_identification_is_refused_naming_what_it_lacks(tmp_path):
    ident = tmp_path / 'ident'
    (ident / 'models').mkdir(parents=True)
    for name in ('table2.md', 'table2.csv'):
        (ident / name).write_text('x')
    for v in (1, 2, 3, 4, 5):
        for kind in ('linear', 'hysteresis'):
            if (v, kind) != (4, 'hysteresis'):
                (ident / 'models' / ('volunteer_%d_%s.yaml' % (v, kind))).write_text('x')
    result = subprocess.run(
        ['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'), '--trials', '1',
         '--identification', str(ident), '--out', str(tmp_path / 'out')],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert '--identification' in result.stderr and 'volunteer_4_hysteresis.yaml' in result.stderr
    assert not (tmp_path / 'out').exists()


def test_core_engine_refuses_what_it_does_not_support(tmp_path):
    scenario = tmp_path / 'online.yaml'
    scenario.write_text('cases: [compensated]\nrpms: [12000]\ntrials: 1\n'
                        'identification: online\n')
    result = subprocess.run(
        ['/usr/bin/python3', os.path.join(ROOT, 'scripts', 'campaign'), '--scenario',
         str(scenario), '--out', str(tmp_path / 'out')],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert 'identification' in result.stderr and '--engine ros' in result.stderr
    assert not (tmp_path / 'out').exists()


# What the safety monitor must say for each sensor fault, and its worst fault-to-stop delay [s]
# (the watchdogs' timeouts plus one check period and the 1 ms transport).
MONITORED_FAULTS = {
    'force_silent': ('force_timeout', 0.11), 'force_nan': ('nan_input', 0.002),
    'force_inf': ('nan_input', 0.002), 'force_spike': ('force_exceeded', 0.002),
    'force_stuck': ('force_stuck', 0.06), 'tracker_silent': ('tracker_timeout', 0.51),
    'tracker_stale': ('tracker_timeout', 0.51), 'tracker_jump': ('position_error', 0.13),
}


def test_fault_campaign_stops_every_sensor_fault_and_breaks_through_nowhere(tmp_path):
    """The shipped fault scenario, 3 seeds per fault: every fault injected while drilling, the
    monitor stops each sensor fault with its reason within its timeout, nothing breaks through,
    the fault-free trials are the campaign's ordinary ones, and the report has the fault table."""
    out = tmp_path / 'faults'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario',
         os.path.join(ROOT, 'config', 'scenario_faults.yaml'), '--trials', '3', '--jobs', '2',
         '--out', str(out)], capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    from pd_campaign.design import FAULTS
    assert sorted(r['fault'] for r in rows) == sorted(list(FAULTS) * 3)
    assert all(r['error'] == '' for r in rows), [r['error'] for r in rows if r['error']]
    assert [r['trial_id'] for r in rows if r['breakthrough'] == 'true'] == []
    for row in rows:
        if row['fault'] == 'none':
            assert row['fault_time_s'] == row['stop_delay_s'] == ''
            continue
        assert float(row['fault_time_s']) >= 0.0, row
        assert float(row['stop_delay_s']) >= 0.0, row
        if row['fault'] in MONITORED_FAULTS:
            reason, worst = MONITORED_FAULTS[row['fault']]
            assert row['stop_source'].endswith('safety_monitor'), row
            assert row['stop_reason'].startswith(reason), row
            assert float(row['stop_delay_s']) <= worst, row
            assert float(row['retreat_delay_s']) <= worst + 0.01, row
    with open(out / 'summary.json') as handle:
        summary = json.load(handle)
    assert {g['fault'] for g in summary['faults']} == set(FAULTS)
    assert sum(g['trials'] for g in summary['groups']) == 3  # Table III: fault-free only
    assert '## Faults' in (out / 'report.md').read_text()


def test_a_profiled_campaign_says_where_its_time_goes_and_changes_no_trial(tmp_path):
    """campaign --profile: the core engine's workers time each component; the
    merged profile covers every trial, its components fit inside the engine's steps, Bullet's
    world step inside the arm's, and the trials are the unprofiled run's, bit for bit."""
    outs = {}
    for name, extra in [('plain', []), ('profiled', ['--profile'])]:
        outs[name] = tmp_path / name
        result = subprocess.run(
            ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'all', '--rpm', '12000',
             '--trials', '1', '--jobs', '2', '--seed', '5', '--out', str(outs[name])] + extra,
            capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, result.stderr[-3000:]
    with open(outs['profiled'] / 'profile.json') as handle:
        profile = json.load(handle)
    assert profile['trials'] == 3 and profile['sim_s'] > 3 * 10.0
    wall = profile['wall_s']
    steps = wall['engine_step']
    assert steps > 0.0
    assert 0.0 < wall['bullet_world'] < wall['arm_step']
    parts = sum(v for k, v in wall.items() if k not in ('engine_step', 'bullet_world'))
    assert 0.5 * steps < parts <= steps * 1.0001
    table = (outs['profiled'] / 'profile.md').read_text()
    assert 'bullet_world' in table and 'pipeline_rest' in table
    assert not list(outs['profiled'].glob('profile-worker-*.json')), 'merged and removed'
    assert not (outs['plain'] / 'profile.json').exists()

    def trials(out):
        with open(out / 'trials.csv') as handle:
            return [{k: v for k, v in row.items() if k != 'wall_s'} for row in csv.DictReader(handle)]
    assert trials(outs['plain']) == trials(outs['profiled'])


def test_a_failing_reader_stops_its_worker_and_the_campaign_exits_1(tmp_path, monkeypatch):
    """A trial the campaign cannot read (here: writing its trace fails) stops that worker, whose
    trial_engine would otherwise wait for its next trial for ever; the campaign ends, exit 1,
    naming the error."""
    import threading
    from pd_campaign import cli, engine_core

    def unreadable(line, trace_dir):
        raise OSError('the traces folder is full')

    monkeypatch.setattr(engine_core, 'row_from_line', unreadable)
    result = {}
    run = threading.Thread(target=lambda: result.update(status=cli.run_campaign(
        ['--case', 'stationary', '--rpm', '12000', '--trials', '4', '--jobs', '1', '--seed', '3',
         '--no-figures', '--out', str(tmp_path / 'out')])), daemon=True)
    run.start()
    run.join(timeout=300)
    assert not run.is_alive(), 'the campaign hangs on a worker whose reader failed'
    assert result['status'] == 1


def test_a_pipeline_that_does_not_come_up_is_named_at_once(tmp_path):
    """A worker whose launch exits (here a launch file that does not exist; as well one that does
    not parse or is given an argument it does not take) says so with the
    end of roslaunch's log and exits 1; before, it waited a minute for /simulator/reset and
    ended with rospy's timeout traceback."""
    trials = tmp_path / 'trials.json'
    trials.write_text(json.dumps([{'trial_id': 'stationary-12000-000', 'case': 'stationary',
                                   'rpm': 12000.0, 'seed': 3, 'design_position': 0}]))
    result = subprocess.run(
        ['/usr/bin/python3', '-m', 'pd_campaign.worker', '--port', '12790', '--trials',
         str(trials), '--out', str(tmp_path / 'out'), '--default-model',
         os.path.join(ROOT, 'config', 'patient_default.yaml'), '--launch', 'no_such.launch'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 1, result.stderr[-3000:]
    assert "the pipeline's roslaunch exited" in result.stderr, result.stderr[-3000:]
    assert 'no_such.launch' in result.stderr, result.stderr[-3000:]
    assert 'Traceback' not in result.stderr, result.stderr[-3000:]
