"""scripts/dev/calibration_depth_margin.py: the depth margin from the plan's and the estimate's
errors, over every pair, rounded up to 0.05 mm."""
import importlib.util
import os

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load():
    spec = importlib.util.spec_from_file_location(
        'calibration_depth_margin',
        os.path.join(ROOT, 'scripts', 'dev', 'calibration_depth_margin.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_margin_covers_the_quantile_of_every_pair_and_rounds_up():
    module = load()
    plan = np.array([-0.2, 0.0, 0.3])
    estimate = np.array([-0.1, 0.05])
    chosen, q = module.margin(plan, estimate, quantile=1.0)
    assert abs(q - 0.35) < 1e-12  # the largest pair: 0.3 + 0.05
    assert abs(chosen - 0.35) < 1e-12
    chosen, _ = module.margin(np.array([0.31]), np.array([0.0]), quantile=1.0)
    assert abs(chosen - 0.35) < 1e-12


def test_a_spread_that_explains_the_error_earns_a_gain_and_a_smaller_margin():
    module = load()
    plan = np.array([0.0, 0.1])
    # Calm windows (small error, no spread) and disturbed ones whose error is twice their spread.
    errors = np.array([0.1] * 8 + [1.0, 0.8])
    spreads = np.array([0.0] * 8 + [0.5, 0.4])
    grid, best = module.choose(plan, errors, spreads, quantile=1.0)
    gain, chosen, q, total = best
    assert gain == 2.0  # the smallest gain whose windows all fall to the calm windows' error
    assert abs(q - 0.2) < 1e-9 and abs(chosen - 0.2) < 1e-9
    assert abs(total - (0.2 + 2.0 * 0.09)) < 1e-9
    no_gain = grid[0]
    assert no_gain[0] == 0.0 and abs(no_gain[1] - 1.1) < 1e-9  # 0.1 + 1.0 without the spread


def test_the_report_reads_the_columns_of_campaign_outputs(tmp_path, capsys):
    (tmp_path / 'trials.csv').write_text(
        'trial_id,plan_far_side_error_mm,depth_estimate_error_mm,depth_window_errors_mm,'
        'depth_window_spreads_mm\n'
        'a,0.1,-0.05,-0.1;-0.05,0.02;0.03\nb,-0.1,,,\nc,0.2,0.01,0.01,0.0\n')
    load().main([str(tmp_path)])
    out = capsys.readouterr().out
    assert '| plan far-side error [mm] (per trial) | 3 |' in out
    assert '| estimate error, 0.25 s window maxima [mm] | 3 |' in out
    assert '| residual spread, 0.25 s window minima [mm] | 3 |' in out
    assert '| estimate error, whole drilling maxima [mm] (per trial) | 2 |' in out
    assert 'over 9 pairs' in out


def test_errors_and_spreads_of_unequal_length_are_refused(tmp_path):
    (tmp_path / 'trials.csv').write_text(
        'trial_id,plan_far_side_error_mm,depth_window_errors_mm,depth_window_spreads_mm\n'
        'a,0.1,0.1;0.2,0.05\n')
    try:
        load().main([str(tmp_path)])
    except SystemExit as stop:
        assert 'trial a has 2 window errors but 1 spreads' in str(stop)
    else:
        raise AssertionError('unequal lists were accepted')
