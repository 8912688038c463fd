"""Paired comparison of two campaigns on the same design: the same specimens and patients (trials
paired by case, rpm and seed), drilled with two recognizers, compensators or compensation
profiles. Per case and speed: the success of each, both / only A / only B / neither, McNemar's
exact p, the difference in success rate A - B with its paired 95 % interval (Newcombe), median
residuals; written as Markdown, JSON and a figure.

    rosrun pedicle_drilling campaign_compare DIR_A DIR_B [--out DIR] [--label-a A --label-b B]

Two campaigns whose designs differ in anything but the algorithm compared (scenario keys
`compensation_profile`, `recognizer`, `compensator`, their `*_params`, and the engine) are
refused: their trials are not the same specimens under the same conditions. With `--benches`
the bench may differ too (`bone_motion`, `model`, `simulator`, `simulator_params`,
`engine_delays`): the same specimens and patients on two benches, e.g. the paper's and the
realistic one (config/scenario_realistic.yaml).
"""
import json
import math
import os
import sys

from . import design, stats, tools, trials_csv
from .atomic import atomic_savefig, atomic_write

# Design keys (design.json "meta") that name the algorithm under comparison: they may differ.
COMPARED_KEYS = ('compensation_profile', 'recognizer', 'compensator', 'recognizer_params',
                 'compensator_params', 'engine')


# Design keys that make the bench: they may differ with --benches (the trials' specimens and
# patients, drawn from the seeds, stay the same).
BENCH_KEYS = ('bone_motion', 'model', 'simulator', 'simulator_params', 'engine_delays')


class DesignMismatch(ValueError):
    """The two campaigns are not the same design."""


def paired_difference_interval(both, only_a, only_b, neither, z=1.959963984540054):
    """95 % interval of p_A - p_B for paired binary outcomes: Newcombe's method 10 (hybrid score,
    no continuity correction), from the Wilson intervals of both proportions and the phi
    correlation of the 2 x 2 table.

    Newcombe, R. G. (1998) Improved confidence intervals for the difference between binomial
    proportions based on paired data. Stat Med 17:2635-2650."""
    n = both + only_a + only_b + neither
    if n == 0:
        return (-1.0, 1.0)
    p_a = (both + only_a) / n
    p_b = (both + only_b) / n
    l_a, u_a = stats.wilson_interval(both + only_a, n, z)
    l_b, u_b = stats.wilson_interval(both + only_b, n, z)
    denominator = ((both + only_a) * (only_b + neither) * (both + only_b) * (only_a + neither))
    phi = (both * neither - only_a * only_b) / math.sqrt(denominator) if denominator > 0 else 0.0
    delta = p_a - p_b
    low = delta - math.sqrt(max(0.0, (p_a - l_a) ** 2 - 2.0 * phi * (p_a - l_a) * (u_b - p_b)
                                + (u_b - p_b) ** 2))
    high = delta + math.sqrt(max(0.0, (u_a - p_a) ** 2 - 2.0 * phi * (u_a - p_a) * (p_b - l_b)
                                 + (p_b - l_b) ** 2))
    return (max(-1.0, low), min(1.0, high))


def noninferiority_p(both, only_a, only_b, neither, margin):
    """One-sided p of "A is not worse than B by `margin` or more" (H0: p_A - p_B <= -margin) for
    paired binary outcomes, by inverting Newcombe's interval (paired_difference_interval): the
    one-sided level at which its lower bound reaches -margin. Below 0.025: the 95 % interval's
    lower bound lies above -margin. 0.5 or more when the observed difference is -margin or
    worse."""
    n = both + only_a + only_b + neither
    if n == 0:
        return 1.0
    if (only_a - only_b) / n <= -margin:
        return 0.5  # the estimate itself is at the margin or beyond

    def lower(z):
        return paired_difference_interval(both, only_a, only_b, neither, z)[0]
    low_z, high_z = 0.0, 40.0
    if lower(high_z) > -margin:
        return 1.0 - stats.normal_cdf(high_z)
    for _ in range(200):  # bisection: the lower bound falls as z grows
        mid = 0.5 * (low_z + high_z)
        if lower(mid) > -margin:
            low_z = mid
        else:
            high_z = mid
    return 1.0 - stats.normal_cdf(0.5 * (low_z + high_z))


def read_campaign(directory):
    """(meta of design.json, rows of trials.csv) of a campaign's output folder."""
    design_path = os.path.join(directory, 'design.json')
    trials_path = os.path.join(directory, 'trials.csv')
    for path in (design_path, trials_path):
        if not os.path.isfile(path):
            raise OSError('%s: no such file (not a campaign output folder?)' % path)
    try:
        with open(design_path) as handle:
            meta = json.load(handle).get('meta')
    except (ValueError, AttributeError) as error:
        raise ValueError('%s: not a campaign design (%s)' % (design_path, error))
    if not isinstance(meta, dict):
        raise ValueError('%s: no "meta" object' % design_path)
    return meta, trials_csv.read_trials_csv(trials_path)


def check_same_design(meta_a, meta_b, rows_a, rows_b, may_differ=()):
    """Raises DesignMismatch naming the first difference that makes the pairing meaningless
    (`may_differ`: further keys allowed to differ, e.g. BENCH_KEYS)."""
    for key in sorted(set(meta_a) | set(meta_b)):
        if key in COMPARED_KEYS or key in may_differ or key == 'design_size':
            continue
        if meta_a.get(key) != meta_b.get(key):
            raise DesignMismatch('the designs differ in %r (A: %s, B: %s): not the same specimens '
                                 'under the same conditions' % (key, json.dumps(meta_a.get(key)),
                                                                json.dumps(meta_b.get(key))))

    def key(row):
        return (row['case'], row['rpm'], row['seed'], row.get('fault') or 'none')
    keys_a = {key(r) for r in rows_a}
    keys_b = {key(r) for r in rows_b}
    if keys_a != keys_b:
        raise DesignMismatch('the designs differ in their trials: %d only in A, %d only in B '
                             '(e.g. %s)' % (len(keys_a - keys_b), len(keys_b - keys_a),
                                            sorted(keys_a ^ keys_b)[0]))


def compare(rows_a, rows_b):
    """Per (case, rpm): the paired counts, McNemar's p, the paired difference and medians."""
    groups = []
    for case, rpm in sorted({(r['case'], r['rpm']) for r in rows_a},
                            key=lambda g: (design.CASES.index(g[0])
                                           if g[0] in design.CASES else 99, g[1])):
        in_a = [r for r in rows_a if r['case'] == case and r['rpm'] == rpm]
        in_b = [r for r in rows_b if r['case'] == case and r['rpm'] == rpm]
        n, both, only_a, only_b, neither = stats.paired_counts(
            in_a, in_b, key=lambda r: (r['seed'], r.get('fault') or 'none'))
        low, high = paired_difference_interval(both, only_a, only_b, neither)
        groups.append({
            'case': case, 'rpm': rpm, 'pairs': n,
            'errors_a': sum(1 for r in in_a if r.get('error')),
            'errors_b': sum(1 for r in in_b if r.get('error')),
            'successes_a': both + only_a, 'successes_b': both + only_b,
            'both': both, 'only_a': only_a, 'only_b': only_b, 'neither': neither,
            'mcnemar_p': stats.mcnemar_exact(only_a, only_b),
            'difference': (only_a - only_b) / n if n else None,
            'difference_ci95': [low, high],
            'wilson95_a': list(stats.wilson_interval(both + only_a, n)),
            'wilson95_b': list(stats.wilson_interval(both + only_b, n)),
            'median_residual_mm_a': stats.median([r.get('residual_mm') for r in in_a
                                                  if not r.get('error')]),
            'median_residual_mm_b': stats.median([r.get('residual_mm') for r in in_b
                                                  if not r.get('error')]),
            'no_penetration_a': sum(1 for r in in_a if not r.get('error')
                                    and not r.get('breakthrough')),
            'no_penetration_b': sum(1 for r in in_b if not r.get('error')
                                    and not r.get('breakthrough')),
            'failure_kinds_a': _kinds(in_a),
            'failure_kinds_b': _kinds(in_b),
        })
    return groups


def _kinds(rows):
    """Failure kinds (pd_campaign.outcome) of the rows that did not error, by count."""
    counts = {}
    for row in rows:
        if row.get('error'):
            continue
        kind = row.get('failure_kind') or ('success' if row['success'] else 'unknown')
        counts[kind] = counts.get(kind, 0) + 1
    return dict(sorted(counts.items()))


def _mm(value):
    return '-' if value is None else '%.2f' % value


def markdown(groups, label_a, label_b, dir_a, dir_b):
    lines = ['# Paired comparison: %s vs %s' % (label_a, label_b), '',
             'A = %s (`%s`), B = %s (`%s`). Trials paired by case, speed and seed (the same '
             'specimen and patient); McNemar\'s exact test on the discordant pairs; the '
             'difference A - B in success rate with its paired 95 %% interval (Newcombe 1998, '
             'method 10).' % (label_a, dir_a, label_b, dir_b), '',
             '| case | rpm | pairs | %s | %s | both | only %s | only %s | neither | '
             'McNemar p | difference %s - %s [95 %%] | median residual %s / %s [mm] |'
             % (label_a, label_b, label_a, label_b, label_a, label_b, label_a, label_b),
             '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for g in groups:
        n = g['pairs']
        rate = (lambda k: '%d/%d (%.0f %%)' % (k, n, 100.0 * k / n)) if n else (lambda k: '-')
        diff = ('%+.1f points [%+.1f, %+.1f]' % (100 * g['difference'],
                                                  100 * g['difference_ci95'][0],
                                                  100 * g['difference_ci95'][1])
                if g['difference'] is not None else '-')
        lines.append('| %s | %.0f | %d | %s | %s | %d | %d | %d | %d | %.3g | %s | %s / %s |' % (
            g['case'], g['rpm'], n, rate(g['successes_a']), rate(g['successes_b']), g['both'],
            g['only_a'], g['only_b'], g['neither'], g['mcnemar_p'], diff,
            _mm(g['median_residual_mm_a']), _mm(g['median_residual_mm_b'])))
    lines += ['', 'No penetration (no breakthrough of the inner layer) and the failure kinds '
              '(src/pd_campaign/outcome.py) of each campaign:', '',
              '| case | rpm | no penetration %s / %s | failure kinds %s | failure kinds %s |'
              % (label_a, label_b, label_a, label_b), '|---|---|---|---|---|']
    for g in groups:
        lines.append('| %s | %.0f | %d / %d | %s | %s |' % (
            g['case'], g['rpm'], g['no_penetration_a'], g['no_penetration_b'],
            ', '.join('%s %d' % kv for kv in g['failure_kinds_a'].items()) or '-',
            ', '.join('%s %d' % kv for kv in g['failure_kinds_b'].items()) or '-'))
    errors = [(g['case'], g['rpm'], g['errors_a'], g['errors_b']) for g in groups
              if g['errors_a'] or g['errors_b']]
    if errors:
        lines += ['', 'Errored trials are left out of the pairs: ' + '; '.join(
            '%s %.0f rpm: %d in A, %d in B' % e for e in errors) + '.']
    return '\n'.join(lines) + '\n'


def figure(groups, label_a, label_b, path):
    """Forest plot: per group, the paired difference in success rate A - B with its 95 %
    interval, the two rates and the discordant pairs beside it."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.0, 0.7 * len(groups) + 1.4))
    for i, g in enumerate(groups):
        y = len(groups) - 1 - i
        if g['difference'] is None:
            continue
        d = 100.0 * g['difference']
        low, high = (100.0 * v for v in g['difference_ci95'])
        ax.errorbar([d], [y], xerr=[[d - low], [high - d]], fmt='o', color='#4477aa', capsize=4)
        ax.annotate('%s %d/%d, %s %d/%d; only %s %d, only %s %d; McNemar p = %.2g' % (
            label_a, g['successes_a'], g['pairs'], label_b, g['successes_b'], g['pairs'],
            label_a, g['only_a'], label_b, g['only_b'], g['mcnemar_p']),
            (0.0, y + 0.22), xycoords=('axes fraction', 'data'), fontsize=7, color='#333333')
    ax.axvline(0.0, color='grey', linewidth=0.8)
    ax.set_yticks(range(len(groups)))
    ax.set_yticklabels(['%s %.0f rpm' % (g['case'], g['rpm']) for g in reversed(groups)],
                       fontsize=8)
    ax.set_ylim(-0.6, len(groups) - 0.2)
    ax.set_xlabel('success %s - %s [percentage points], paired 95 %% interval' % (label_a,
                                                                                 label_b))
    ax.set_title('%s vs %s on the same specimens' % (label_a, label_b), fontsize=9)
    fig.tight_layout()
    try:
        atomic_savefig(fig, path, dpi=100)
    finally:
        plt.close(fig)


def _write_text(path, text):
    with atomic_write(path) as handle:
        handle.write(text)


def main(argv=None):
    parser = tools.argument_parser(prog='campaign_compare', description=__doc__.split('\n')[0])
    parser.add_argument('dir_a', help='output folder of campaign A')
    parser.add_argument('dir_b', help='output folder of campaign B')
    parser.add_argument('--out', help='folder for compare.md, compare.json and compare.png '
                        '(default: ./compare_<A>_vs_<B>)')
    parser.add_argument('--label-a', help='name of A in the tables (default: its folder name)')
    parser.add_argument('--label-b', help='name of B in the tables (default: its folder name)')
    parser.add_argument('--benches', action='store_true',
                        help='the same specimens on two benches: the bench keys (%s) may '
                        'differ too' % ', '.join(BENCH_KEYS))
    args = parser.parse_args(argv)
    name_a = os.path.basename(os.path.normpath(args.dir_a))
    name_b = os.path.basename(os.path.normpath(args.dir_b))
    label_a = args.label_a or name_a
    label_b = args.label_b or name_b
    out = args.out or 'compare_%s_vs_%s' % (name_a, name_b)
    try:
        meta_a, rows_a = read_campaign(args.dir_a)
        meta_b, rows_b = read_campaign(args.dir_b)
        check_same_design(meta_a, meta_b, rows_a, rows_b,
                          BENCH_KEYS if args.benches else ())
        groups = compare(rows_a, rows_b)
        text = markdown(groups, label_a, label_b, args.dir_a, args.dir_b)
        os.makedirs(out, exist_ok=True)
    except (OSError, ValueError) as error:
        sys.stderr.write('campaign_compare: %s\n' % error)
        return 2
    differing = {k: [meta_a.get(k), meta_b.get(k)]
                 for k in COMPARED_KEYS + (BENCH_KEYS if args.benches else ())
                 if meta_a.get(k) != meta_b.get(k)}
    _write_text(os.path.join(out, 'compare.json'), json.dumps(
        {'a': {'dir': args.dir_a, 'label': label_a}, 'b': {'dir': args.dir_b, 'label': label_b},
         'compared': differing, 'groups': groups}, indent=1, sort_keys=True) + '\n')
    _write_text(os.path.join(out, 'compare.md'), text + '\n![paired comparison](compare.png)\n')
    figure(groups, label_a, label_b, os.path.join(out, 'compare.png'))
    sys.stdout.write(text)
    sys.stdout.write('written: %s/compare.md, compare.json, compare.png\n' % out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
