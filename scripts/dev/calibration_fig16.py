#!/usr/bin/env python3
"""Fig. 16 error of peak-force campaigns (doc/simulator_physics.md, "Calibration of the DAQ rate
and the chisel-edge share"): for each campaign directory, the medians of the recognizer's F_out /
F_in per case at 12000 rpm, each moving case's difference to the stationary median in %, and the
sum of the squared errors of the six targets (stationary F_out, F_in in % of the paper's 3.16 /
2.88 N; the differences in percentage points of the paper's -38 / -49.7 % uncompensated and
-13 / -0.2 % compensated). Prints a markdown table, best row first.

usage: calibration_fig16.py LABEL=DIR [LABEL=DIR ...]"""
import json
import os
import sys

STATIONARY = (3.16, 2.88)  # N, Sec. V-D: 1.2 / 0.38 and 1.43 / 0.497
DIFFERENCES = {'uncompensated': (-38.0, -49.7), 'compensated': (-13.0, -0.2)}  # %


def row(label, directory):
    with open(os.path.join(directory, 'summary.json')) as handle:
        groups = {g['case']: g for g in json.load(handle)['groups'] if g['rpm'] == 12000.0}
    base = groups['stationary']
    out, inn = base['median_f_out_n'], base['median_f_in_n']
    error = ((out / STATIONARY[0] - 1) * 100) ** 2 + ((inn / STATIONARY[1] - 1) * 100) ** 2
    cells = ['%.2f / %.2f' % (out, inn)]
    for case, (paper_out, paper_in) in sorted(DIFFERENCES.items(), reverse=True):
        g = groups[case]
        d_out = (g['median_f_out_n'] / out - 1) * 100
        d_in = (g['median_f_in_n'] / inn - 1) * 100
        error += (d_out - paper_out) ** 2 + (d_in - paper_in) ** 2
        cells.append('%+.0f %% / %+.0f %%' % (d_out, d_in))
    trials = sum(g['trials'] for g in groups.values())
    return error, '| %s | %d | %s | %.0f |' % (label, trials, ' | '.join(cells), error)


def main(argv):
    if not argv or any('=' not in a for a in argv):
        sys.stderr.write(__doc__.split('\n\n')[-1] + '\n')
        return 2
    rows = sorted(row(*a.rsplit('=', 1)) for a in argv)
    print('| DAQ rate, chisel share | trials | stationary F_out / F_in [N] '
          '| uncompensated vs stationary | compensated vs stationary | Fig. 16 error |')
    print('|---|---|---|---|---|---|')
    print('| paper | | 3.16 / 2.88 | -38 % / -49.7 % | -13 % / -0.2 % | |')
    for _, text in rows:
        print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
