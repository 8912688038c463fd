#!/usr/bin/python3
"""doc/campaign_results.md's generated tables, from the archived `make run` campaigns in
doc/results/ (make_docs.py's BLOCKS; the same folders in a `make run` output, default results/):
  1. the exact and the paper's compensation profile on the paper's bench (campaign_exact/ and
     campaign/, the same seeds): stationary against compensated per profile, and the profiles
     paired seed for seed;
  2. the paper's bench against the realistic bench (campaign/, campaign_realistic/), trial by
     trial, and which imperfection acts (campaign_virtual_patient/ between them);
  3. the ROS pipeline against the core engine (campaign_ros/, campaign_ros_repeat/,
     campaign_realistic_ros/ beside the core campaigns);
  4. the paper's classes against the baselines (campaign/ beside baseline_tracked_marker/ and
     baseline_force_difference/);

usage: campaign_results_tables.py [RESULTS_DIR]"""
import csv
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'src'))

from pd_campaign import agreement, compare, stats, trials_csv  # noqa: E402

PROFILES = (('exact', 'campaign_exact'), ('paper (125 ms trapezoids)', 'campaign'))
BENCHES = (('the paper\'s', 'campaign'), ('the virtual patient alone (`scenario_virtual_patient.yaml`)',
                                           'campaign_virtual_patient'),
           ('the realistic bench (`scenario_realistic.yaml`)', 'campaign_realistic'))


def rows_at_12000(archive, name, cases=None):
    """The campaign `name`'s 12000 rpm trials (of `cases`, every case by default)."""
    return [r for r in trials_csv.read_trials_csv(os.path.join(archive, name, 'trials.csv'))
            if r['rpm'] == 12000.0 and (cases is None or r['case'] in cases)]


def _rate(successes, trials):
    low, high = stats.wilson_interval(successes, trials)
    return '%d/%d (%.0f-%.0f %%)' % (successes, trials, 100 * low, 100 * high)


def _median(values, fmt):
    value = stats.median(values)
    return '-' if value is None else fmt % value


def summary_group(archive, name, case, rpm=12000.0):
    """The group (case, rpm) of the archived campaign `name`'s summary.json."""
    with open(os.path.join(archive, name, 'summary.json')) as handle:
        groups = json.load(handle)['groups']
    return next(g for g in groups if g['case'] == case and float(g['rpm']) == rpm)


def profiles_table(archive):
    """Per profile: stationary against compensated on the same specimens (paired by seed), the
    interruptions of the cut before the stop and the tip-bone tracking RMS (summary.json's
    medians)."""
    lines = ['| profile | stationary | compensated | only stationary / only compensated | '
             'McNemar p | interruptions of the cut before the stop, median, stationary / '
             'compensated | tracking RMS, median, stationary / compensated [mm] |',
             '|---|---|---|---|---|---|---|']
    for label, name in PROFILES:
        rows = rows_at_12000(archive, name)
        n, both, only_s, only_c, _ = stats.paired_counts(
            [r for r in rows if r['case'] == 'stationary'],
            [r for r in rows if r['case'] == 'compensated'], key=lambda r: r['seed'])
        groups = [summary_group(archive, name, case) for case in ('stationary', 'compensated')]
        lines.append('| %s | %s | %s | %d / %d | %.2g | %.0f / %.0f | %.3f / %.3f |' % (
            label, _rate(both + only_s, n), _rate(both + only_c, n), only_s, only_c,
            stats.mcnemar_exact(only_s, only_c),
            *[g['median_contact_loss_count'] for g in groups],
            *[g['median_tracking_rms_mm'] for g in groups]))
    return '\n'.join(lines) + '\n'


def profile_pairs_table(archive):
    """The two profiles paired seed for seed per case, as campaign_compare writes it."""
    cases = ('stationary', 'compensated')
    groups = compare.compare(rows_at_12000(archive, PROFILES[0][1], cases),
                             rows_at_12000(archive, PROFILES[1][1], cases))
    text = compare.markdown(groups, 'exact', 'paper', '', '')
    table = text.split('\n\n')[2]
    return table.rstrip('\n') + '\n'


def benches_table(archive):
    """The paper's bench against the realistic bench, trial by trial, every case and speed."""
    groups = compare.compare(
        trials_csv.read_trials_csv(os.path.join(archive, 'campaign', 'trials.csv')),
        trials_csv.read_trials_csv(os.path.join(archive, 'campaign_realistic', 'trials.csv')))
    lines = ['| case | rpm | paper bench | realistic bench | only paper / only realistic | '
             'McNemar p | no penetration (paper / realistic) |', '|---|---|---|---|---|---|---|']
    for g in groups:
        lines.append('| %s | %.0f | %d/%d | %d/%d | %d / %d | %.2g | %d / %d |' % (
            g['case'], g['rpm'], g['successes_a'], g['pairs'], g['successes_b'], g['pairs'],
            g['only_a'], g['only_b'], g['mcnemar_p'], g['no_penetration_a'],
            g['no_penetration_b']))
    return '\n'.join(lines) + '\n'


def imperfections_table(archive):
    """The compensated case at 12000 rpm on the paper's bench, the virtual patient alone and the
    realistic bench (the same seeds): successes, H1 stops, breakthroughs and tracking RMS."""
    lines = ['| bench | compensated | H1 stops | breakthroughs | tracking RMS, median [mm] |',
             '|---|---|---|---|---|']
    for label, name in BENCHES:
        rows = rows_at_12000(archive, name, ('compensated',))
        lines.append('| %s | %d/%d | %d | %d | %s |' % (
            label, sum(r['success'] for r in rows), len(rows),
            sum(r['failure_kind'] == 'safety_h1' for r in rows),
            sum(bool(r['breakthrough']) for r in rows),
            _median([r['tracking_rms_mm'] for r in rows], '%.2f')))
    return '\n'.join(lines) + '\n'


# The ROS campaigns of `make run` and the core campaign each is compared with.
# Two runs of the same engine are compared column by column too.
AGREEMENT = (('the paper\'s design', 'campaign_ros', 'campaign', 'ROS against the core engine'),
             ('the paper\'s design', 'campaign_ros', 'campaign_ros_repeat',
              'ROS against ROS, every step waited for'),
             ('the realistic bench', 'campaign_realistic_ros', 'campaign_realistic',
              'ROS against the core engine'))
# The trial columns compared for "every column equal" (the archived ones; not the wall time).
SAME_COLUMNS = ('success', 'breakthrough', 'failure_kind', 'tracking_rms_mm', 'residual_mm',
                'max_depth_mm', 'inner_start_mm', 'stop_source', 'stop_reason',
                'contact_loss_count', 'h1_error_mm', 'lockstep_timeouts')


def _raw(archive, name):
    with open(os.path.join(archive, name, 'trials.csv')) as handle:
        return {r['trial_id']: r for r in csv.DictReader(handle)}


def agreement_table(archive):
    """Per comparison: pairs, the same outcome, the same success, every archived column equal,
    the largest residual difference."""
    lines = ['| bench (12000 rpm) | comparison | pairs | the same outcome | every archived column '
             'equal (two ROS runs) | largest residual difference [mm] | lockstep timeouts |',
             '|---|---|---|---|---|---|---|']
    for bench, ros, other, label in AGREEMENT:
        read = (lambda name: trials_csv.read_trials_csv(os.path.join(archive, name,
                                                                     'trials.csv')))
        pairs, figures = agreement.compare(read(ros), read(other))
        raw_a, raw_b = _raw(archive, ros), _raw(archive, other)
        equal = ('%d' % sum(all(raw_a[a['trial_id']].get(c) == raw_b[a['trial_id']].get(c)
                                for c in SAME_COLUMNS) for a, _ in pairs)
                 if other.startswith('campaign_ros') else '-')
        differences = [abs(a['residual_mm'] - b['residual_mm']) for a, b in pairs
                       if a.get('residual_mm') is not None and b.get('residual_mm') is not None]
        timeouts = sum(int(raw_a[a['trial_id']].get('lockstep_timeouts') or 0)
                       + int(raw_b[a['trial_id']].get('lockstep_timeouts') or 0) for a, _ in pairs)
        lines.append('| %s | %s | %d | %d | %s | %.2g | %d |' % (
            bench, label, figures['paired'], figures['same_outcome'], equal,
            max(differences) if differences else float('nan'), timeouts))
    return '\n'.join(lines) + '\n'


def compare_table(archive, name_a, name_b, labels, cases):
    """campaign_compare's table of two archived campaigns' 12000 rpm trials of `cases`, paired by
    seed."""
    groups = compare.compare(rows_at_12000(archive, name_a, cases),
                             rows_at_12000(archive, name_b, cases))
    return compare.markdown(groups, labels[0], labels[1], '', '').split('\n\n')[2] + '\n'


def baselines_table(archive):
    """The paper's compensator against the tracker-feedback one, and the paper's recognizer
    against the breakthrough detector, on the paper campaign's seeds."""
    return (compare_table(archive, 'campaign', 'baseline_tracked_marker', ('paper', 'tracked'),
                          ('compensated',))
            + '\n' + compare_table(archive, 'campaign', 'baseline_force_difference',
                                   ('paper', 'baseline'), ('stationary', 'compensated')))


def main(argv=None):
    argv = sys.argv if argv is None else argv
    results = argv[1] if len(argv) > 1 else os.path.join(ROOT, 'results')
    for table in (profiles_table, profile_pairs_table, benches_table, imperfections_table,
                  agreement_table, baselines_table):
        print(table(results))
    return 0


if __name__ == '__main__':
    sys.exit(main())
