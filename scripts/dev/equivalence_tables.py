#!/usr/bin/python3
""""Compensated drilling is as good as stationary drilling", tested as it is stated, from a
`make run` output directory (default results/) or the archive (doc/results/, make_docs.py):
a markdown table on stdout.

The claim is non-inferiority, not the absence of a significant difference: on the same specimens
and patients (trials paired by speed and seed: the cases share their seeds), the compensated
success rate is lower than the stationary one by less than MARGIN_POINTS, at one-sided level
ALPHA, for every bench and speed at once (Holm's correction over the whole table). The test
inverts Newcombe's paired interval (pd_campaign.compare.noninferiority_p). The margin is one
trial in twenty: the resolution of the paper's Table III (20 trials per case), below which the
paper's own claim could not tell two systems apart. The power column is the chance to show
non-inferiority when the two cases truly succeed equally often: the share of POWER_DRAWS
simulated tables of the same number of pairs, drawn with the observed share of pairs where both
succeed and the observed share of discordant pairs (at least one pair) split evenly, whose
Newcombe lower bound at the Bonferroni level ALPHA / (tests in the table) lies above the margin
(a fixed random seed: the same table every time).
usage: equivalence_tables.py [RESULTS_DIR]"""
import csv
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))

from pd_campaign import compare, stats, trials_csv  # noqa: E402

MARGIN_POINTS = 5.0
ALPHA = 0.025  # one-sided
POWER_DRAWS = 2000
# (label, campaign folder): the benches whose design runs both cases on the same seeds.
BENCHES = (('paper\'s bench', 'campaign'), ('realistic bench', 'campaign_realistic'),
           ('population bench', 'campaign_population'))


def rows(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return [trials_csv.normalise_row(r) for r in csv.DictReader(handle)]


def tests(out):
    """One entry per bench and speed: the paired counts, the difference's interval, the
    non-inferiority p and its Holm-adjusted value."""
    entries = []
    for label, folder in BENCHES:
        data = rows(os.path.join(out, folder))
        for rpm in sorted({r['rpm'] for r in data}):
            compensated = [r for r in data if r['case'] == 'compensated' and r['rpm'] == rpm]
            stationary = [r for r in data if r['case'] == 'stationary' and r['rpm'] == rpm]
            n, both, only_c, only_s, neither = stats.paired_counts(
                compensated, stationary, lambda r: (r['rpm'], r['seed']))
            low, high = compare.paired_difference_interval(both, only_c, only_s, neither)
            entries.append({
                'bench': label, 'rpm': rpm, 'n': n, 'compensated': both + only_c,
                'stationary': both + only_s, 'only_c': only_c, 'only_s': only_s,
                'interval': (low, high),
                'p': compare.noninferiority_p(both, only_c, only_s, neither,
                                              MARGIN_POINTS / 100.0)})
    for entry, adjusted in zip(entries, stats.holm([e['p'] for e in entries])):
        entry['holm'] = adjusted
    return entries


def power(entry, tests_in_family):
    """The simulated power at a true difference of 0 (see the module's text)."""
    n = entry['n']
    discordant = max(entry['only_c'] + entry['only_s'], 1)
    both = min(entry['compensated'] - entry['only_c'], n - discordant)
    shares = np.array([both, discordant / 2.0, discordant / 2.0, n - both - discordant]) / n
    z = stats.normal_quantile(1.0 - ALPHA / tests_in_family)
    tables = np.random.default_rng(1).multinomial(n, shares, size=POWER_DRAWS)
    shown = sum(1 for t in tables if compare.paired_difference_interval(
        int(t[0]), int(t[1]), int(t[2]), int(t[3]), z)[0] > -MARGIN_POINTS / 100.0)
    return shown / float(POWER_DRAWS)


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(ROOT, 'results')
    entries = tests(out)
    shown = [e for e in entries if e['holm'] < ALPHA]
    print('| bench | rpm | pairs | successes compensated / stationary | only compensated / only '
          'stationary | difference [points, 95 %%] | non-inferiority p (margin %.0f points) | '
          'Holm-adjusted p | power | shown |' % MARGIN_POINTS)
    print('|---|---|---|---|---|---|---|---|---|---|')
    for e in entries:
        print('| %s | %.0f | %d | %d / %d | %d / %d | %+.1f [%+.1f, %+.1f] | %.2g | %.2g | %.2f | '
              '%s |' % (
                  e['bench'], e['rpm'], e['n'], e['compensated'], e['stationary'], e['only_c'],
                  e['only_s'], 100.0 * (e['compensated'] - e['stationary']) / e['n'],
                  100.0 * e['interval'][0], 100.0 * e['interval'][1], e['p'], e['holm'],
                  power(e, len(entries)), 'yes' if e['holm'] < ALPHA else '**no**'))
    print()
    print('Non-inferiority of compensated to stationary drilling (margin %.0f points, one-sided '
          '%.3g, Holm over %d tests) is shown on %d of %d bench and speed cells%s.' % (
              MARGIN_POINTS, ALPHA, len(entries), len(shown), len(entries),
              '' if len(shown) == len(entries) else '; not shown: ' + ', '.join(
                  '%s at %.0f rpm' % (e['bench'], e['rpm']) for e in entries
                  if e['holm'] >= ALPHA)))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
