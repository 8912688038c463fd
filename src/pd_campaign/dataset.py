"""The labelled force dataset (doc/dataset.md).

    rosrun pedicle_drilling campaign_dataset --out DIR [--trials N] [--test-trials M] [--large]

runs the dataset's campaign twice on the core engine with every force-sensor sample recorded
(`campaign --samples`): once on calibration seeds (the train and validation splits) and once on
evaluation seeds (the test split), and writes

- ``DIR/train.npz``, ``DIR/validation.npz``, ``DIR/test.npz``: one row per force-sensor sample
  (the SAMPLE_FIELDS columns, plus ``trial``: the row's index into the split's trial table) and
  the trial table (the TRIAL_FIELDS columns, prefixed ``trial_``); numpy.load reads them, and
  ``pandas.DataFrame({k: z[k] for k in SAMPLE_COLUMNS})`` or ``torch.from_numpy(z[k])`` take the
  columns as they are;
- ``DIR/split.json``: each split's trial ids and seeds (the split is fixed by the seed space and
  the trial's index, never by an outcome), and under ``meta`` the base seed and the scenario;
- ``DIR/DATASHEET.md``: the fields, their units, how the data were made, the counts, the
  simulator's known limits;
- ``DIR/runs/{calibration,evaluation}/``: the two campaigns, with their reports.

The protocol is the paper's peak-force protocol (Sec. V-D): the recognizer observes and every
trial drills through the inner cortical layer, so every trial holds every layer. The split: the
calibration-space trials whose index is 3 modulo 4 form the validation split, the other ones the
training split; the test split is the evaluation-space trials only."""

import argparse
import csv
import json
import os
import subprocess
import sys

import numpy as np
import yaml

from pd_campaign import tools
from pd_campaign.atomic import atomic_write

PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# name -> (unit, meaning). The order is the .npy files' (trial_engine's kSampleFields).
SAMPLE_FIELDS = [
    ('t', 's', 'simulation time (the trial starts a few seconds in)'),
    ('raw_force_n', 'N', 'thrust the recognizer is given: the F/T sensor\'s z force, tared, at '
     'the DAQ rate, faults applied (the input of a recognizer)'),
    ('true_force_n', 'N', 'the simulator\'s true thrust (no sensor chain, no noise)'),
    ('averaged_force_n', 'N', 'the paper recognizer\'s latest averaged force, held between its '
     'block means (what its DrillingState publishes)'),
    ('tip_depth_m', 'm', 'tip depth below the bone\'s top surface (negative: in front of it)'),
    ('max_depth_cut_m', 'm', 'deepest point cut so far'),
    ('layer', '-', 'the label: material at the deepest cut, 0 air, 1 outer cortical, '
     '2 cancellous, 3 inner cortical (the stop layer), 4 canal (broken through)'),
    ('contact', '-', '1 while the drill\'s lips cut'),
    ('bone_ap_m', 'm', 'true vertebra AP displacement from its home'),
    ('predicted_ap_m', 'm', 'the planner\'s predicted AP bone displacement since the trial\'s '
     'start (NaN before it plans)'),
    ('tracker_x_m', 'm', 'last tracked marker position as the pipeline received it, tracker '
     'camera frame (NaN before the first)'),
    ('tracker_y_m', 'm', 'see tracker_x_m'),
    ('tracker_z_m', 'm', 'see tracker_x_m'),
    ('breath_phase', '-', 'fraction of the current ventilator breath elapsed, [0, 1]'),
    ('tidal_volume_ml', 'ml', 'patient tidal volume'),
]
SAMPLE_COLUMNS = [name for name, _, _ in SAMPLE_FIELDS]
LAYERS = ('air', 'outer_cortical', 'cancellous', 'inner_cortical', 'canal')
INNER_CORTICAL = LAYERS.index('inner_cortical')  # the stop layer's label
CANAL = LAYERS.index('canal')  # broken through

# trials.csv column -> (numpy type, unit, meaning), stored as trial_<column>.
TRIAL_FIELDS = [
    ('trial_id', str, '-', 'the campaign\'s trial id (case-rpm-index)'),
    ('case', str, '-', 'stationary, uncompensated or compensated (paper cases a-c)'),
    ('rpm', float, 'rpm', 'spindle speed'),
    ('index', int, '-', 'trial index in its campaign'),
    ('seed', np.uint64, '-', 'the trial\'s seed: the same seed gives the same trial'),
    ('seed_space', str, '-', 'calibration or evaluation'),
    ('volunteer_id', int, '-', 'the virtual volunteer breathing under the bone'),
    ('amplitude_scale', float, '-', 'the patient\'s breathing amplitude factor'),
    ('ventilator_rate_bpm', float, '1/min', 'ventilator rate'),
    ('tidal_volume_ml', float, 'ml', 'ventilator tidal volume setting'),
    ('force_noise_sd_n', float, 'N', 'the sensor\'s white noise of this trial'),
    ('inner_start_mm', float, 'mm', 'depth where the inner cortical layer starts'),
    ('inner_cortical_mm', float, 'mm', 'inner cortical thickness'),
    ('f_out_truth_n', float, 'N', 'true peak block-mean thrust in the outer cortex'),
    ('f_in_truth_n', float, 'N', 'true peak block-mean thrust in the inner cortex'),
]
SPLITS = ('train', 'validation', 'test')
VALIDATION_MODULUS = 4  # calibration trials with index % 4 == 3 are the validation split


def split_of(seed_space, index):
    """The split of a trial, fixed by its seed space and its index (never by its outcome)."""
    if seed_space == 'evaluation':
        return 'test'
    if seed_space != 'calibration':
        raise ValueError('seed space %r is neither calibration nor evaluation' % seed_space)
    return 'validation' if int(index) % VALIDATION_MODULUS == VALIDATION_MODULUS - 1 else 'train'


def _convert(kind, text):
    if kind is str:
        return text
    if text == '':
        return np.nan if kind is float else -1
    return kind(text) if kind is not np.uint64 else np.uint64(int(text))


def assemble(run_dirs, out_dir):
    """Reads the campaigns' trials.csv and samples, writes the three splits; returns the counts
    {split: {'trials': n, 'samples': n, 'cases': {case: n}}}. A trial that errored is left out
    (its row stays in its campaign's trials.csv)."""
    tables = {split: [] for split in SPLITS}
    for run_dir in run_dirs:
        with open(os.path.join(run_dir, 'trials.csv'), newline='') as handle:
            for row in csv.DictReader(handle):
                if row.get('error'):
                    continue
                path = os.path.join(run_dir, 'samples', row['trial_id'] + '.npy')
                if not os.path.isfile(path):
                    raise RuntimeError('%s: no samples file for trial %s' % (path, row['trial_id']))
                tables[split_of(row['seed_space'], row['index'])].append((row, path))
    counts = {}
    for split in SPLITS:
        rows = sorted(tables[split], key=lambda item: (float(item[0]['rpm']),
                                                        int(item[0]['index']), item[0]['case']))
        columns = {name: [] for name in SAMPLE_COLUMNS}
        trial_index = []
        for k, (_, path) in enumerate(rows):
            samples = np.load(path)
            if tuple(samples.dtype.names) != tuple(SAMPLE_COLUMNS):
                raise RuntimeError('%s: fields %s, expected %s' % (
                    path, samples.dtype.names, SAMPLE_COLUMNS))
            for name in SAMPLE_COLUMNS:
                columns[name].append(samples[name])
            trial_index.append(np.full(len(samples), k, dtype=np.int32))
        arrays = {name: (np.concatenate(parts) if parts else np.zeros(0))
                  for name, parts in columns.items()}
        arrays['trial'] = np.concatenate(trial_index) if trial_index else np.zeros(0, np.int32)
        for name, kind, _, _ in TRIAL_FIELDS:
            values = [_convert(kind, row[name]) for row, _ in rows]
            arrays['trial_' + name] = np.array(values, dtype=(
                np.uint64 if kind is np.uint64 else None if kind is not str else np.str_))
        with atomic_write(os.path.join(out_dir, split + '.npz'), 'wb') as handle:
            np.savez_compressed(handle, **arrays)
        cases = {}
        for row, _ in rows:
            cases[row['case']] = cases.get(row['case'], 0) + 1
        counts[split] = {'trials': len(rows), 'samples': int(len(arrays['trial'])), 'cases': cases,
                         'ids': [(row['trial_id'], row['seed']) for row, _ in rows]}
    return counts


def datasheet(counts, command, scenario_text):
    """The datasheet's Markdown (after Gebru et al., "Datasheets for Datasets", CACM 2021)."""
    lines = ['# Datasheet: simulated pedicle-drilling force dataset', '',
             'Written by `%s`.' % command, '',
             '## Motivation',
             'A labelled force dataset for drilling-state recognition in pedicle drilling on a '
             'breathing vertebra: no public one exists. Train a recognizer on `train.npz`, choose '
             'its settings on `validation.npz`, report on `test.npz` only, then run it in the '
             'closed loop (doc/plugins.md) and on the leaderboard (doc/leaderboard.md).', '',
             '## Composition',
             '| split | trials | samples | trials per case |', '|---|---|---|---|']
    for split in SPLITS:
        c = counts[split]
        lines.append('| %s | %d | %d | %s |' % (split, c['trials'], c['samples'], ', '.join(
            '%s %d' % item for item in sorted(c['cases'].items())) or '-'))
    lines += ['', 'Each split is one `.npz` file: per-sample columns (one row per force-sensor '
              'sample, from the trial\'s start to its end), `trial` (the row\'s index into the '
              'trial table) and the trial table (`trial_<field>`).', '',
              '### Per-sample columns', '| column | unit | meaning |', '|---|---|---|']
    lines += ['| `%s` | %s | %s |' % field for field in SAMPLE_FIELDS]
    lines += ['| `trial` | - | index into the trial table of the same file |', '',
              '### Trial table', '| column | unit | meaning |', '|---|---|---|']
    lines += ['| `trial_%s` | %s | %s |' % (name, unit, text) for name, _, unit, text in TRIAL_FIELDS]
    lines += ['', '## Split',
              'Fixed by the seed, never by an outcome: the evaluation seed space (bit 62 of the '
              'seed set; doc/experiments.md, "Seed spaces") is the test split; calibration-space '
              'trials whose index is 3 modulo 4 are the validation split, the others the training '
              'split. `split.json` lists every split\'s trial ids and seeds.', '',
              '## Collection process',
              'Simulated closed-loop trials of the core engine (`campaign --samples`, '
              'core::ClosedLoopEngine), the paper\'s peak-force protocol: the recognizer observes '
              'and the drill goes through the inner cortical layer, so each trial has every layer. '
              'One seed gives the same trial bit for bit. The scenario:', '', '```yaml',
              scenario_text.rstrip(), '```', '',
              '## Labels',
              '`layer` is the simulator\'s ground truth at the deepest cut. The task of a '
              'recognizer is to stop while the label is 3 (inner cortical): a stop at 4 is a '
              'breakthrough; a stop at 1 or 2 an early stop.', '',
              '## Known limits',
              '- Simulated, not measured: the force model, the sensor chain and the specimens are '
              'those of doc/simulator_physics.md, each constant with its source or marked as an '
              'assumption; the sensitivity sweeps (doc/campaign_results.md) say which conclusions '
              'depend on which constant.',
              '- One drill, one feed rate, one bone model family (three layers, smooth boundaries); '
              'no specimen-to-specimen texture beyond the drawn thicknesses, densities and noise.',
              '- The recognizer in the loop is the paper\'s: `averaged_force_n` is its averaging; '
              'a learned recognizer should start from `raw_force_n`.',
              '- No vibration, acoustic or current channel: force and motion only.', '',
              '## Reading it', '```python', 'import numpy as np',
              'z = np.load("train.npz")',
              'force, label, trial = z["raw_force_n"], z["layer"], z["trial"]',
              '# pandas: pd.DataFrame({k: z[k] for k in z.files if not k.startswith("trial_")})',
              '# PyTorch: torch.from_numpy(z["raw_force_n"])', '```', '']
    return '\n'.join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='campaign_dataset',
        description='The labelled force dataset (doc/dataset.md): train/validation from '
        'calibration seeds, test from evaluation seeds.')
    parser.add_argument('--out', required=True)
    parser.add_argument('--scenario', default=os.path.join(PACKAGE_ROOT, 'config',
                                                           'scenario_dataset.yaml'))
    parser.add_argument('--trials', type=int, default=8,
                        help='calibration-seed trials per case and speed (train + validation)')
    parser.add_argument('--test-trials', type=int, default=4,
                        help='evaluation-seed trials per case and speed (test)')
    parser.add_argument('--large', action='store_true',
                        help='400 calibration and 200 evaluation trials per case and speed')
    parser.add_argument('--rpm', default=None, help='comma-separated spindle speeds '
                        '(default: the scenario\'s)')
    parser.add_argument('--seed', type=int, default=None,
                        help='base seed (default: the scenario\'s); the test split\'s specimens '
                        'are the evaluation-space trials of this base seed')
    parser.add_argument('--jobs', type=int, default=2)
    args = parser.parse_args(argv)
    if args.large:
        args.trials, args.test_trials = 400, 200
    if args.trials < VALIDATION_MODULUS or args.test_trials < 1:
        parser.error('--trials must be at least %d (a validation trial per case) and '
                     '--test-trials at least 1' % VALIDATION_MODULUS)
    try:
        with open(args.scenario) as handle:
            scenario_text = handle.read()
        scenario = yaml.safe_load(scenario_text)
    except (OSError, yaml.YAMLError) as e:
        parser.error('--scenario: %s' % e)
    base_seed = args.seed if args.seed is not None else int(scenario.get('seed', 1))
    os.makedirs(args.out, exist_ok=True)
    run_dirs = []
    for space, trials in (('calibration', args.trials), ('evaluation', args.test_trials)):
        run_dir = os.path.join(args.out, 'runs', space)
        command = tools.tool('campaign') + [
            '--scenario', args.scenario, '--seed-space', space, '--trials', str(trials),
            '--samples', '--jobs', str(args.jobs), '--seed', str(base_seed), '--out', run_dir]
        if args.rpm:
            command += ['--rpm', args.rpm]
        sys.stderr.write('campaign_dataset: %s seeds, %d trials per case and speed\n'
                         % (space, trials))
        if subprocess.run(command).returncode != 0:
            sys.stderr.write('campaign_dataset: the %s campaign failed\n' % space)
            return 1
        run_dirs.append(run_dir)
    counts = assemble(run_dirs, args.out)
    with atomic_write(os.path.join(args.out, 'split.json')) as handle:
        listing = {split: [{'trial_id': i, 'seed': s} for i, s in counts[split]['ids']]
                   for split in SPLITS}
        listing['meta'] = {'base_seed': base_seed, 'scenario': os.path.basename(args.scenario),
                           'validation_modulus': VALIDATION_MODULUS,
                           'protocol': scenario.get('protocol', 'recognition')}
        json.dump(listing, handle, indent=1)
    command = 'campaign_dataset ' + ' '.join(argv if argv is not None else sys.argv[1:])
    with atomic_write(os.path.join(args.out, 'DATASHEET.md')) as handle:
        handle.write(datasheet(counts, command, scenario_text))
    for split in SPLITS:
        sys.stderr.write('campaign_dataset: %s: %d trials, %d samples\n' % (
            split, counts[split]['trials'], counts[split]['samples']))
    return 0
