#!/usr/bin/python3
"""The population bench in a `make run` output directory (default results/): markdown tables on
stdout (population.md); doc/results.md's and doc/identification.md's generated blocks come from the
same functions, on the archived data (make_docs.py).
  1. the paper's design on the population bench (campaign_population/): successes per case and
     speed with the paper's Table III beside them, and the failure kinds at 12000 rpm (the same
     tables as the paper's bench, results_tables.py);
  2. why trials ended at 12000 rpm (failure kinds) and the tip-bone tracking RMS's quartiles;
  3. the models the planner drilled with, identified per trial from each patient's own
     recording, against Table II's five volunteers (campaign/table2.csv): the AP slope of the
     linear model, its R^2, and the bone's slope on the table over the identified one.
usage: population_tables.py [RESULTS_DIR]"""
import csv
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))
sys.path.insert(0, HERE)

from pd_campaign import aggregate, trials_csv  # noqa: E402
import results_tables  # noqa: E402


def rows(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return [trials_csv.normalise_row(r) for r in csv.DictReader(handle) if not r.get('error')]


def quartiles(values):
    values = sorted(v for v in values if v is not None)
    if not values:
        return '-'
    q = aggregate.quartile_values(values)
    return '%.3g [%.3g, %.3g]' % (q[1], q[0], q[2])


def kinds_table(summary, trials):
    """Why trials ended at 12000 rpm (the failure kinds) and the tracking RMS's spread."""
    print('| case (12000 rpm) | failure kinds | tracking RMS, median [quartiles] [mm] |')
    print('|---|---|---|')
    for g in summary['groups']:
        if g['rpm'] != 12000.0:
            continue
        kinds = sorted(((k, v) for k, v in g['failure_kinds'].items() if k != 'success'),
                       key=lambda kv: (-kv[1], kv[0]))
        group = [r for r in trials if r['case'] == g['case'] and r['rpm'] == 12000.0]
        print('| %s | %s | %s |' % (g['case'], ', '.join('%s %d' % kv for kv in kinds) or '-',
                                    quartiles(r.get('tracking_rms_mm') for r in group)))


BENCHES = (('the paper\'s', 'campaign'), ('realistic', 'campaign_realistic'),
           ('population', 'campaign_population'))


def benches_table(results):
    """The three benches on the same evaluation seeds: successes per case at 12000 rpm, the
    compensated case at the higher speeds, its H1 stops and breakthroughs (by the trials'
    breakthrough flag) and its median tip-bone tracking RMS at 12000 rpm."""
    print('| bench | stationary | uncompensated | compensated | compensated, 16000 / 20000 rpm '
          '| compensated: H1 stops, breakthroughs | compensated tracking RMS, median [mm] |')
    print('|---|---|---|---|---|---|---|')
    for name, folder in BENCHES:
        groups = {(g['case'], g['rpm']): g
                  for g in results_tables.load(os.path.join(results, folder))['groups']}
        trials = [r for r in rows(os.path.join(results, folder))
                  if r['case'] == 'compensated' and r['rpm'] == 12000.0]
        compensated = groups[('compensated', 12000.0)]
        print('| %s | %s | %s | %s | %s | %d, %d | %.3f |' % (
            name, *('%d/%d' % (groups[(c, 12000.0)]['successes'], groups[(c, 12000.0)]['trials'])
                    for c in ('stationary', 'uncompensated', 'compensated')),
            ', '.join('%d/%d' % (groups[('compensated', rpm)]['successes'],
                                 groups[('compensated', rpm)]['trials'])
                      for rpm in (16000.0, 20000.0)),
            compensated['failure_kinds'].get('safety_h1', 0),
            sum(1 for r in trials if r['breakthrough']),
            compensated['median_tracking_rms_mm']))


def number(text):
    return float(text) if text not in (None, '') else None


def identification_table(trials, table2_csv):
    """The population's identified AP models (one per trial seed of the moving cases) beside
    Table II's volunteers (linear model, AP)."""
    seen = {}
    for r in trials:
        slope = number(r.get('model_ap_slope_mm_per_ml'))
        if r['case'] != 'stationary' and slope is not None and r['seed'] not in seen:
            seen[r['seed']] = (slope, r.get('identification_r2_ap'),
                               number(r.get('patient_ap_slope_mm_per_ml')))
    patients = list(seen.values())
    print('| models | patients | AP slope at 500 ml [mm], median [quartiles] (range) | R^2 AP, '
          'median [quartiles] (min) | bone on the table / model, median [quartiles] |')
    print('|---|---|---|---|---|')
    slopes = [500.0 * s for s, _, _ in patients]
    r2 = [q for _, q, _ in patients if q is not None]
    ratio = [b / s for s, _, b in patients if b is not None and s]
    print('| population bench, identified per patient | %d | %s (%.2f-%.2f) | %s (%.3f) | %s |' % (
        len(patients), quartiles(slopes), min(slopes), max(slopes), quartiles(r2), min(r2),
        quartiles(ratio)))
    with open(table2_csv) as handle:
        volunteers = [r for r in csv.DictReader(handle)
                      if r['model'] == 'linear' and r['axis'] == 'ap']
    slopes = [500.0 * float(r['q1']) for r in volunteers]
    r2 = [float(r['r2']) for r in volunteers]
    print('| Table II, the five virtual volunteers | %d | %s (%.2f-%.2f) | %s (%.3f) | 1 (the '
          'bone is the volunteer) |' % (len(volunteers), quartiles(slopes), min(slopes),
                                       max(slopes), quartiles(r2), min(r2)))


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(ROOT, 'results')
    population = os.path.join(out, 'campaign_population')
    summary = results_tables.load(population)
    results_tables.design_table(summary)
    print()
    results_tables.metrics_table(summary)
    print()
    trials = rows(population)
    kinds_table(summary, trials)
    print()
    identification_table(trials, os.path.join(out, 'campaign', 'table2.csv'))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
