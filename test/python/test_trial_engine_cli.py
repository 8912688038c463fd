"""trial_engine (the core engine as a tool): one JSON line per trial, an errored trial recorded
without stopping the others, and bad options or input refused with exit status 2 naming them."""
import json
import os
import subprocess

import pytest

POSE = '0,0.435859,1.319709,0,1.386025,0'  # config/drilling_pose.yaml


def run(bin_dir, *args):
    return subprocess.run([os.path.join(bin_dir, 'trial_engine')] + list(args),
                          capture_output=True, text=True, timeout=300)


def trials_file(tmp_path, trials, name='trials.json'):
    path = tmp_path / name
    path.write_text(trials if isinstance(trials, str) else json.dumps(trials))
    return str(path)


def test_one_line_per_trial_and_errors_recorded(bin_dir, tmp_path):
    path = trials_file(tmp_path, [
        {'trial_id': 'stationary-12000-000', 'seed': 5, 'case': 'stationary', 'rpm': 12000},
        {'trial_id': 'sideways-12000-000', 'seed': 5, 'case': 'sideways', 'rpm': 12000}])
    # The paper's system (no plan): the recognizer's stop.
    paper = ('--planner-param', 'depth_limit/require_plan=false')
    result = run(bin_dir, '--trials', path, '--drilling-pose', POSE, *paper)
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert [line['trial']['trial_id'] for line in lines] == ['stationary-12000-000',
                                                             'sideways-12000-000']
    record = lines[0]['record']
    assert record['stops'][0][1] == '/state_recognizer'
    assert [s[1] for s in record['status']][-1] == 'done'
    assert not record['last_truth']['breakthrough']
    assert 'mode' in lines[1]['error']
    # The same seed gives the same record, bit for bit.
    again = run(bin_dir, '--trials', path, '--drilling-pose', POSE, *paper)
    assert again.stdout == result.stdout
    # With the bench's plan (the default) the same trial ends in the inner layer too, by the
    # recognizer or the plan's depth limit.
    planned = json.loads(run(bin_dir, '--trials', path, '--drilling-pose', POSE)
                         .stdout.splitlines()[0])['record']
    first = planned['stops'][0]
    assert first[1] == '/state_recognizer' or first[2].startswith('depth_limit'), first
    assert not planned['last_truth']['breakthrough']


def test_trials_from_stdin_give_the_files_lines_and_a_bad_line_is_named(bin_dir, tmp_path):
    """`--trials -` (the campaign's feed): each line of stdin a trial, run as it arrives; the
    same output as the file gives, bit for bit. A line that is not a trial ends the run with exit
    2 naming its number, after the trials before it."""
    trials = [{'trial_id': 'stationary-12000-000', 'seed': 5, 'case': 'stationary',
               'rpm': 12000},
              {'trial_id': 'compensated-12000-000', 'seed': 9, 'case': 'stationary',
               'rpm': 16000}]
    from_file = run(bin_dir, '--trials', trials_file(tmp_path, trials), '--drilling-pose', POSE)
    assert from_file.returncode == 0, from_file.stderr
    tool = [os.path.join(bin_dir, 'trial_engine'), '--trials', '-', '--drilling-pose', POSE]
    text = '\n'.join(json.dumps(t) for t in trials) + '\n\n'  # an empty line is skipped
    streamed = subprocess.run(tool, input=text, capture_output=True, text=True, timeout=300)
    assert streamed.returncode == 0, streamed.stderr
    assert streamed.stdout == from_file.stdout
    bad = json.dumps(trials[0]) + '\n{"trial_id": "b", "case": "stationary", "rpm": 1}\n'
    refused = subprocess.run(tool, input=bad, capture_output=True, text=True, timeout=300)
    assert refused.returncode == 2
    assert 'line 2' in refused.stderr and "'seed'" in refused.stderr
    assert [json.loads(l)['trial']['trial_id'] for l in refused.stdout.splitlines()] == [
        'stationary-12000-000']
    garbled = subprocess.run(tool, input='{"trial_id"\n', capture_output=True, text=True,
                             timeout=60)
    assert garbled.returncode == 2 and 'line 1 is not JSON' in garbled.stderr


@pytest.mark.parametrize('trials, extra, named', [
    ('not json', [], '--trials'),
    ('{"trial_id": "a"}', [], 'not a list'),
    ([{'trial_id': 'a', 'case': 'stationary', 'rpm': 12000}], [], "'seed'"),
    ([{'trial_id': 'a', 'seed': -3, 'case': 'stationary', 'rpm': 12000}], [], 'seed'),
    ([], ['--model', 'linear', '--model', 'hysteresis'], '--model'),
    ([], ['--command-delay-s', '-1'], '--command-delay-s'),
    ([], ['--urdf', '/nonexistent.urdf'], '--urdf'),
    ([], ['--simulator-param', 'trial_distribution/patient/amplitude_scale_sd=0.9'],
     'trial_distribution/patient/amplitude_scale_sd = 0.9 is out of range [0, 0.3]'),
    ([], ['--simulator-param', 'trial_distribution/specimen/no_such_mm=1'],
     "unknown parameter 'trial_distribution/specimen/no_such_mm'"),
    ([], ['--simulator-param', 'arm_rate_hz'], '--simulator-param'),
    ([], ['--protocol', 'breakthrough'], '--protocol'),
])
def test_bad_input_exits_2_naming_it(bin_dir, tmp_path, trials, extra, named):
    path = trials_file(tmp_path, trials)
    result = run(bin_dir, '--trials', path, '--drilling-pose', POSE, *extra)
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert named in result.stderr
    assert result.stdout == ''


def test_a_pose_of_the_wrong_size_is_refused(bin_dir, tmp_path):
    path = trials_file(tmp_path, [])
    result = run(bin_dir, '--trials', path, '--drilling-pose', '0,1,2,3,4')
    assert result.returncode == 2
    assert 'drilling_pose' in result.stderr


def test_simulator_params_reach_the_trial(bin_dir, tmp_path):
    """--simulator-param sets the simulation by the Simulator nodelet's own declaration: an
    explicit inner-cortex thickness without spread is the specimen every seed draws."""
    path = trials_file(tmp_path, [
        {'trial_id': 'stationary-12000-000', 'seed': 5, 'case': 'stationary', 'rpm': 12000}])
    result = run(bin_dir, '--trials', path, '--drilling-pose', POSE, '--simulator-param',
                 'trial_distribution/specimen/inner_cortical_thickness_mean_mm=2.5',
                 '--simulator-param', 'trial_distribution/specimen/inner_cortical_thickness_sd_mm=0')
    assert result.returncode == 0, result.stderr
    record = json.loads(result.stdout.splitlines()[0])['record']
    assert abs(record['conditions']['inner_cortical_mm'] - 2.5) < 1e-9
    check = subprocess.run([os.path.join(bin_dir, 'trial_engine'), '--check-simulator',
                            'trial_distribution/arm/stiffness_scale_sd=0.2'],
                           capture_output=True, text=True)
    assert check.returncode == 0, check.stderr


def test_planner_params_reach_the_trial(bin_dir, tmp_path):
    """--planner-param sets the trial sequence by the CompensationPlanner nodelet's declaration:
    with a 1 s hold the recognizer's stop is followed by `stopped`, then the retreat 1 s later;
    with the default (0) the retreat starts at the stop."""
    path = trials_file(tmp_path, [
        {'trial_id': 'stationary-12000-000', 'seed': 5, 'case': 'stationary', 'rpm': 12000}])
    phases, stops = {}, {}
    for hold in ('0', '1'):
        result = run(bin_dir, '--trials', path, '--drilling-pose', POSE,
                     '--planner-param', 'stop_hold_s=' + hold,
                     '--planner-param', 'depth_limit/require_plan=false')  # the recognizer's stop
        assert result.returncode == 0, result.stderr
        record = json.loads(result.stdout.splitlines()[0])['record']
        assert record['stops'] and record['stops'][0][3] is False, record['stops']  # recognizer
        phases[hold] = {name: t for t, name in record['status']}
        stops[hold] = record['stops'][0][0]
        assert phases[hold]['retreating'] >= stops[hold]
    assert 'stopped' not in phases['0']
    assert phases['0']['retreating'] - stops['0'] < 0.01
    assert abs(phases['1']['retreating'] - phases['1']['stopped'] - 1.0) < 0.13
    bad = subprocess.run([os.path.join(bin_dir, 'trial_engine'), '--check-planner',
                          'stop_hold_s=-1'], capture_output=True, text=True)
    assert bad.returncode == 2 and 'stop_hold_s' in bad.stderr, bad.stderr
    good = subprocess.run([os.path.join(bin_dir, 'trial_engine'), '--check-planner',
                           'stop_hold_s=0.5'], capture_output=True, text=True)
    assert good.returncode == 0, good.stderr


def test_the_retare_check_tells_a_drifted_sensor_from_a_healthy_one(bin_dir, tmp_path):
    """The monitor's re-tare check when the retreat ended: a healthy sensor reads its tare
    within a few hundredths of a newton; one that drifted (the force_drift fault, 0.2 N/s from a
    moment while drilling) is flagged, with the offset it read."""
    path = trials_file(tmp_path, [
        {'trial_id': 'stationary-12000-000', 'seed': 5, 'case': 'stationary', 'rpm': 12000},
        {'trial_id': 'stationary-force_drift-12000-000', 'seed': 5, 'case': 'stationary',
         'rpm': 12000, 'fault': 'force_drift'}])
    result = run(bin_dir, '--trials', path, '--drilling-pose', POSE)
    assert result.returncode == 0, result.stderr
    healthy, drifted = [json.loads(line)['record'] for line in result.stdout.splitlines()]
    assert healthy['retare']['done'] and not healthy['retare']['drift']
    assert healthy['retare']['offset_n'] < 0.05
    assert drifted['fault']['injected']
    assert drifted['retare']['done'] and drifted['retare']['drift'], drifted['retare']
    assert drifted['retare']['offset_n'] > 0.3
    assert drifted['retare']['message'].startswith('force_offset: ')
    # Not a stop of the trial: the stops are the drilling's.
    assert all(not s[2].startswith('force_offset') for s in drifted['stops'])
