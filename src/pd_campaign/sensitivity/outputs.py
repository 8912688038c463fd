"""The sweep's outputs: sensitivity.md, sensitivity.csv, sensitivity.json and the tornado plot
sensitivity.png."""
import csv
import json
import os

from ..atomic import atomic_savefig, atomic_write
from ..design import CASES
from ..scenario import PACKAGE_ROOT
from .sweep import ALPHA, ENDS, label, number_text
from .verdicts import rate

# --- the outputs ---------------------------------------------------------------------------------

def _cell_text(cell):
    if not cell['trials']:
        return '-'
    low, high = cell['wilson95']
    return '%d/%d (%.0f-%.0f %%)' % (cell['successes'], cell['trials'], 100 * low, 100 * high)


def _moved_text(row):
    parts = []
    for end in ENDS:
        moved = row[end + '_moved']
        if moved:
            parts.append('%s: %s' % (end, ', '.join('%s %d→%d' % (k, a, b)
                                                    for k, (a, b) in moved.items())))
    return '; '.join(parts) or '-'


def _values_text(row):
    def value(end):
        return number_text(row[end]) + (' (nominal)' if row[end + '_is_nominal'] else '')
    unit = ' %s' % row['unit'] if row['unit'] else ''
    return '%s / %s / %s%s' % (value('low'), number_text(row['nominal']), value('high'), unit)


def group_markdown(group):
    """The table of one case and speed."""
    nominal = group['rows'][0]['nominal_cell'] if group['rows'] else None
    lines = ['### %s, %.0f rpm' % (group['case'], group['rpm']), '',
             'Nominal bench: %s.' % (_cell_text(nominal) if nominal else '-'), '',
             '| constant | low / nominal / high | success at low | at nominal | at high '
             '| McNemar p, low vs nominal | high vs nominal | swing [points] '
             '| failure kinds that moved (nominal→end) |',
             '|---|---|---|---|---|---|---|---|---|']
    for row in group['rows']:
        p = ['-' if row[end + '_is_nominal'] else '%.2g' % row[end + '_test']['mcnemar_p']
             for end in ENDS]
        lines.append('| `%s` | %s | %s | %s | %s | %s | %s | %.0f | %s |' % (
            row['key'], _values_text(row), _cell_text(row['low_cell']),
            _cell_text(row['nominal_cell']), _cell_text(row['high_cell']), p[0], p[1],
            100 * row['swing'], _moved_text(row)))
    return '\n'.join(lines)


def _holds_text(holds):
    return {True: 'holds', False: 'fails', None: 'not evaluated'}[holds]


def conclusions_markdown(found):
    """The section "Conclusions over the range"."""
    lines = ['## Conclusions over the range', '']
    for c in found:
        lines += ['### %s' % c['title'], '', 'Rule: %s.' % c['rule'], '',
                  '- At the nominal bench: **%s** (%s).' % (_holds_text(c['nominal']['holds']),
                                                            c['nominal']['detail'])]
        unevaluated = [e for e in c['ends'] if e['holds'] is None]
        if c['fails_at']:
            lines.append('- Over the range: **fails at %d of %d swept ends**:' % (
                len(c['fails_at']), len(c['ends'])))
            lines += ['    - `%s` = %s (%s): %s' % (e['key'], number_text(e['value']), e['end'],
                                                    e['detail']) for e in c['fails_at']]
        elif c['nominal']['holds'] is None or len(unevaluated) == len(c['ends']):
            lines.append('- Over the range: **not evaluated** (%s).' % (
                (unevaluated[0] if unevaluated else c['nominal'])['detail']))
            unevaluated = []
        elif unevaluated:
            lines.append('- Over the range: **holds at every one of the %d evaluated ends** '
                         '(of %d):' % (len(c['ends']) - len(unevaluated), len(c['ends'])))
        else:
            lines.append('- Over the range: **holds at every one of the %d swept ends**.'
                         % len(c['ends']))
        lines += ['    - not evaluated: `%s` = %s (%s): %s' % (e['key'], number_text(e['value']),
                                                               e['end'], e['detail'])
                  for e in unevaluated]
        lines.append('')
    return '\n'.join(lines)


def shown(path):
    """A path as the report names it: relative to the package for its own files."""
    absolute = os.path.abspath(path)
    inside = absolute.startswith(PACKAGE_ROOT + os.sep)
    return os.path.relpath(absolute, PACKAGE_ROOT) if inside else path


def design_markdown(setup):
    """The head of sensitivity.md: the design and the constants swept."""
    lines = ['# Sensitivity of the conclusions', '',
             'Scenario `%s`, sweep `%s`: %s trials per case and speed at %s rpm, base seed %d, '
             '%s seeds. One constant at a time at each end of its range, every other at the '
             'nominal bench; every bench is a campaign on the same seeds, so each end is paired '
             'with the nominal bench trial by trial. Success k/n with Wilson 95 %% intervals; '
             'McNemar\'s exact p of each end against the nominal bench on the same seeds; the '
             'swing is the largest minus the smallest of the three success rates, and the rows '
             'are sorted by it. An end marked (nominal) is the nominal value: its numbers are '
             'the nominal campaign\'s. Tests are two-sided at %g, without a correction for the '
             'number of tests.' % (
                 shown(setup['scenario_path']), shown(setup['sweep_path']), setup['trials'],
                 ', '.join('%.0f' % r for r in setup['rpms']), setup['seed'],
                 setup['seed_space'], ALPHA), '',
             '| constant | low | nominal | high | unit | source |', '|---|---|---|---|---|---|']
    for e in setup['entries']:
        lines.append('| `%s` | %s | %s (%s) | %s | %s | %s |' % (
            e['key'], number_text(e['low']), number_text(e['nominal']), e['nominal_from'],
            number_text(e['high']), e['unit'] or '-', e['source']))
    return '\n'.join(lines)


def benches_markdown(benches, statuses):
    """Where each bench's campaign is, and how its campaign ended."""
    lines = ['## The campaigns', '', '| bench | directory | campaign |', '|---|---|---|']
    for c in benches:
        if c['scenario'] is None:
            how = 'the nominal\'s (the end is the nominal value)'
        else:
            status = statuses.get(c['id'])
            how = 'exit %d' % status if status else 'complete'
        lines.append('| %s | `%s` | %s |' % (label(c), os.path.basename(c['dir']), how))
    return '\n'.join(lines)


CSV_COLUMNS = ['case', 'rpm', 'constant', 'unit', 'low', 'nominal', 'high', 'swing',
               'successes_low', 'trials_low', 'wilson_low_lo', 'wilson_low_hi',
               'successes_nominal', 'trials_nominal', 'wilson_nominal_lo', 'wilson_nominal_hi',
               'successes_high', 'trials_high', 'wilson_high_lo', 'wilson_high_hi',
               'mcnemar_p_low', 'only_low', 'only_nominal_vs_low',
               'mcnemar_p_high', 'only_high', 'only_nominal_vs_high',
               'errors_low', 'errors_nominal', 'errors_high', 'moved_low', 'moved_high',
               'source']


def csv_rows(groups):
    """sensitivity.csv's rows: one per case, speed and constant."""
    out = []
    for group in groups:
        for row in group['rows']:
            line = {'case': group['case'], 'rpm': '%.0f' % group['rpm'],
                    'constant': row['key'], 'unit': row['unit'], 'low': number_text(row['low']),
                    'nominal': number_text(row['nominal']), 'high': number_text(row['high']),
                    'swing': '%.6g' % row['swing'], 'source': row['source']}
            for end in ('low', 'nominal', 'high'):
                cell = row[end + '_cell']
                line.update({'successes_' + end: cell['successes'], 'trials_' + end:
                             cell['trials'], 'errors_' + end: cell['errors'],
                             'wilson_%s_lo' % end: '%.6g' % cell['wilson95'][0],
                             'wilson_%s_hi' % end: '%.6g' % cell['wilson95'][1]})
            for end in ENDS:
                test = row[end + '_test']
                line.update({'mcnemar_p_' + end: '%.6g' % test['mcnemar_p'],
                             'only_' + end: test['only_end'],
                             'only_nominal_vs_' + end: test['only_nominal'],
                             'moved_' + end: json.dumps(row[end + '_moved'], sort_keys=True)})
            out.append(line)
    return out


def _short(key):
    return key.split('.', 1)[1].split('/')[-1]


def _tornado_axis(ax, group):
    rows = group['rows']
    nominal = rate(rows[0]['nominal_cell']) if rows else None
    for i, row in enumerate(rows):
        y = len(rows) - 1 - i
        for end, colour, offset in (('low', 'tab:blue', 0.18), ('high', 'tab:orange', -0.18)):
            value = rate(row[end + '_cell'])
            if value is None or nominal is None:
                continue
            ax.barh(y + offset, 100 * (value - nominal), left=100 * nominal, height=0.34,
                    color=colour)
            ax.plot([100 * value], [y + offset], marker='|', color=colour, markersize=9,
                    markeredgewidth=2, zorder=3)
    if nominal is not None:
        ax.axvline(100 * nominal, color='black', linewidth=0.9, zorder=2)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(['%s [%s-%s%s]' % (_short(r['key']), number_text(r['low']),
                                          number_text(r['high']),
                                          ' ' + r['unit'] if r['unit'] else '')
                        for r in reversed(rows)], fontsize=7)
    ax.set_xlim(-2, 102)
    ax.set_xlabel('success [%]', fontsize=8)
    nominal_cell = rows[0]['nominal_cell'] if rows else {'successes': 0, 'trials': 0}
    ax.set_title('%s, %.0f rpm (nominal %d/%d)' % (group['case'], group['rpm'],
                                                    nominal_cell['successes'],
                                                    nominal_cell['trials']), fontsize=9)


def tornado(groups, path):
    """sensitivity.png: per case (columns) and speed (rows) a tornado plot, one bar from the
    nominal success rate to each end's, the constants with the largest swing on top."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    rpms = sorted({g['rpm'] for g in groups})
    cases = [c for c in CASES if any(g['case'] == c for g in groups)]
    count = max([len(g['rows']) for g in groups] + [1])
    fig, axes = plt.subplots(len(rpms), len(cases), squeeze=False,
                             figsize=(6.2 * len(cases), (0.32 * count + 1.4) * len(rpms)))
    for group in groups:
        _tornado_axis(axes[rpms.index(group['rpm'])][cases.index(group['case'])], group)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    fig.legend(handles=[Patch(color='tab:blue', label='low end'),
                        Patch(color='tab:orange', label='high end'),
                        Line2D([], [], color='black', linewidth=0.9, label='nominal bench')],
               loc='upper center', ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / fig.get_size_inches()[1]))
    try:
        atomic_savefig(fig, path, dpi=100)
    finally:
        plt.close(fig)


def write_outputs(setup, benches, statuses, groups, found):
    """sensitivity.md, sensitivity.csv, sensitivity.json and sensitivity.png in the output
    folder, each through a temporary file; the conclusions' section as text."""
    out = setup['out']
    section = conclusions_markdown(found)
    text = '\n\n'.join([design_markdown(setup), '## Success per case and speed',
                        '![tornado plots](sensitivity.png)']
                       + [group_markdown(g) for g in groups]
                       + [section, benches_markdown(benches, statuses)]) + '\n'
    with atomic_write(os.path.join(out, 'sensitivity.md')) as handle:
        handle.write(text)
    with atomic_write(os.path.join(out, 'sensitivity.csv'), newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        writer.writerows(csv_rows(groups))
    design = {k: setup[k] for k in ('scenario_path', 'sweep_path', 'rpms', 'trials', 'seed',
                                    'seed_space', 'entries')}
    with atomic_write(os.path.join(out, 'sensitivity.json')) as handle:
        json.dump({'design': design, 'groups': groups, 'conclusions': found}, handle, indent=1,
                  sort_keys=True)
        handle.write('\n')
    tornado(groups, os.path.join(out, 'sensitivity.png'))
    return section
