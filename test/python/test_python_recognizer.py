"""Recognizers written in Python: `python:pd_campaign.recognizers.ThresholdRecognizer`
runs in the closed loop of the core engine (200 trials per case at 12000 rpm, calibration seeds)
and of the ROS pipeline (one trial: the StateRecognizer nodelet embeds the interpreter), chosen
by name as the C++ classes are, with the same parameter handling; pd_campaign.recognizers'
base class and baseline on their own."""
import csv
import os
import subprocess

import pytest

from pd_campaign.recognizers import BlockMean, Recognizer, ThresholdRecognizer

CLASS = 'python:pd_campaign.recognizers.ThresholdRecognizer'


def run_campaign(tmp_path, *args):
    out = tmp_path / 'out'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--rpm', '12000', '--seed-space',
         'calibration', '--recognizer', CLASS, '--out', str(out)] + list(args),
        capture_output=True, text=True, timeout=1800)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    with open(str(out / 'trials.csv')) as handle:
        return list(csv.DictReader(handle))


def stops_of_the_python_class(rows):
    return [r for r in rows if r['stop_source'].endswith('state_recognizer') and
            'ThresholdRecognizer' in r['stop_reason']]


def test_the_core_engine_runs_200_trials_per_case_with_the_python_class(tmp_path):
    rows = run_campaign(tmp_path, '--case', 'all', '--trials', '200', '--jobs', '2', '--seed',
                        '20261126')
    assert len(rows) == 600
    assert [r['error'] for r in rows if r['error']] == []
    by_case = {case: [r for r in rows if r['case'] == case]
               for case in ('stationary', 'uncompensated', 'compensated')}
    for case, case_rows in by_case.items():
        assert len(case_rows) == 200, case
        # The drill stops on the Python class's decision in most trials of every case.
        stopped = stops_of_the_python_class(case_rows)
        assert len(stopped) > 100, (case, len(stopped))
    # On a still bone its absolute thresholds find the inner layer: it is a working recognizer.
    successes = sum(r['success'] == 'true' for r in by_case['stationary'])
    assert successes > 150, successes


def test_the_ros_pipeline_runs_the_python_class(tmp_path):
    rows = run_campaign(tmp_path, '--engine', 'ros', '--case', 'stationary', '--trials', '1',
                        '--jobs', '1', '--seed', '20261126')
    assert len(rows) == 1 and rows[0]['error'] == '', rows
    assert stops_of_the_python_class(rows), rows[0]['stop_source'] + ': ' + rows[0]['stop_reason']


def test_a_missing_python_class_is_refused_naming_it(tmp_path):
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'trial_engine', '--check-recognizer',
         'python:pd_campaign.recognizers.NoSuchRecognizer'],
        capture_output=True, text=True, timeout=120)
    assert result.returncode != 0
    assert 'NoSuchRecognizer' in result.stdout + result.stderr


def feed(recognizer, forces, pre_average):
    out = []
    t = 0.0
    for force in forces:
        for _ in range(pre_average):
            t += 0.003
            result = recognizer.push(t, force)
        out.append(result)
    return out


def test_the_threshold_baseline_stops_on_the_second_cortical_rise():
    r = ThresholdRecognizer()
    r.configure({'pre_average': '5', 'cortical_n': '2.0', 'cancellous_n': '1.5',
                 'confirm': '2'})
    outputs = feed(r, [0.1, 3.0, 3.1, 1.2, 1.0, 2.5, 2.6, 2.7], 5)
    states = [o['state'] for o in outputs]
    assert states == ['idle', 'outer_cortical', 'outer_cortical', 'cancellous', 'cancellous',
                      'cancellous', 'inner_cortical', 'inner_cortical']
    assert [o['stop'] for o in outputs].index(True) == 6
    assert 'ThresholdRecognizer' in r.stop_reason()
    r.reset()
    assert feed(r, [0.1], 5)[0]['state'] == 'idle'


@pytest.mark.parametrize('settings, named', [
    ({'speed': '1'}, 'speed'), ({'pre_average': 'many'}, 'pre_average'),
    ({'cortical_n': '-1'}, 'cortical_n'), ({'confirm': '0'}, 'confirm')])
def test_bad_parameters_raise_naming_them(settings, named):
    with pytest.raises(ValueError) as error:
        ThresholdRecognizer().configure(settings)
    assert str(error.value).startswith(named)


def test_the_base_class_describes_its_parameters():
    class Two(Recognizer):
        PARAMETERS = {'a': (int, 1, lambda v: v > 0), 'b': (float, 0.5, lambda v: True)}

        def push(self, t, raw_force):
            return {}
    r = Two()
    r.configure({'a': '3'})
    assert r.parameter_names() == ['a', 'b']
    assert r.describe() == 'Two(a=3, b=0.5)'
    assert os.path.basename(__file__)  # the module imports without ROS


def test_the_block_mean_gives_each_full_blocks_mean_and_starts_again():
    blocks = BlockMean(3)
    assert [blocks.add(x) for x in (1.0, 2.0, 6.0)] == [None, None, 3.0]
    assert [blocks.add(x) for x in (0.5, 0.5, 2.0, 7.0)] == [None, None, 1.0, None]
