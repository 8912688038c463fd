#!/usr/bin/env python3
"""Prints the published results tables from a `make run` output directory (default results/):
the paper's design (successes with Wilson intervals, Fisher against Table III: the README), the
field's metrics with the failure kinds at 12000 rpm (doc/results.md), and the fault campaign's
breakthroughs, so that the
published numbers are copied from the run, not typed. usage: results_tables.py [RESULTS_DIR]"""
import json
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))

from pd_campaign import design, report, stats  # noqa: E402


def pct(x):
    return '%.0f' % (100 * x)


def load(directory):
    with open(os.path.join(directory, 'summary.json')) as handle:
        return json.load(handle)


def design_table(summary):
    groups = {(g['case'], g['rpm']): g for g in summary['groups']}
    rpms = sorted({g['rpm'] for g in summary['groups']})
    print('| case | %s | paper, 12000 rpm | Fisher p vs paper |' % ' | '.join(
        '%.0f rpm' % r for r in rpms))
    print('|---|%s---|---|' % ('---|' * len(rpms)))
    for case in design.CASES:
        cells = []
        for rpm in rpms:
            g = groups.get((case, rpm))
            cells.append('-' if g is None else '%d/%d (%s-%s %%)' % (
                g['successes'], g['trials'], pct(g['wilson95'][0]), pct(g['wilson95'][1])))
        g = groups.get((case, 12000.0))
        paper = report.PAPER_TABLE_III[case]
        p = stats.fisher_exact(g['successes'], g['trials'], paper[0], paper[1]) if g else None
        print('| %s | %s | %d/%d | %s |' % (case, ' | '.join(cells), paper[0], paper[1],
                                            '-' if p is None else '%.2g' % p))


def metrics_table(summary):
    print('| case (12000 rpm) | correct stops | no penetration | stop to the layer\'s end [mm] '
          '| overshoot past the entry [mm] | detection latency [ms] | failure kinds |')
    print('|---|---|---|---|---|---|---|')
    for g in summary['groups']:
        if g['rpm'] != 12000.0:
            continue
        if 'failure_kinds' not in g:
            sys.exit('results_tables: %s has no failure kinds (a campaign from before them)'
                     % g['case'])
        q = g['quartiles_stop_residual_mm'], g['quartiles_overshoot_mm']
        lat = g['quartiles_detection_latency_ms']
        print('| %s | %d/%d | %d/%d | %s | %s | %s | %s |' % (
            g['case'], g['successes'], g['trials'], g['no_penetration'], g['trials'],
            '%.2f [%.2f, %.2f]' % (q[0][1], q[0][0], q[0][2]) if q[0] else '-',
            '%.2f [%.2f, %.2f]' % (q[1][1], q[1][0], q[1][2]) if q[1] else '-',
            '%.0f [%.0f, %.0f]' % (lat[1], lat[0], lat[2]) if lat else '-',
            ', '.join('%s %d' % kv for kv in g['failure_kinds'].items() if kv[0] != 'success')
            or '-'))


def fault_table(summary):
    print('| fault | trials | breakthroughs (Wilson 95 % upper) | failure kinds |')
    print('|---|---|---|---|')
    for g in summary.get('faults', []):
        print('| %s | %d | %d (%s %%) | %s |' % (
            g['fault'], g['trials'], g['breakthroughs'], pct(g['breakthrough_wilson95'][1]),
            ', '.join('%s %d' % kv for kv in g.get('failure_kinds', {}).items())))


def main(argv):
    results = argv[0] if argv else os.path.join(ROOT, 'results')
    paper = load(os.path.join(results, 'campaign'))
    design_table(paper)
    print()
    metrics_table(paper)
    faults = os.path.join(results, 'campaign_faults')
    if os.path.exists(os.path.join(faults, 'summary.json')):
        print()
        fault_table(load(faults))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
