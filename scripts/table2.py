#!/usr/bin/python3
"""Table II of the paper for the five default virtual volunteers, plus a Fig. 14-style plot.

    rosrun pedicle_drilling table2.py [--out DIR] [--method ceres|pso] [--paper-denoising]
                                      [--plot-volunteer 1] [--jobs J] [--no-figure]

Runs `generate_volunteers` (ids 1..5, 30 s), then `identify` on each volunteer's 8 Hz CSV with
the linear (paper) and the hysteresis model. By default Tv is de-noised like the displacement
(`identify --denoise-tv`, see motion_pipeline.hpp: without it the AP/SI slopes are biased low by
up to ~7 %); --paper-denoising uses the paper's displacement-only de-noising. Writes in DIR:
  table2.md   R^2 per axis per volunteer (linear | hysteresis) with the mean, and the recovered
              vs true slopes q1 of AP and SI (linear model) with the relative error
  table2.csv  volunteer,model,axis,wavelet,q1,q2,q0,r2,rmse,q1_true,q2_true,q1_rel_err
  table2_fig14.png  de-noised displacement and both model fits per axis for one volunteer
              (not with --no-figure)
  data/       the volunteers' CSV and truth files; models/ the identified model YAML files
The Markdown table is also printed. Exit status 0, 1 when a tool fails, 2 on a bad option or an
--out that cannot be created (one line naming it).
"""
import csv
import os
import concurrent.futures
import subprocess
import sys

import yaml

from pd_campaign.atomic import atomic_savefig, atomic_write
from pd_campaign.tools import argument_parser, tool

IDS = [1, 2, 3, 4, 5]
MODELS = ['linear', 'hysteresis']
AXES = ['ap', 'si', 'lr']
CSV_FIELDS = ['volunteer', 'model', 'axis', 'wavelet', 'q1', 'q2', 'q0', 'r2', 'rmse',
              'q1_true', 'q2_true', 'q1_rel_err']


def run(cmd):
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        sys.stderr.write('table2: %s failed (%d):\n%s' % (' '.join(cmd), out.returncode,
                                                          out.stderr))
        sys.exit(1)
    return out.stdout


def load_axes(path):
    with open(path) as f:
        return yaml.safe_load(f)['axes']


def plot(fit_csvs, vid, png):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    data = {m: np.genfromtxt(p, delimiter=',', names=True) for m, p in fit_csvs.items()}
    lin, hys = data['linear'], data['hysteresis']
    fig, axs = plt.subplots(3, 2, figsize=(12, 9), gridspec_kw={'width_ratios': [2.2, 1]})
    names = {'ap': 'AP', 'si': 'SI', 'lr': 'LR'}
    for row, axis in enumerate(AXES):
        ax = axs[row][0]
        ax.plot(lin['t'], lin[axis + '_raw'], color='0.75', lw=0.8, label='recorded')
        ax.plot(lin['t'], lin[axis + '_fit'], color='C0', lw=1.4, label='de-noised')
        ax.plot(lin['t'], lin[axis + '_model'], 'C3--', lw=1.2, label='linear model')
        ax.plot(hys['t'], hys[axis + '_model'], 'C2:', lw=1.4, label='hysteresis model')
        ax.set_ylabel('%s displacement (mm)' % names[axis])
        if row == 0:
            ax.legend(loc='upper right', ncol=4, fontsize=8)
        ax2 = axs[row][1]
        tv = lin[axis + '_tv']  # the Tv the model was fitted against
        ax2.plot(tv, lin[axis + '_fit'], '-', color='C0', lw=0.8, label='de-noised')
        order = np.argsort(tv)
        ax2.plot(tv[order], lin[axis + '_model'][order], 'C3-', lw=1.6, label='linear model')
        if row == 0:
            ax2.legend(loc='upper left', fontsize=8)
        ax2.set_xlabel('tidal volume (ml)' if row == 2 else '')
        ax2.set_ylabel('mm')
    axs[2][0].set_xlabel('time (s)')
    fig.suptitle('Virtual volunteer %d: de-noised displacement and identified models '
                 '(cf. paper Fig. 14)' % vid)
    fig.tight_layout()
    try:
        atomic_savefig(fig, png, dpi=90)
    finally:
        plt.close(fig)


def parse_args(argv):
    parser = argument_parser(description='Table II for the virtual volunteers')
    parser.add_argument('--out', default='table2_out')
    parser.add_argument('--method', default='ceres', choices=['ceres', 'pso'])
    parser.add_argument('--paper-denoising', action='store_true')
    parser.add_argument('--plot-volunteer', type=int, default=1, choices=IDS)
    parser.add_argument('--jobs', type=int, default=1,
                        help='identifications run at once (each is independent; same output)')
    parser.add_argument('--no-figure', action='store_true',
                        help='no table2_fig14.png (the campaign\'s identification: it needs the '
                        'models and the table only; matplotlib is half of this tool\'s time)')
    return parser.parse_args(argv)


def identify_commands(args, data_dir, model_dir):
    """([((vid, model), output yaml, identify command)], {model: fit csv of the plotted
    volunteer})."""
    commands, fit_csvs = [], {}
    for vid in IDS:
        stem = os.path.join(data_dir, 'volunteer_%d' % vid)
        for model in MODELS:
            out_yaml = os.path.join(model_dir, 'volunteer_%d_%s.yaml' % (vid, model))
            cmd = tool('identify') + ['--input', stem + '.csv', '--output', out_yaml,
                                      '--model', model, '--method', args.method,
                                      '--patient-id', 'volunteer_%d' % vid]
            if not args.paper_denoising:
                cmd.append('--denoise-tv')
            if vid == args.plot_volunteer:
                fit_csvs[model] = os.path.join(model_dir, 'volunteer_%d_%s_fit.csv' % (vid, model))
                cmd += ['--fit-csv', fit_csvs[model]]
            commands.append(((vid, model), out_yaml, cmd))
    return commands, fit_csvs


def table_rows(commands, truths):
    """(table2.csv's rows, {(vid, model): identified axes}) from the identifications' files."""
    rows, results = [], {}
    for (vid, model), out_yaml, _ in commands:
        axes = load_axes(out_yaml)
        results[(vid, model)] = axes
        for axis in AXES:
            a, t = axes[axis], truths[vid][axis]
            rows.append({'volunteer': vid, 'model': model, 'axis': axis,
                         'wavelet': a['wavelet'], 'q1': a['q1'], 'q2': a['q2'],
                         'q0': a['q0'], 'r2': a['r2'], 'rmse': a['rmse'],
                         'q1_true': t['q1'], 'q2_true': t['q2'],
                         'q1_rel_err': a['q1'] / t['q1'] - 1.0})
    return rows, results


def write_csv(rows, path):
    with atomic_write(path, newline='') as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ('%.10g' % v if isinstance(v, float) else v) for k, v in r.items()})


def table_markdown(args, results, truths):
    """table2.md: R² per volunteer, axis and model, and the recovered slopes against the truth."""
    den = 'Tv and displacement de-noised' if not args.paper_denoising else \
        'displacement de-noised (paper)'
    md = ['### Table II (virtual volunteers, %s, %s)' % (args.method, den), '',
          '| volunteer | R² AP linear | R² AP hysteresis | R² SI linear | R² SI hysteresis '
          '| R² LR linear | R² LR hysteresis |',
          '|---|---|---|---|---|---|---|']
    sums = [0.0] * 6
    for vid in IDS:
        cells = []
        for axis in AXES:
            for model in MODELS:
                cells.append(results[(vid, model)][axis]['r2'])
        sums = [s + c / len(IDS) for s, c in zip(sums, cells)]
        md.append('| %d | %s |' % (vid, ' | '.join('%.4f' % c for c in cells)))
    md.append('| **mean** | %s |' % ' | '.join('**%.4f**' % c for c in sums))
    md += ['', 'Recovered vs true slopes q1 (mm/ml, linear model; the truth is the generator\'s '
           'hysteresis model q1):', '',
           '| volunteer | AP q1 | AP true | AP error | SI q1 | SI true | SI error '
           '| LR q1 | LR true | LR error |',
           '|---|---|---|---|---|---|---|---|---|---|']
    for vid in IDS:
        cells = []
        for axis in AXES:
            q1 = results[(vid, 'linear')][axis]['q1']
            q1t = truths[vid][axis]['q1']
            cells += ['%.6f' % q1, '%.6f' % q1t, '%+.1f %%' % (100.0 * (q1 / q1t - 1.0))]
        md.append('| %d | %s |' % (vid, ' | '.join(cells)))
    return '\n'.join(md) + '\n'


def main(argv):
    args = parse_args(argv)
    data_dir = os.path.join(args.out, 'data')
    model_dir = os.path.join(args.out, 'models')
    try:
        os.makedirs(model_dir, exist_ok=True)
    except OSError as e:
        sys.stderr.write('table2: --out %r cannot be created: %s\n' % (args.out, e.strerror))
        return 2
    run(tool('generate_volunteers') + ['--out', data_dir, '--ids', ','.join(map(str, IDS))])

    if not 1 <= args.jobs <= 64:
        sys.stderr.write('table2: --jobs must be in 1..64\n')
        return 2
    truths = {vid: load_axes(os.path.join(data_dir, 'volunteer_%d_truth.yaml' % vid))
              for vid in IDS}
    commands, fit_csvs = identify_commands(args, data_dir, model_dir)
    # The identifications are independent processes: run them side by side, read them in order.
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        list(pool.map(run, [cmd for _, _, cmd in commands]))
    rows, results = table_rows(commands, truths)
    write_csv(rows, os.path.join(args.out, 'table2.csv'))
    text = table_markdown(args, results, truths)
    with atomic_write(os.path.join(args.out, 'table2.md')) as f:
        f.write(text)
    print(text)

    written = [os.path.join(args.out, 'table2.md'), os.path.join(args.out, 'table2.csv')]
    if not args.no_figure:
        written.append(os.path.join(args.out, 'table2_fig14.png'))
        plot(fit_csvs, args.plot_volunteer, written[-1])
    print('table2: wrote %s' % ', '.join(written))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
