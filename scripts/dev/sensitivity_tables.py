#!/usr/bin/python3
"""doc/campaign_results.md's tables of the sensitivity sweeps of `make run` (campaign_sensitivity:
sensitivity_paper/, sensitivity_realistic/, sensitivity_speed/ of a `make run` output, default
results/, or of the archive doc/results/, which keeps each sweep's sensitivity.csv and its
conclusions):
  1. per swept constant, each case's successes at the low end, the nominal bench and the high
     end, an end that differs from the nominal bench significantly (McNemar p < 0.05, the same
     seeds) in bold;
  2. the paper's conclusions: at the nominal bench, and at how many swept ends they hold.
usage: sensitivity_tables.py [RESULTS_DIR]"""
import csv
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, '..', '..'))
CASES = ('stationary', 'uncompensated', 'compensated')
SWEEPS = ('sensitivity_paper', 'sensitivity_realistic', 'sensitivity_speed')
ALPHA = 0.05


def read_rows(archive, folder):
    with open(os.path.join(archive, folder, 'sensitivity.csv')) as handle:
        return list(csv.DictReader(handle))


def _end(row, end):
    text = row['successes_' + end]
    if end != 'nominal' and float(row['mcnemar_p_' + end]) < ALPHA:
        text = '**%s**' % text
    return text


def cell(row):
    """`low / nominal / high of trials` successes of one case and constant."""
    return '%s / %s / %s of %s' % (_end(row, 'low'), _end(row, 'nominal'), _end(row, 'high'),
                                   row['trials_nominal'])


def _short(constant):
    """A constant's name without its section (`simulator_params.`) and path."""
    return constant.split('.', 1)[-1]


def sweep_table(archive, folder, columns):
    """One row per constant (in the sweep's order), one column per (case, rpm) of `columns`."""
    rows = read_rows(archive, folder)
    constants = list(dict.fromkeys(r['constant'] for r in rows))
    by_key = {(r['case'], float(r['rpm']), r['constant']): r for r in rows}
    lines = ['| constant | low / nominal / high | %s |' % ' | '.join(
        '%s, %.0f rpm' % column for column in columns),
        '|---|---|%s' % ('---|' * len(columns))]
    for constant in constants:
        first = next(r for r in rows if r['constant'] == constant)
        unit = ' ' + first['unit'] if first['unit'] else ''
        cells = [cell(by_key[(case, rpm, constant)]) if (case, rpm, constant) in by_key else '-'
                 for case, rpm in columns]
        lines.append('| `%s` | %s / %s / %s%s | %s |' % (
            _short(constant), first['low'], first['nominal'], first['high'], unit,
            ' | '.join(cells)))
    return '\n'.join(lines) + '\n'


def screen_table(archive, folder):
    """A 12000 rpm screen of the three cases."""
    return sweep_table(archive, folder, [(case, 12000.0) for case in CASES])


def speed_table(archive):
    """Fig. 15's sweep: the compensated case at each speed."""
    return sweep_table(archive, 'sensitivity_speed',
                       [('compensated', rpm) for rpm in (12000.0, 16000.0, 20000.0)])


def conclusions_table(archive, folder):
    """Per conclusion of the paper the sweep tests: the verdict at the nominal bench, the swept
    ends where it holds, and those where it fails."""
    found = read_conclusions(os.path.join(archive, folder))
    lines = ['| conclusion | at the nominal bench | holds at (of the swept ends) | fails at |',
             '|---|---|---|---|']
    verdicts = {True: 'holds', False: 'fails', None: 'not evaluated'}
    for c in found:
        if c['nominal']['holds'] is None:
            continue
        holding = sum(1 for e in c['ends'] if e['holds'])
        failing = ('every swept end' if c['fails_at'] and len(c['fails_at']) == len(c['ends'])
                   else ', '.join('`%s` = %s' % (_short(e['key']), e['value'])
                                  for e in c['fails_at']) or 'none')
        lines.append('| %s | %s (%s) | %d of %d | %s |' % (
            c['title'], verdicts[c['nominal']['holds']], c['nominal']['detail'], holding,
            len(c['ends']), failing))
    return '\n'.join(lines) + '\n'


END_KEYS = ('key', 'end', 'value', 'holds', 'detail')


def read_conclusions(directory):
    """A sweep's conclusions, as archived: sensitivity.json's (a make run output) or the
    archive's conclusions.json, each end kept with END_KEYS."""
    full = os.path.join(directory, 'sensitivity.json')
    if not os.path.isfile(full):
        full = os.path.join(directory, 'conclusions.json')
    with open(full) as handle:
        found = json.load(handle)
    found = found['conclusions'] if isinstance(found, dict) else found
    return [{'id': c['id'], 'title': c['title'], 'nominal': c['nominal'],
             'ends': [{k: e[k] for k in END_KEYS} for e in c['ends']],
             'fails_at': [{k: e[k] for k in END_KEYS} for e in c['fails_at']]} for c in found]


def archive_sweep(source, target):
    """A sweep's sensitivity.csv, and its conclusions (read_conclusions) as conclusions.json."""
    sys.path.insert(0, os.path.join(ROOT, 'src'))
    from pd_campaign.atomic import atomic_path
    import shutil
    os.makedirs(target, exist_ok=True)
    with atomic_path(os.path.join(target, 'sensitivity.csv')) as tmp:
        shutil.copyfile(os.path.join(source, 'sensitivity.csv'), tmp)
    with atomic_path(os.path.join(target, 'conclusions.json')) as tmp, open(tmp, 'w') as out:
        json.dump(read_conclusions(source), out, indent=1, sort_keys=True)
        out.write('\n')


def main(argv=None):
    argv = sys.argv if argv is None else argv
    results = argv[1] if len(argv) > 1 else os.path.join(ROOT, 'results')
    for folder in SWEEPS[:2]:
        print(screen_table(results, folder))
        print(conclusions_table(results, folder))
    print(speed_table(results))
    print(conclusions_table(results, 'sensitivity_speed'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
