#!/usr/bin/python3
"""The latency-budget table (scripts/dev/run_latency_budget.sh): one row per campaign directory,
given as LABEL=DIR, with the correct-stop and no-penetration rates (Wilson 95 %), the failure
kinds and the residual's median, each against the first row (paired seeds: McNemar's exact
test on the successes)."""
import csv
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'src'))
from pd_campaign import stats  # noqa: E402


def load(directory):
    with open(os.path.join(directory, 'trials.csv'), newline='') as handle:
        return {(row['case'], float(row['rpm']), int(row['index'])): row
                for row in csv.DictReader(handle)}


def flag(row, key):
    return str(row.get(key, '')).lower() in ('1', 'true')


def main(argv):
    cells = [arg.rsplit('=', 1) for arg in argv]
    if not cells or any(len(c) != 2 for c in cells):
        sys.stderr.write('usage: latency_table.py LABEL=DIR...\n')
        return 2
    base = load(cells[0][1])
    print('| delay | trials | correct stops (Wilson 95 %) | no penetration (Wilson 95 %) | '
          'McNemar p vs first row | residual median [mm] | failure kinds |')
    print('|---|---|---|---|---|---|---|')
    for label, directory in cells:
        rows = load(directory)
        keys = sorted(set(rows) & set(base))
        n = len(keys)
        ok = sum(flag(rows[k], 'success') for k in keys)
        safe = sum(not flag(rows[k], 'breakthrough') for k in keys)
        b = sum(flag(base[k], 'success') and not flag(rows[k], 'success') for k in keys)
        c = sum(not flag(base[k], 'success') and flag(rows[k], 'success') for k in keys)
        residuals = sorted(float(rows[k]['residual_mm']) for k in keys
                           if rows[k].get('residual_mm') not in (None, ''))
        kinds = {}
        for k in keys:
            kinds[rows[k]['failure_kind']] = kinds.get(rows[k]['failure_kind'], 0) + 1
        lo, hi = stats.wilson_interval(ok, n)
        slo, shi = stats.wilson_interval(safe, n)
        median = stats.median(residuals)
        print('| %s | %d | %d (%.0f-%.0f %%) | %d (%.0f-%.0f %%) | %.3g | %s | %s |' % (
            label, n, ok, 100 * lo, 100 * hi, safe, 100 * slo, 100 * shi,
            stats.mcnemar_exact(b, c), '-' if median is None else '%.2f' % median,
            ', '.join('%s %d' % kv for kv in sorted(kinds.items()))))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
