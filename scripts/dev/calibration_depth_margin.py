#!/usr/bin/python3
"""The depth limit's margins from the plan's and the limit's errors, on campaign outputs of
CALIBRATION seeds: the hole held at the limit goes past the inner cortex's far side when the plan's
far-side error (CT) plus the limit's estimate error (tracked and predicted bone, the sensed
contact, the arm's following) exceed the plan's margin plus the limit's online margin (its gain
times the spread of the tracker's recent residuals). The limit acts at a moment the drilling does
not choose and holds the tip until the stop's retreat, within 0.25 s: the estimate error that
counts is its maximum over a 0.25 s window of the drilling in contact (depth_window_errors_mm),
paired with the residual's smallest spread in that window (depth_window_spreads_mm). Every plan
error is paired with every window (the two are independent: one is the imaging step's, the other
the drilling's). For each spread gain g of a grid, the plan's margin m(g) is the smallest multiple
of 0.05 mm at or above the 99.9 % quantile of plan + (window error - g x spread); the gain chosen
is the one whose mean total margin over the windows, m(g) + g x spread, is smallest (the limit
then stands as deep as the errors allow, on average). Outcomes (successes, breakthroughs) are not
read. A markdown report on stdout.
Usage: calibration_depth_margin.py CAMPAIGN_DIR..."""
import csv
import math
import os
import sys

import numpy as np

QUANTILE = 0.999
STEP_MM = 0.05


GAINS = [0.25 * i for i in range(13)]  # 0 to 3


def rows(directories):
    """The trials.csv rows of the campaigns."""
    out = []
    for directory in directories:
        with open(os.path.join(directory, 'trials.csv')) as handle:
            out.extend(csv.DictReader(handle))
    return out


def numbers(text):
    """The finite numbers of a ';'-separated list (a float for a single value)."""
    values = []
    for item in (text or '').split(';'):
        try:
            value = float(item)
        except ValueError:
            continue
        if math.isfinite(value):
            values.append(value)
    return values


def column(table, name):
    """Every finite number of a column (';'-separated lists flattened)."""
    return np.array([v for row in table for v in numbers(row.get(name))])


def windows(table):
    """The windows' (error, spread) pairs [mm]; a trial without spreads (an output of a build
    before the online margin) counts a spread of 0 (no online margin covered it)."""
    errors, spreads = [], []
    for row in table:
        e = numbers(row.get('depth_window_errors_mm'))
        s = numbers(row.get('depth_window_spreads_mm'))
        if s and len(s) != len(e):
            sys.exit('calibration_depth_margin: trial %s has %d window errors but %d spreads'
                     % (row.get('trial_id'), len(e), len(s)))
        errors.extend(e)
        spreads.extend(s if s else [0.0] * len(e))
    return np.array(errors), np.array(spreads)


def margin(plan_errors, estimate_errors, quantile=QUANTILE):
    """The 0.05 mm step at or above the quantile of plan + estimate error over all pairs [mm]."""
    total = np.add.outer(plan_errors, estimate_errors).ravel()
    q = float(np.quantile(total, quantile))
    return math.ceil(q / STEP_MM - 1e-9) * STEP_MM, q


def choose(plan, errors, spreads, gains=GAINS, quantile=QUANTILE):
    """[(gain, plan margin, quantile, mean total margin)] for each gain, and the chosen entry
    (the smallest mean total margin; the smaller gain on a tie)."""
    table = []
    for gain in gains:
        chosen, q = margin(plan, errors - gain * spreads, quantile)
        table.append((gain, chosen, q, chosen + gain * float(np.mean(spreads))))
    best = min(table, key=lambda entry: (round(entry[3], 9), entry[0]))
    return table, best


def main(directories):
    table = rows(directories)
    plan = column(table, 'plan_far_side_error_mm')
    errors, spreads = windows(table)
    whole = column(table, 'depth_estimate_error_mm')
    if plan.size == 0 or errors.size == 0:
        sys.exit('calibration_depth_margin: no plan or estimate errors in %s' % directories)
    print('| quantity | samples | median | 99.9 % | max |')
    print('|---|---|---|---|---|')
    for name, values in (('plan far-side error [mm] (per trial)', plan),
                         ('estimate error, 0.25 s window maxima [mm]', errors),
                         ('residual spread, 0.25 s window minima [mm]', spreads),
                         ('estimate error, whole drilling maxima [mm] (per trial)', whole)):
        if values.size:
            print('| %s | %d | %.3f | %.3f | %.3f |' % (
                name, values.size, np.median(values), np.quantile(values, QUANTILE),
                values.max()))
    grid, best = choose(plan, errors, spreads)
    print('')
    print('| spread gain | plan margin [mm] | 99.9 % quantile [mm] | mean total margin [mm] |')
    print('|---|---|---|---|')
    for gain, chosen, q, total in grid:
        print('| %.2f | %.2f | %.3f | %.3f |' % (gain, chosen, q, total))
    print('')
    print('over %d pairs: spread gain %.2f, plan margin %.2f mm (99.9 %% quantile %.3f mm), '
          'mean total margin %.3f mm' % (plan.size * errors.size, best[0], best[1], best[2],
                                         best[3]))


if __name__ == '__main__':
    main(sys.argv[1:])
