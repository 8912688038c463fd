"""WrenchThresholdRecognizer: a Python recognizer that reads the whole wrench (push_sample):
its fused thrust, its skiving and clogging checks on their own, and in the closed loop of the
core engine and of the ROS pipeline, where the drilling torque must reach it (a clogging bound
below the simulated lever stops the trial, naming the torque)."""
import csv
import math
import re
import subprocess

from pd_campaign.recognizers import TORQUE_LEVER_M, WrenchThresholdRecognizer

CLASS = 'python:pd_campaign.recognizers.WrenchThresholdRecognizer'
NAN = float('nan')


def make(**params):
    r = WrenchThresholdRecognizer()
    settings = {'pre_average': '5'}
    settings.update({k: str(v) for k, v in params.items()})
    r.configure(settings)
    return r


def block(r, t0, thrust, torque, lateral=(0.0, 0.0)):
    """Five samples (one block); the last sample's output."""
    out = None
    for i in range(5):
        out = r.push_sample({'t': t0 + 0.003 * i, 'thrust': thrust,
                             'force': (lateral[0], lateral[1], thrust),
                             'torque': (0.0, 0.0, torque), 'feed_depth_m': NAN,
                             'spindle_rpm': 12000.0})
    return out


def test_the_block_mean_is_of_the_thrust_fused_with_the_torques():
    r = make(torque_weight=0.5)
    out = block(r, 0.0, 2.0, 3.0 * TORQUE_LEVER_M)  # the torque says 3 N
    assert math.isclose(out['averaged_force'], 2.5)
    r = make(torque_weight=0.5)
    assert math.isclose(block(r, 0.0, 2.0, NAN)['averaged_force'], 2.0)  # the thrust alone
    # The default weight: inverse variance of the sensor's noise, mostly the thrust.
    r = make()
    assert 0.0 < r.params['torque_weight'] < 0.05


def test_a_lateral_force_above_its_bound_is_a_skiving_stop():
    r = make(lateral_max_n=1.0)
    assert not block(r, 0.0, 0.5, 0.5 * TORQUE_LEVER_M, lateral=(0.6, 0.6)).get('stop')
    out = block(r, 0.1, 0.5, 0.5 * TORQUE_LEVER_M, lateral=(0.9, 0.9))  # 1.27 N
    assert out['stop']
    assert r.stop_reason().startswith('skiving'), r.stop_reason()
    assert block(r, 0.2, 0.5, 0.0)['stop']  # stays stopped until the reset
    r.reset()
    assert not block(r, 0.3, 0.5, 0.0).get('stop')
    # A non-finite lateral force is left out, not a stop.
    assert not block(r, 0.4, 0.5, 0.0, lateral=(NAN, 5.0)).get('stop')


def test_torque_without_the_thrust_to_cause_it_is_a_clogging_stop():
    r = make(torque_ratio_max=2.0, cancellous_n=1.7)
    assert not block(r, 0.0, 2.5, 1.9 * TORQUE_LEVER_M * 2.5).get('stop')
    # Out of bone (thrust below cancellous_n) the ratio is not judged.
    assert not block(r, 0.1, 1.0, 5.0 * TORQUE_LEVER_M * 1.0).get('stop')
    out = block(r, 0.2, 2.5, 2.5 * TORQUE_LEVER_M * 2.5)
    assert out['stop']
    assert r.stop_reason().startswith('clogging'), r.stop_reason()


def run_campaign(tmp_path, *args):
    out = tmp_path / 'out'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--rpm', '12000', '--seed-space',
         'calibration', '--seed', '20261129', '--recognizer', CLASS, '--out', str(out)] +
        list(args), capture_output=True, text=True, timeout=1800)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    with open(str(out / 'trials.csv')) as handle:
        return list(csv.DictReader(handle))


def torque_ratio(reason):
    """The torque per thrust over the lever that a clogging stop names."""
    match = re.search(r'([0-9.]+) times the lever', reason)
    assert match, reason
    return float(match.group(1))


def test_the_core_engine_runs_it_and_the_drilling_torque_reaches_it(tmp_path):
    rows = run_campaign(tmp_path, '--case', 'stationary,compensated', '--trials', '20',
                        '--jobs', '2')
    assert len(rows) == 40 and [r['error'] for r in rows if r['error']] == []
    # Neither check stops a simulated trial: the torque follows the thrust, the lateral force
    # is noise. The class's own stops are its thresholds'.
    ours = [r for r in rows if 'WrenchThresholdRecognizer' in r['stop_reason']]
    assert len(ours) > 20, [r['stop_reason'] for r in rows]
    assert not [r for r in ours if r['stop_reason'].startswith(('skiving', 'clogging'))]
    stationary = [r for r in rows if r['case'] == 'stationary']
    assert sum(r['success'] == 'true' for r in stationary) > 10
    # A clogging bound below the lever: the first block in bone stops, naming the torque per
    # thrust it saw, the simulated lever (1 within the noise of one block).
    rows = run_campaign(tmp_path, '--case', 'stationary', '--trials', '2', '--jobs', '1',
                        '--recognizer-param', 'torque_ratio_max=0.5')
    for row in rows:
        assert row['stop_reason'].startswith('clogging'), row['stop_reason']
        assert 0.8 < torque_ratio(row['stop_reason']) < 1.2, row['stop_reason']


def test_the_ros_pipeline_passes_it_the_torque(tmp_path):
    rows = run_campaign(tmp_path, '--engine', 'ros', '--case', 'stationary', '--trials', '1',
                        '--jobs', '1', '--recognizer-param', 'torque_ratio_max=0.5')
    assert len(rows) == 1 and rows[0]['error'] == '', rows
    assert rows[0]['stop_reason'].startswith('clogging'), rows[0]['stop_reason']
    assert 0.8 < torque_ratio(rows[0]['stop_reason']) < 1.2, rows[0]['stop_reason']
