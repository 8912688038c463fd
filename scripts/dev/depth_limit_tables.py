#!/usr/bin/python3
"""The plan's depth limit in a `make run` output directory (default results/): markdown tables
on stdout (make run's depth_limit.md). doc/results.md's "The plan's depth limit" has the same
tables as generated blocks of scripts/dev/make_docs.py, from the archive in doc/results/, whose
folders are laid out as a make run output's.
  1. the paper's design at 12000 rpm on the same seeds without the plan (campaign/, the paper's
     system as published) and with it (campaign_depth_limit/): the paper's successes (the
     recognizer's stop in the inner layer), the drill stopped in the inner layer by either line
     (the recognizer or the limit; residual in (0, 2 mm], no breakthrough), the first stops the
     limit made, the breakthroughs and how many of them the limit prevented;
  2. every shipped compensator and recognizer class through every fault with the limit
     (depth_limit_faults/<compensator>_<recognizer>/): breakthroughs per fault and class;
  3. the fault-free and x1.3 amplitude trials per class (depth_limit_amplitude/...): breakthroughs
     and the first stop's line; and the tracked-marker compensator's on the same seeds without
     the plan (depth_limit_amplitude_without_plan/), the control.
usage: depth_limit_tables.py [RESULTS_DIR]"""
import csv
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))

from pd_campaign import aggregate, trials_csv  # noqa: E402


def rows(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return [trials_csv.normalise_row(r) for r in csv.DictReader(handle) if not r.get('error')]


def in_layer(row):
    """Stopped in the inner layer by the recognizer or the depth limit (residual (0, 2 mm])."""
    line = aggregate.stop_line(row)
    depth, start, residual = row.get('max_depth_mm'), row.get('inner_start_mm'), \
        row.get('residual_mm')
    return (line in ('recognizer', 'depth limit') and not row['breakthrough']
            and depth is not None and start is not None and depth > start
            and residual is not None and 0.0 < residual <= 2.0)


def design_table(out):
    without = [r for r in rows(os.path.join(out, 'campaign')) if r['rpm'] == 12000.0]
    with_limit = rows(os.path.join(out, 'campaign_depth_limit'))
    by_seed = {(r['case'], r['seed']): r for r in without}
    print('| case (12000 rpm) | trials | paper\'s successes without / with the plan | in the inner '
          'layer (recognizer or limit) without / with | first stop by the limit | '
          'breakthroughs without / with | prevented by the limit |')
    print('|---|---|---|---|---|---|---|')
    for case in ('stationary', 'uncompensated', 'compensated'):
        new = [r for r in with_limit if r['case'] == case]
        old = [by_seed[(case, r['seed'])] for r in new if (case, r['seed']) in by_seed]
        prevented = sum(1 for r in new if (case, r['seed']) in by_seed
                        and by_seed[(case, r['seed'])]['breakthrough'] and not r['breakthrough'])
        print('| %s | %d | %d / %d | %d / %d | %d | %d / %d | %d |' % (
            case, len(new), sum(r['success'] for r in old), sum(r['success'] for r in new),
            sum(in_layer(r) for r in old), sum(in_layer(r) for r in new),
            sum(aggregate.stop_line(r) == 'depth limit' for r in new),
            sum(r['breakthrough'] for r in old), sum(r['breakthrough'] for r in new), prevented))


def classes(out, kind):
    base = os.path.join(out, 'depth_limit_' + kind)
    return sorted(d for d in os.listdir(base) if os.path.isdir(os.path.join(base, d)))


def faults_table(out):
    names = classes(out, 'faults')
    data = {name: rows(os.path.join(out, 'depth_limit_faults', name)) for name in names}
    faults = []
    for name in names:
        for r in data[name]:
            if r['fault'] not in faults:
                faults.append(r['fault'])
    print('| fault | ' + ' | '.join(n.replace('_', ' + ') for n in names) + ' |')
    print('|---|' + '---|' * len(names))
    for fault in faults:
        cells = []
        for name in names:
            group = [r for r in data[name] if r['fault'] == fault]
            cells.append('%d/%d' % (sum(r['breakthrough'] for r in group), len(group)))
        print('| %s | %s |' % (fault, ' | '.join(cells)))


def amplitude_table(out):
    print('| compensator + recognizer | fault | trials | breakthroughs | in the inner layer | '
          'first stop: recognizer / limit / plausibility / monitor / other |')
    print('|---|---|---|---|---|---|')
    for name in classes(out, 'amplitude'):
        data = rows(os.path.join(out, 'depth_limit_amplitude', name))
        for fault in ('none', 'breathing_amplitude'):
            group = [r for r in data if r['fault'] == fault]
            lines = [aggregate.stop_line(r) for r in group]
            print('| %s | %s | %d | %d | %d | %s |' % (
                name.replace('_', ' + '), fault, len(group), sum(r['breakthrough'] for r in group),
                sum(in_layer(r) for r in group), ' / '.join(
                    str(lines.count(line)) for line in ('recognizer', 'depth limit',
                                                        'plausibility bound', 'safety monitor',
                                                        'other'))))


def control_table(out):
    """The tracked-marker compensator's fault-free and amplitude trials without the plan."""
    directory = os.path.join(out, 'depth_limit_amplitude_without_plan')
    if not os.path.isdir(directory):
        return
    data = rows(directory)
    print('| fault | trials | breakthroughs |')
    print('|---|---|---|')
    for fault in ('none', 'breathing_amplitude'):
        group = [r for r in data if r['fault'] == fault]
        print('| %s | %d | %d |' % (fault, len(group), sum(r['breakthrough'] for r in group)))


def main(out):
    print('## The paper\'s design with and without the plan\n')
    design_table(out)
    print('\n## Breakthroughs per fault and class, with the plan\n')
    faults_table(out)
    print('\n## Fault-free and x1.3 amplitude, with the plan\n')
    amplitude_table(out)
    if os.path.isdir(os.path.join(out, 'depth_limit_amplitude_without_plan')):
        print('\n## The same seeds without the plan (TrackedMarkerCompensator + PaperRecognizer)\n')
        control_table(out)


if __name__ == '__main__':
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, 'results'))
