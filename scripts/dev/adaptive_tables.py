#!/usr/bin/python3
"""The AdaptiveModelCompensator against the paper's compensator in a `make run` output directory
(default results/): markdown tables on stdout, the generated block of doc/results.md's "A
compensator that corrects a wrong model" (make_docs.py), from the run, not typed. Every comparison is paired, seed for seed, at
12000 rpm, compensated:
  1. the breathing_amplitude fault (the bone moves 1.3 x the model from a moment drawn per seed):
     adaptive_amplitude/ (AdaptiveModelCompensator) against adaptive_amplitude_paper/;
  2. no fault, the paper's bench: campaign_adaptive/ against campaign/; the realistic bench:
     campaign_realistic_adaptive/ against campaign_realistic/; the population bench:
     campaign_population_adaptive/ against campaign_population/. "Not worse" is a non-inferiority
     claim: the lower end of the 95 % interval of the paired difference in success rate must lie
     above -NONINFERIORITY_MARGIN;
  3. the ROS pipeline beside the core engine, trial by trial (campaign_adaptive_ros/ against the
     first trials of campaign_adaptive/).
usage: adaptive_tables.py [RESULTS_DIR]"""
import csv
import math
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))

from pd_campaign import agreement, stats, trials_csv  # noqa: E402

# Non-inferiority margin on the success rate (percentage points): a compensator "not worse" than
# the paper's loses at most this many successes in a hundred, at 95 % confidence.
NONINFERIORITY_MARGIN = 5.0


def rows(directory):
    with open(os.path.join(directory, 'trials.csv')) as handle:
        return [trials_csv.normalise_row(r) for r in csv.DictReader(handle)]


def compensated(directory):
    return [r for r in rows(directory) if r['case'] == 'compensated' and r['rpm'] == 12000.0]


def paired_difference(n, only_a, only_b):
    """The paired difference of success rates, A - B [percentage points], and its 95 % Wald
    interval for paired proportions (Agresti, Categorical Data Analysis, 10.1)."""
    d = (only_a - only_b) / n
    se = math.sqrt(max(0.0, (only_a + only_b) / n - d * d) / n)
    return 100.0 * d, 100.0 * (d - 1.959963984540054 * se), 100.0 * (d + 1.959963984540054 * se)


def median_tracking(group):
    values = [r['tracking_rms_mm'] for r in group if r.get('tracking_rms_mm') is not None]
    return stats.median(values) if values else None


def kinds(group):
    counts = {}
    for r in group:
        kind = r.get('failure_kind') or 'unknown'
        counts[kind] = counts.get(kind, 0) + 1
    return ', '.join('%s %d' % (k, v) for k, v in sorted(counts.items(), key=lambda x: -x[1]))


def paired_rows(adaptive_dir, paper_dir):
    """The compensated 12000 rpm trials of both campaigns on the seeds they share."""
    adaptive, paper = compensated(adaptive_dir), compensated(paper_dir)
    seeds = {r['seed'] for r in adaptive} & {r['seed'] for r in paper}
    return ([r for r in adaptive if r['seed'] in seeds], [r for r in paper if r['seed'] in seeds])


def comparison(label, adaptive, paper):
    n, _, only_a, only_b, _ = stats.paired_counts(adaptive, paper, lambda r: r['seed'])
    d, low, high = paired_difference(n, only_a, only_b)
    p = stats.mcnemar_exact(only_a, only_b)
    verdict = 'not worse' if low > -NONINFERIORITY_MARGIN else 'not shown not worse'
    return '| %s | %d | %d / %d | %d / %d | %d / %d | %.3f / %.3f | %+.1f [%+.1f, %+.1f] | %.3g | %s |' % (
        label, n, sum(r['success'] for r in adaptive), sum(r['success'] for r in paper),
        sum(r.get('failure_kind') == 'safety_h1' for r in adaptive),
        sum(r.get('failure_kind') == 'safety_h1' for r in paper),
        sum(bool(r['breakthrough']) for r in adaptive), sum(bool(r['breakthrough']) for r in paper),
        median_tracking(adaptive) or float('nan'), median_tracking(paper) or float('nan'),
        d, low, high, p, verdict)


BENCHES = (
    ('x1.3 amplitude fault, paper\'s bench', 'adaptive_amplitude', 'adaptive_amplitude_paper'),
    ('no fault, paper\'s bench', 'campaign_adaptive', 'campaign'),
    ('no fault, realistic bench', 'campaign_realistic_adaptive', 'campaign_realistic'),
    ('no fault, population bench', 'campaign_population_adaptive', 'campaign_population'),
)


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(ROOT, 'results')
    print('| bench (12000 rpm, compensated) | paired trials | successes adaptive / paper | '
          'H1 stops adaptive / paper | breakthroughs adaptive / paper | median tracking RMS '
          'adaptive / paper [mm] | success difference [points, 95 %%] | McNemar p | '
          'non-inferiority (margin %.0f points) |' % NONINFERIORITY_MARGIN)
    print('|---|---|---|---|---|---|---|---|---|')
    groups = [(label, paired_rows(os.path.join(out, a), os.path.join(out, b)))
              for label, a, b in BENCHES]
    for label, (adaptive, paper) in groups:
        print(comparison(label, adaptive, paper))
    print()
    print('| bench | how the trials ended, adaptive | how the trials ended, paper\'s compensator |')
    print('|---|---|---|')
    for label, (adaptive, paper) in groups:
        print('| %s | %s | %s |' % (label, kinds(adaptive), kinds(paper)))
    print()
    ros = rows(os.path.join(out, 'campaign_adaptive_ros'))
    core = rows(os.path.join(out, 'campaign_adaptive'))
    _, figures = agreement.compare(ros, core)
    print('The ROS pipeline beside the core engine (AdaptiveModelCompensator, paper\'s bench, '
          '12000 rpm, compensated): the same outcome in %d of %d paired trials, the same success '
          'in %d.' % (figures['same_outcome'], figures['paired'], figures['same_success']))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
