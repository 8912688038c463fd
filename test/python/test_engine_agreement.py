"""The two engines run the same trial: the same seeds through the core engine and
through the ROS pipeline (the Simulator in lockstep with the planner, the recognizer and the
monitor; doc/running.md "Lockstep"), trial by trial: 2 per case of the paper's design at 12000 rpm and 2
of the virtual patient (the bone's true motion, lag, drift and small movements).

The pipeline's trial of a seed is the engine's, so the pass criterion is equality, not a
statistic: every pair has the same outcome and the same recognizer stop (raw sample and key
point), and the inner cortex left differs by no more than the ground truth's sampling can make
it (the ROS side reads it from simulator/ground_truth at 20 Hz; the engine at every step). A
trial where a lockstep participant missed a step is no longer the engine's: it fails the test by
name. The 30-per-case measurement is in `make run` (results/engine_agreement.md)."""
import os
import re
import subprocess

from pd_campaign import agreement, trials_csv

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# The ground truth's sampling: the residual at the ROS side's last 20 Hz sample after the stop.
RESIDUAL_TOLERANCE_MM = 0.01


def campaign(out, engine, port):
    rows = []
    for name, args in [('paper', ['--case', 'all', '--rpm', '12000', '--trials', '2']),
                       ('virtual_patient', ['--scenario', os.path.join(
                           ROOT, 'config', 'scenario_virtual_patient.yaml'), '--trials', '2'])]:
        result = subprocess.run(
            ['rosrun', 'pedicle_drilling', 'campaign'] + args +
            ['--seed', '31', '--jobs', '2', '--engine', engine, '--out', str(out / name),
             '--base-port', str(port)],
            capture_output=True, text=True, timeout=1800)
        assert result.returncode == 0, result.stderr[-3000:]
        for row in trials_csv.read_trials_csv(str(out / name / 'trials.csv')):
            row['trial_id'] = name + '/' + row['trial_id']
            rows.append(row)
    return rows


def raw_stop(row):
    """The recognizer's stop as its reason names it: (key point, raw sample), or None."""
    match = re.search(r'key point (\d+).*raw sample (\d+)', row.get('stop_reason') or '')
    return (int(match.group(1)), int(match.group(2))) if match else None


def test_ros_pipeline_runs_the_core_engines_trial(tmp_path):
    core = campaign(tmp_path / 'core', 'core', 14100)
    ros = campaign(tmp_path / 'ros', 'ros', 14300)
    pairs, figures = agreement.compare(ros, core)
    text = agreement.markdown(pairs, figures, 'ros', 'core')
    print(text)
    artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
    if artifacts:
        os.makedirs(artifacts, exist_ok=True)
        with open(os.path.join(artifacts, 'engine_agreement.md'), 'w') as handle:
            handle.write(text)
    assert figures['paired'] == 8
    for a, b in pairs:
        assert not a.get('error') and not b.get('error'), (a.get('error'), b.get('error'))
        assert not a.get('lockstep_timeouts'), \
            '%s: a lockstep participant missed %s steps' % (a['trial_id'], a['lockstep_timeouts'])
        # The monitor's inputs as received (its diagnostics at the trial's end): under the
        # lockstep every F/T and tracker sample arrives, in the step it was stamped in.
        assert a['force_samples_missing'] == 0 and a['tracker_samples_missing'] == 0, a
        assert 0.0 <= a['force_delay_max_ms'] <= 1.0, a['force_delay_max_ms']
        assert 0.0 <= a['tracker_delay_max_ms'] <= 1.0, a['tracker_delay_max_ms']
        assert b['force_delay_max_ms'] is None  # the core engine: its delays are configured
        assert agreement.outcome(a) == agreement.outcome(b), a['trial_id']
        assert raw_stop(a) == raw_stop(b), (a['trial_id'], a['stop_reason'], b['stop_reason'])
        assert abs(a['residual_mm'] - b['residual_mm']) <= RESIDUAL_TOLERANCE_MM, \
            (a['trial_id'], a['residual_mm'], b['residual_mm'])


# What depends on the wall clock, not on the trial.
WALL = {'wall_s'}


def test_waiting_at_every_step_changes_no_ros_trial(tmp_path):
    """Fewer synchronised steps (StepAck.next_step) are the same trials, and the ROS
    pipeline gives a seed the same trial in every run: the realistic bench (its delays, the
    tracker's 14 ms among them) through the ROS pipeline twice, once waiting for the
    participants at every step (--lockstep-every-step), with one worker instead of two, and
    not pinned to a CPU (--pin-workers off; the first run pins each worker). Every trials.csv
    column is equal to the last bit (the stop's key point and raw sample and its stamps too),
    but the wall time. Every node publishes in order (publishInOrder) and each trial's stamps
    start at its place in the design (ResetSimulation.time_zero); before either, two runs
    differed in the last bits and, through them, by micrometres after the stop."""
    runs = {}
    for name, extra in [('fewer', ['--jobs', '2']),
                        ('every', ['--lockstep-every-step', '--jobs', '1',
                                   '--pin-workers', 'off'])]:
        out = tmp_path / name
        result = subprocess.run(
            ['rosrun', 'pedicle_drilling', 'campaign', '--scenario',
             os.path.join(ROOT, 'config', 'scenario_realistic.yaml'), '--rpm', '12000',
             '--trials', '2', '--seed', '33', '--engine', 'ros', '--out', str(out),
             '--base-port', '14500'] + extra, capture_output=True, text=True, timeout=1800)
        assert result.returncode == 0, result.stderr[-3000:]
        rows = trials_csv.read_trials_csv(str(out / 'trials.csv'))
        assert all(not row.get('error') for row in rows), [row.get('error') for row in rows]
        runs[name] = {row['trial_id']: row for row in rows}
    fewer, every = runs['fewer'], runs['every']
    assert len(fewer) == 6 and set(fewer) == set(every)
    for trial_id, a in fewer.items():
        b = every[trial_id]
        for column, value in a.items():
            if column not in WALL:
                assert value == b[column], (trial_id, column, value, b[column])


def test_class_parameters_reach_the_ros_pipeline(tmp_path):
    """--recognizer-param / --compensator-param on --engine ros (before: core engine only): the
    worker writes them into the StateRecognizer's and the CompensationPlanner's parameter files
    (every class's as text in ~recognizer_params / ~compensator_params, the paper recognizer's
    too, read by its table) and the pipeline runs the core engine's trial of
    each seed with them. Each setting changes a stop here (core engine with and without it), so
    a setting lost on the way fails the test."""
    cases = [('paper', ['--case', 'stationary'], ['--recognizer-param', 'pre_average_s=0.12']),
             ('baselines', ['--case', 'compensated',
                            '--recognizer', 'pedicle_drilling/ForceDifferenceRecognizer',
                            '--compensator', 'pedicle_drilling/TrackedMarkerCompensator'],
              ['--recognizer-param', 'drop_confirm=4',
               '--compensator-param', 'extrapolate=true'])]
    for k, (name, design, settings) in enumerate(cases):
        rows = {}
        for label, engine, extra in (('default', 'core', []), ('core', 'core', settings),
                                     ('ros', 'ros', settings)):
            out = tmp_path / name / label
            result = subprocess.run(
                ['rosrun', 'pedicle_drilling', 'campaign'] + design +
                ['--rpm', '12000', '--trials', '3', '--seed', '35', '--jobs', '1',
                 '--engine', engine, '--out', str(out), '--base-port', str(14700 + 100 * k)] +
                extra, capture_output=True, text=True, timeout=1800)
            assert result.returncode == 0, result.stderr[-3000:]
            rows[label] = {row['trial_id']: row
                           for row in trials_csv.read_trials_csv(str(out / 'trials.csv'))}
            assert all(not row.get('error') for row in rows[label].values()), rows[label]
        assert len(rows['ros']) == 3 and set(rows['ros']) == set(rows['core'])
        assert any(raw_stop(rows['default'][t]) != raw_stop(rows['core'][t])
                   or rows['default'][t]['residual_mm'] != rows['core'][t]['residual_mm']
                   for t in rows['core']), (name, 'the settings changed nothing')
        for trial_id, a in rows['ros'].items():
            b = rows['core'][trial_id]
            assert not a.get('lockstep_timeouts'), (trial_id, a['lockstep_timeouts'])
            assert agreement.outcome(a) == agreement.outcome(b), (name, trial_id)
            assert raw_stop(a) == raw_stop(b), (name, trial_id, a['stop_reason'],
                                                b['stop_reason'])
            assert abs(a['residual_mm'] - b['residual_mm']) <= RESIDUAL_TOLERANCE_MM, \
                (name, trial_id, a['residual_mm'], b['residual_mm'])
