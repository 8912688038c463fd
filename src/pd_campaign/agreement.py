"""Trial-by-trial agreement of two campaigns on the same design (paired by trial_id, i.e. by
case, rpm and seed): outcome, where the drill ended, residual. Used by `make run` to put the core
engine beside the ROS pipeline, and the ROS pipeline beside a second run of itself.

    python3 -m pd_campaign.agreement DIR_A DIR_B [--label-a A --label-b B]
"""
import sys

from . import tools, trials_csv


def outcome(row):
    """Where a trial ended: success, or the ground-truth category of its failure (its failure
    kind, pd_campaign.outcome, when the row has one)."""
    if row.get('error'):
        return 'error'
    if row['success']:
        return 'success'
    if row.get('failure_kind'):
        return row['failure_kind']
    if row['breakthrough']:
        return 'breakthrough'
    depth, inner = row.get('max_depth_mm'), row.get('inner_start_mm')
    if depth is not None and inner is not None and depth <= inner:
        return 'before inner layer'
    return 'inner layer, residual > 2 mm'


def compare(rows_a, rows_b):
    """Paired rows (by trial_id) and the agreement figures."""
    b_by_id = {r['trial_id']: r for r in rows_b}
    pairs = [(a, b_by_id[a['trial_id']]) for a in rows_a if a['trial_id'] in b_by_id]
    if not pairs:
        raise ValueError('no trial_id in common: not the same design')
    same_success = sum(a['success'] == b['success'] for a, b in pairs)
    same_outcome = sum(outcome(a) == outcome(b) for a, b in pairs)
    residual_diffs = sorted(abs(a['residual_mm'] - b['residual_mm']) for a, b in pairs
                            if a.get('residual_mm') is not None
                            and b.get('residual_mm') is not None)
    median = residual_diffs[len(residual_diffs) // 2] if residual_diffs else None
    return pairs, {'paired': len(pairs), 'same_success': same_success,
                   'same_outcome': same_outcome, 'median_residual_diff_mm': median}


def markdown(pairs, figures, label_a, label_b):
    lines = ['| trial | %s | %s | residual %s / %s [mm] |' % (label_a, label_b, label_a, label_b),
             '|---|---|---|---|']
    for a, b in pairs:
        mark = '' if outcome(a) == outcome(b) else ' **differs**'
        lines.append('| %s | %s | %s%s | %s / %s |' % (
            a['trial_id'], outcome(a), outcome(b), mark, _mm(a.get('residual_mm')),
            _mm(b.get('residual_mm'))))
    lines.append('')
    lines.append('%s vs %s: the same success in %d of %d paired trials, the same outcome in %d; '
                 'median |residual difference| %s mm.' % (
                     label_a, label_b, figures['same_success'], figures['paired'],
                     figures['same_outcome'], _mm(figures['median_residual_diff_mm'])))
    return '\n'.join(lines) + '\n'


def _mm(value):
    return '-' if value is None else '%.2f' % value


def main(argv=None):
    parser = tools.argument_parser(prog='agreement', description=__doc__.split('\n')[0])
    parser.add_argument('dir_a')
    parser.add_argument('dir_b')
    parser.add_argument('--label-a', default='A')
    parser.add_argument('--label-b', default='B')
    args = parser.parse_args(argv)
    try:
        rows_a = trials_csv.read_trials_csv(args.dir_a + '/trials.csv')
        rows_b = trials_csv.read_trials_csv(args.dir_b + '/trials.csv')
        pairs, figures = compare(rows_a, rows_b)
    except (OSError, ValueError) as error:
        sys.stderr.write('agreement: %s\n' % error)
        return 2
    sys.stdout.write(markdown(pairs, figures, args.label_a, args.label_b))
    return 0


if __name__ == '__main__':
    sys.exit(main())
