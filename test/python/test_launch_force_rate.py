"""One launch argument, force_rate_hz, declares the F/T sensor's rate to every node that depends
on it: the StateRecognizer's ~sensor_rate_hz (its block of pre_average_s in samples, and the check
of the measured rate) and the SafetyMonitor's ~expected_force_rate_hz; with the simulator, the
Simulator's ~force_sensor_rate_hz too. Read from roslaunch's own loader (--dump-params: no
master, nothing started)."""
import subprocess

import pytest
import yaml


def params(launch, *args):
    out = subprocess.run(['roslaunch', '--dump-params', 'pedicle_drilling', launch] + list(args),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr + out.stdout
    return yaml.safe_load(out.stdout)


def test_hardware_launch_declares_one_rate_to_the_recognizer_and_the_monitor():
    p = params('hardware.launch', 'force_rate_hz:=1000')
    assert p['/state_recognizer/sensor_rate_hz'] == 1000.0
    assert p['/safety_monitor/expected_force_rate_hz'] == 1000.0
    # The default: the simulated DAQ's rate, at which the block of 0.15 s is the paper's 50.
    p = params('hardware.launch')
    assert p['/state_recognizer/sensor_rate_hz'] == pytest.approx(1000.0 / 3.0, rel=1e-5)
    assert p['/safety_monitor/expected_force_rate_hz'] == p['/state_recognizer/sensor_rate_hz']
    assert round(p['/state_recognizer/pre_average_s'] * p['/state_recognizer/sensor_rate_hz']) \
        == 50
    assert '/state_recognizer/pre_average' not in p


@pytest.mark.parametrize('launch', ['drilling_pipeline.launch', 'campaign_pipeline.launch'])
def test_the_simulated_pipelines_set_the_simulators_rate_with_them(launch):
    extra = ['sim:=true'] if launch == 'drilling_pipeline.launch' else []
    p = params(launch, 'force_rate_hz:=1000', *extra)
    for name in ('/state_recognizer/sensor_rate_hz', '/safety_monitor/expected_force_rate_hz',
                 '/simulator/force_sensor_rate_hz'):
        assert p[name] == 1000.0, name
    # Without it, the parameter files' rates (the Simulator's own default: 1000/3 Hz).
    p = params(launch, *extra)
    assert p['/state_recognizer/sensor_rate_hz'] == pytest.approx(1000.0 / 3.0, rel=1e-5)
    assert '/simulator/force_sensor_rate_hz' not in p
