"""Compensators written in Python: `python:pd_campaign.compensators.
PhaseTemplateCompensator` runs in the closed loop of the core engine and of the ROS pipeline
(the CompensationPlanner nodelet embeds the interpreter), chosen by name as the C++ classes are,
with the same parameter handling; the base class and the example on their own."""
import csv
import subprocess

import numpy as np
import pytest

from pd_campaign.compensators import Compensator, PhaseTemplateCompensator

CLASS = 'python:pd_campaign.compensators.PhaseTemplateCompensator'


def run_campaign(tmp_path, *args):
    out = tmp_path / 'out'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--rpm', '12000', '--seed-space',
         'calibration', '--case', 'compensated', '--compensator', CLASS, '--out', str(out)]
        + list(args), capture_output=True, text=True, timeout=1800)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    with open(str(out / 'trials.csv')) as handle:
        return list(csv.DictReader(handle))


def test_the_core_engine_drills_with_the_python_compensator(tmp_path):
    rows = run_campaign(tmp_path, '--trials', '20', '--jobs', '2', '--seed', '20261127')
    assert len(rows) == 20
    assert [r['error'] for r in rows if r['error']] == []
    # It follows the bone: the tip-bone tracking error stays far below the breathing motion
    # (several mm uncompensated), and the drill stops on the recognizer in most trials.
    rms = sorted(float(r['tracking_rms_mm']) for r in rows)
    assert rms[len(rms) // 2] < 0.5, rms
    assert sum(r['stop_source'].endswith('state_recognizer') for r in rows) >= 15


def test_the_ros_pipeline_runs_the_python_compensator(tmp_path):
    rows = run_campaign(tmp_path, '--engine', 'ros', '--trials', '1', '--jobs', '1', '--seed',
                        '20261127')
    assert len(rows) == 1 and rows[0]['error'] == '', rows
    assert float(rows[0]['tracking_rms_mm']) < 0.5, rows[0]['tracking_rms_mm']


def test_a_missing_python_compensator_is_refused_naming_it():
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'trial_engine', '--check-compensator',
         'python:pd_campaign.compensators.NoSuchCompensator'],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert 'NoSuchCompensator' in result.stderr


def test_the_template_predicts_the_breath_it_has_seen_and_holds_before():
    c = PhaseTemplateCompensator()
    c.configure({'bins': '20'})
    c.set_ventilator({'rate_bpm': 15.0})  # 4 s breaths
    c.set_breath_start(100.0)
    assert not c.ready()
    c.observe_marker(100.0, np.array([0.0, 0.0, 0.001]))
    assert c.ready()
    assert np.allclose(c.displacement(103.0), [0.0, 0.0, 0.001])  # held: the template is empty
    for t in np.arange(100.0, 108.0, 0.125):
        c.observe_marker(t, np.array([0.0, 0.0, 0.002 * np.cos(2 * np.pi * (t - 100.0) / 4.0)]))
    for t in np.arange(108.0, 112.0, 0.3):
        assert abs(c.displacement(t)[2] - 0.002 * np.cos(2 * np.pi * (t - 100.0) / 4.0)) < 2e-4


def test_parameters_are_checked_by_name():
    c = PhaseTemplateCompensator()
    for settings, name in (({'bins': '2'}, 'bins'), ({'bins': 'x'}, 'bins'),
                           ({'nope': '1'}, 'nope')):
        with pytest.raises(ValueError) as error:
            c.configure(settings)
        assert str(error.value).startswith(name)
    assert c.parameter_names() == ['bins', 'min_samples']
    with pytest.raises(NotImplementedError):
        Compensator().displacement(0.0)
