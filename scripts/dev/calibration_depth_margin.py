#!/usr/bin/python3
"""The depth limit's margin from the plan's error, on campaign outputs of CALIBRATION seeds: the
hole held at the limit goes past the inner cortex's far side when the plan's far-side error (CT)
plus the limit's estimate error (tracked and predicted bone, the sensed contact, the arm's
following) exceed the margin. The limit acts at a moment the drilling does not choose and holds
the tip until the stop's retreat, within 0.25 s: the estimate error that counts is its maximum over
a 0.25 s window of the drilling in contact (depth_window_errors_mm, every window of every trial).
Every plan error is paired with every window (the two are independent: one is the imaging step's,
the other the drilling's), and the margin is the smallest multiple of 0.05 mm at or above the
99.9 % quantile of their sum. Outcomes (successes, breakthroughs) are not read. The trials' largest
error over the whole drilling is shown beside it. A markdown report on stdout.
Usage: calibration_depth_margin.py CAMPAIGN_DIR..."""
import csv
import math
import os
import sys

import numpy as np

QUANTILE = 0.999
STEP_MM = 0.05


def column(directories, name):
    """Every finite number of a column of the campaigns' trials.csv (';'-separated lists
    flattened)."""
    values = []
    for directory in directories:
        with open(os.path.join(directory, 'trials.csv')) as handle:
            for row in csv.DictReader(handle):
                for text in (row.get(name) or '').split(';'):
                    try:
                        value = float(text)
                    except ValueError:
                        continue
                    if math.isfinite(value):
                        values.append(value)
    return np.array(values)


def margin(plan_errors, estimate_errors, quantile=QUANTILE):
    """The 0.05 mm step at or above the quantile of plan + estimate error over all pairs [mm]."""
    total = np.add.outer(plan_errors, estimate_errors).ravel()
    q = float(np.quantile(total, quantile))
    return math.ceil(q / STEP_MM - 1e-9) * STEP_MM, q


def main(directories):
    plan = column(directories, 'plan_far_side_error_mm')
    windows = column(directories, 'depth_window_errors_mm')
    whole = column(directories, 'depth_estimate_error_mm')
    if plan.size == 0 or windows.size == 0:
        sys.exit('calibration_depth_margin: no plan or estimate errors in %s' % directories)
    chosen, q = margin(plan, windows)
    print('| quantity | samples | median | 99.9 % | max |')
    print('|---|---|---|---|---|')
    for name, values in (('plan far-side error [mm] (per trial)', plan),
                         ('estimate error, 0.25 s window maxima [mm]', windows),
                         ('estimate error, whole drilling maxima [mm] (per trial)', whole)):
        if values.size:
            print('| %s | %d | %.3f | %.3f | %.3f |' % (
                name, values.size, np.median(values), np.quantile(values, QUANTILE),
                values.max()))
    print('')
    print('99.9 %% quantile of plan error + window error over %d pairs: %.3f mm; margin (next '
          '%.2f mm): %.2f mm' % (plan.size * windows.size, q, STEP_MM, chosen))


if __name__ == '__main__':
    main(sys.argv[1:])
