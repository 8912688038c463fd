"""PNG figures of a campaign (matplotlib, Agg backend). Each returns the file name written."""
import json
import os

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from .atomic import atomic_savefig  # noqa: E402
from .design import CASES  # noqa: E402
from .report import PAPER_FIG15_COUNTS, PAPER_TABLE_III  # noqa: E402

COLOURS = {'stationary': 'tab:green', 'uncompensated': 'tab:red', 'compensated': 'tab:blue'}
PAPER_FIG15 = {case: {rpm: k / n for rpm, (k, n) in by_rpm.items()}  # Sec. V-C (report.py)
               for case, by_rpm in PAPER_FIG15_COUNTS.items()}


def _save(fig, out_dir, name):
    fig.tight_layout()
    try:
        atomic_savefig(fig, os.path.join(out_dir, name), dpi=100)
    finally:
        plt.close(fig)
    return name


def table3(summary, out_dir):
    rows = []
    for case in CASES:
        ours = [g for g in summary if g['case'] == case and g['rpm'] == 12000.0]
        if not ours:
            continue
        g = ours[0]
        paper = PAPER_TABLE_III[case]
        rows.append([case, '%d/%d (%.0f %%)' % (paper[0], paper[1], 100.0 * paper[0] / paper[1]),
                     '%d/%d (%.0f %%)' % (g['successes'], g['trials'],
                                          100.0 * (g['success_rate'] or 0.0)),
                     '%.0f-%.0f %%' % (100 * g['wilson95'][0], 100 * g['wilson95'][1])])
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 0.6 + 0.45 * len(rows)))
    ax.axis('off')
    table = ax.table(cellText=rows, colLabels=['case (12000 rpm)', 'paper', 'this campaign',
                                               'Wilson 95 %'], loc='center', cellLoc='center')
    table.scale(1, 1.4)
    ax.set_title('Table III: success of the recognition algorithm')
    return _save(fig, out_dir, 'table3.png')


def fig15(summary, out_dir):
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for case in CASES:
        groups = sorted((g for g in summary if g['case'] == case and g['trials']),
                        key=lambda g: g['rpm'])
        if not groups:
            continue
        rpm = [g['rpm'] for g in groups]
        rate = [100 * g['success_rate'] for g in groups]
        # Rounding can put a bound a hair inside the rate (all or none succeeded): clamp at 0.
        low = [max(0.0, 100 * (g['success_rate'] - g['wilson95'][0])) for g in groups]
        high = [max(0.0, 100 * (g['wilson95'][1] - g['success_rate'])) for g in groups]
        ax.errorbar(rpm, rate, yerr=[low, high], marker='o', capsize=4, label=case,
                    color=COLOURS[case])
        if case in PAPER_FIG15:
            paper = PAPER_FIG15[case]
            ax.plot(list(paper), [100 * v for v in paper.values()], linestyle=':', marker='x',
                    color=COLOURS[case], label='%s (paper)' % case)
    ax.set_xlabel('spindle speed [rpm]')
    ax.set_ylabel('success rate [%] (Wilson 95 % interval)')
    ax.set_ylim(-5, 105)
    ax.legend(fontsize=8)
    ax.set_title('Fig. 15: success rate vs spindle speed')
    return _save(fig, out_dir, 'fig15_success_vs_speed.png')


def fig16(rows, out_dir, rpm=12000.0):
    data_out, data_in, labels = [], [], []
    for case in CASES:
        sel = [r for r in rows if r['case'] == case and r['rpm'] == rpm and not r.get('error')]
        if not sel:
            continue
        data_out.append([r['f_out_n'] for r in sel if r['f_out_n'] is not None])
        data_in.append([r['f_in_n'] for r in sel if r['f_in_n'] is not None])
        labels.append(case)
    if not labels:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(9, 4), sharey=True)
    for ax, data, title in ((axes[0], data_out, 'F_out (outer cortical)'),
                            (axes[1], data_in, 'F_in (inner cortical)')):
        ax.boxplot([d if d else [float('nan')] for d in data], labels=labels)
        ax.set_title(title)
        ax.set_ylabel('peak averaged thrust [N]')
    fig.suptitle('Fig. 16: peak forces per case, %.0f rpm' % rpm)
    return _save(fig, out_dir, 'fig16_peak_forces.png')


def fig17(rows, out_dir, trace_dir, rpm=12000.0):
    chosen = []
    for case in CASES:
        sel = sorted((r for r in rows if r['case'] == case and r['rpm'] == rpm),
                     key=lambda r: r['index'])
        for row in sel:
            path = os.path.join(trace_dir, row['trial_id'] + '.json')
            if os.path.exists(path):
                chosen.append((row, path))
                break
    if not chosen:
        return None
    fig, axes = plt.subplots(len(chosen), 1, figsize=(8, 2.6 * len(chosen)), squeeze=False)
    for ax, (row, path) in zip(axes[:, 0], chosen):
        with open(path) as handle:
            trace = json.load(handle)
        ax.plot(trace['t'], trace['force'], color=COLOURS[row['case']], label='averaged force')
        if trace.get('feature'):
            ax.plot(trace['t'], trace['feature'], color='grey', linewidth=0.8, label='A*')
        for kp in trace.get('key_points', []):
            ax.axvline(kp['t'], color='black', linewidth=0.6, linestyle=':')
            ax.annotate(str(kp['id']), (kp['t'], ax.get_ylim()[1] * 0.9), fontsize=8)
        if trace.get('stop_t'):
            ax.axvline(trace['stop_t'], color='red', linewidth=1.5, label='stop')
        ax.set_title('%s (seed %d): %s, residual %s mm' % (
            row['case'], row['seed'], 'success' if row['success'] else 'failure',
            '-' if row['residual_mm'] is None else '%.2f' % row['residual_mm']), fontsize=9)
        ax.set_ylabel('N')
        ax.legend(fontsize=7, loc='upper left')
    axes[-1, 0].set_xlabel('t [s] (sim time)')
    fig.suptitle('Fig. 17: stop-point detection, %.0f rpm' % rpm)
    return _save(fig, out_dir, 'fig17_force_traces.png')


def fig18(rows, out_dir, rpm=12000.0):
    fig, ax = plt.subplots(figsize=(6.5, 4))
    any_data = False
    for i, case in enumerate(CASES):
        values = [r['residual_mm'] for r in rows if r['case'] == case and r['rpm'] == rpm
                  and r['success'] and r['residual_mm'] is not None]
        if values:
            any_data = True
            ax.scatter([i + 1] * len(values), values, color=COLOURS[case], alpha=0.7)
    ax.axhline(2.0, color='grey', linestyle='--', linewidth=0.8)
    ax.axhline(1.5, color='grey', linestyle=':', linewidth=0.8)
    ax.set_xticks([1, 2, 3])
    ax.set_xticklabels(CASES)
    ax.set_ylabel('residual inner cortical thickness [mm]')
    ax.set_title('Fig. 18: residual thickness of successful stops, %.0f rpm\n'
                 '(paper: close to 1.5 mm; success bound 2 mm)' % rpm, fontsize=10)
    if not any_data:
        ax.text(0.5, 0.5, 'no successful stop', transform=ax.transAxes, ha='center')
    return _save(fig, out_dir, 'fig18_residual_thickness.png')


def table2(csv_path, out_dir):
    """Table II: identification R^2 per axis for the five virtual volunteers (linear and
    hysteresis models), from table2.csv of scripts/table2.py."""
    import csv as _csv
    if not os.path.exists(csv_path):
        return None
    with open(csv_path) as handle:
        rows = list(_csv.DictReader(handle))
    volunteers = sorted({int(r['volunteer']) for r in rows})
    cells = []
    for model in ('linear', 'hysteresis'):
        for axis in ('ap', 'si', 'lr'):
            values = [next((float(r['r2']) for r in rows if int(r['volunteer']) == v
                            and r['model'] == model and r['axis'] == axis), float('nan'))
                      for v in volunteers]
            mean = sum(values) / len(values) if values else float('nan')
            cells.append(['%s %s' % (axis.upper(), model)] + ['%.1f %%' % (100 * x)
                                                               for x in values + [mean]])
    fig, ax = plt.subplots(figsize=(8, 0.6 + 0.4 * len(cells)))
    ax.axis('off')
    table = ax.table(cellText=cells, colLabels=['R^2'] + [str(v) for v in volunteers] + ['mean'],
                     loc='center', cellLoc='center')
    table.scale(1, 1.3)
    ax.set_title('Table II: identification R^2, five virtual volunteers\n'
                 '(paper, linear: AP 94.6 %, SI 95.0 %, LR 81.2 % mean)', fontsize=10)
    return _save(fig, out_dir, 'table2.png')
