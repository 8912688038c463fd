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


def test_the_report_reads_the_columns_of_campaign_outputs(tmp_path, capsys):
    (tmp_path / 'trials.csv').write_text(
        'trial_id,plan_far_side_error_mm,depth_estimate_error_mm,depth_window_errors_mm\n'
        'a,0.1,-0.05,-0.1;-0.05\nb,-0.1,,\nc,0.2,0.01,0.01\n')
    load().main([str(tmp_path)])
    out = capsys.readouterr().out
    assert '| plan far-side error [mm] (per trial) | 3 |' in out
    assert '| estimate error, 0.25 s window maxima [mm] | 3 |' in out
    assert '| estimate error, whole drilling maxima [mm] (per trial) | 2 |' in out
    assert 'over 9 pairs' in out
