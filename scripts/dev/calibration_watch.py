#!/usr/bin/python3
"""How close the trials of campaign outputs come to the planner's controller-watch tolerances:
per case and fault, the largest and the 99th percentile of watch_desired_ratio and
watch_following_ratio (|desired - commanded| and |error| over the trial, as fractions of their
tolerances: 1 trips the watch), and how many trials the watch stopped. A markdown table on
stdout. Usage: calibration_watch.py CAMPAIGN_DIR..."""
import csv
import os
import sys

import numpy as np


def rows(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return list(csv.DictReader(handle))


def number(value):
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def main(directories):
    print('| campaign | case | fault | trials | desired ratio: max / 99 % | following ratio: '
          'max / 99 % | stopped by the watch |')
    print('|---|---|---|---|---|---|---|')
    for directory in directories:
        groups = {}
        for row in rows(directory):
            groups.setdefault((row['case'], row.get('fault') or 'none'), []).append(row)
        for (case, fault), members in sorted(groups.items()):
            desired = [number(r.get('watch_desired_ratio')) for r in members]
            following = [number(r.get('watch_following_ratio')) for r in members]
            desired = np.array([d for d in desired if d is not None])
            following = np.array([f for f in following if f is not None])
            watch_stops = sum(1 for r in members if 'controller_watch' in (
                r.get('stop_reason') or '') or 'refused or arrived late' in (
                r.get('stop_reason') or '') or 'does not follow' in (r.get('stop_reason') or ''))

            def cell(values):
                if values.size == 0:
                    return '-'
                return '%.3g / %.3g' % (values.max(), np.percentile(values, 99))
            print('| %s | %s | %s | %d | %s | %s | %d |' % (
                os.path.basename(directory.rstrip('/')), case, fault, len(members), cell(desired),
                cell(following), watch_stops))


if __name__ == '__main__':
    main(sys.argv[1:])
