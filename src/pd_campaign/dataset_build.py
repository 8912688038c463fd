"""`rosrun pedicle_drilling campaign_dataset`: the labelled force dataset made (doc/dataset.md; its
declaration is dataset.py's): the dataset's two campaigns run, their trials assembled into the
splits' files, the HDF5 file, DATASHEET.md, croissant.json and SHA256SUMS written."""
import argparse
import csv
import json
import os
import subprocess
import sys

import numpy as np
import yaml

from pd_campaign import croissant, dataset_files, tools
from pd_campaign.atomic import atomic_write
from pd_campaign.dataset import (FORMAT_VERSION, PACKAGE_ROOT, SAMPLE_COLUMNS, SPLITS,
                                 TRIAL_FIELDS, VALIDATION_MODULUS, columns_markdown, convert,
                                 HIDDEN_VOLUNTEERS, SEEN_DENSITY_RANGE, density_references,
                                 hidden_reason, hidden_rule, specimen_densities, specimen_peaks,
                                 split_of)
from pd_campaign.design import SEED_SPACE_BIT
from pd_campaign.scenario import Scenario


def _trial_rows(run_dirs):
    """({split: [(trials.csv row, samples .npy path)]} in (rpm, index, case) order, {'hidden':
    [(trial id, seed, reason)], 'test_hidden': [...], 'references': [[rpm, N]]}). A trial that
    errored is left out (its row stays in its campaign's trials.csv); so is a calibration-space
    trial under a hidden condition (dataset.hidden_reason: its specimen's breathing, or its
    density against the calibration specimens' references), which no training or validation
    trial may hold; an evaluation-space one stays in the test split, listed."""
    tables = {split: [] for split in SPLITS}
    runs = []
    for run_dir in run_dirs:
        with open(os.path.join(run_dir, 'trials.csv'), newline='') as handle:
            runs.append((run_dir, [row for row in csv.DictReader(handle) if not row.get('error')]))
    references = density_references(specimen_peaks(
        [row for _, rows in runs for row in rows if row['seed_space'] == 'calibration']))
    hidden = {'hidden': [], 'test_hidden': [], 'references': references}
    for run_dir, rows in runs:
        densities = specimen_densities(rows, references)
        for row in rows:
            path = os.path.join(run_dir, 'samples', row['trial_id'] + '.npy')
            if not os.path.isfile(path):
                raise RuntimeError('%s: no samples file for trial %s' % (path, row['trial_id']))
            split = split_of(row['seed_space'], row['index'])
            reason = hidden_reason(row.get('volunteer_id'), densities.get(
                (float(row['rpm']), int(row['seed']))))
            if reason:
                hidden['test_hidden' if split == 'test' else 'hidden'].append(
                    (row['trial_id'], row['seed'], reason))
                if split != 'test':
                    continue
            tables[split].append((row, path))
    return {split: sorted(rows, key=lambda item: (float(item[0]['rpm']), int(item[0]['index']),
                                                  item[0]['case']))
            for split, rows in tables.items()}, hidden


def _split_arrays(rows):
    """The columns of one split: the sample columns, `trial` and `trial_<field>`."""
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
    for name, kind, _, _, _ in TRIAL_FIELDS:
        values = [convert(kind, row[name]) for row, _ in rows]
        arrays['trial_' + name] = np.array(values, dtype=(
            np.uint64 if kind is np.uint64 else None if kind is not str else np.str_))
    return arrays


def assemble(run_dirs, out_dir, meta):
    """Reads the campaigns' trials.csv and samples, writes the three splits as .npz files and
    the HDF5 file (dataset_files, with `meta`: main's); returns the counts {split: {'trials': n,
    'samples': n, 'cases': {case: n}, 'ids': [(trial id, seed)]}} and the finished
    dataset_files.Hdf5Writer (its version, content hash and columns)."""
    tables, hidden = _trial_rows(run_dirs)
    counts = {'hidden': hidden}
    with dataset_files.hdf5_writer(os.path.join(out_dir, dataset_files.HDF5_NAME), meta) as h5:
        for split in SPLITS:
            rows = tables[split]
            arrays = _split_arrays(rows)
            with atomic_write(os.path.join(out_dir, split + '.npz'), 'wb') as handle:
                np.savez_compressed(handle, **arrays)
            h5.add_split(split, arrays)
            cases = {}
            for row, _ in rows:
                cases[row['case']] = cases.get(row['case'], 0) + 1
            counts[split] = {'trials': len(rows), 'samples': int(len(arrays['trial'])),
                             'cases': cases,
                             'ids': [(row['trial_id'], row['seed']) for row, _ in rows]}
    return counts, h5


def datasheet(counts, meta, writer):
    """The datasheet's Markdown (after Gebru et al., "Datasheets for Datasets", CACM 2021)."""
    package = meta['package']
    lines = ['# Datasheet: simulated pedicle-drilling force dataset', '',
             'Written by `%s`.' % meta['command'], '',
             '## Identity', '',
             '- dataset version `%s` (format %s and the content hash\'s first 12 digits); '
             'content SHA-256 `%s`' % (writer.version, FORMAT_VERSION, writer.content_sha256),
             '- made by %s %s, build `%s` (digest of its executables `%s`)' % (
                 package['name'], package['version'], package['build_id'],
                 package['build_digest']),
             '- force-sample rate(s): %s Hz' % ', '.join(
                 '%g' % rate for rate in sorted(writer.rates)), '',
             '## Motivation',
             'A labelled force dataset for drilling-state recognition in pedicle drilling on a '
             'breathing vertebra: no public one exists. Train a recognizer on the train split, '
             'choose its settings on the validation split, report on the test split only, then '
             'run it in the closed loop (doc/plugins.md) and on the leaderboard '
             '(doc/leaderboard.md).', '',
             '## Composition',
             '| split | trials | samples | trials per case |', '|---|---|---|---|']
    for split in SPLITS:
        c = counts[split]
        lines.append('| %s | %d | %d | %s |' % (split, c['trials'], c['samples'], ', '.join(
            '%s %d' % item for item in sorted(c['cases'].items())) or '-'))
    lines += ['', 'The same data twice: `%s`, the metadata inside as HDF5 attributes, and one '
              '`.npz` file per split. In the HDF5 file: %s. In a `.npz` file: the per-sample '
              'columns, `trial` (the row\'s index into the trial table) and the trial table '
              '(`trial_<field>`). `croissant.json` describes them (Croissant 1.0); `SHA256SUMS` '
              'checks them (`sha256sum -c SHA256SUMS`).'
              % (dataset_files.HDF5_NAME, dataset_files.HDF5_LAYOUT), '',
              columns_markdown().rstrip()]
    return '\n'.join(lines + _datasheet_rest(meta)) + '\n'


def _datasheet_rest(meta):
    """The datasheet's sections after its composition."""
    return ['', '## Split',
            'Fixed by the seed, never by an outcome: the evaluation seed space (bit 62 of the '
            'seed set; doc/experiments.md, "Seed spaces") is the test split; calibration-space '
            'trials whose index is 3 modulo 4 are the validation split, the others the training '
            'split. Hidden conditions: a calibration-space trial whose specimen breathes as '
            'volunteer %s or whose bone density (its outer cortex\'s true peak over the median '
            'of the calibration specimens at its speed) lies outside %.2f-%.2f is in neither '
            '(`split.json`: `hidden`); evaluation-space ones stay in the test split (`test_hidden`), for the '
            'leaderboard\'s hidden-condition board. `split.json` lists every split\'s trial ids '
            'and seeds.' % (', '.join(str(v) for v in HIDDEN_VOLUNTEERS),
                           SEEN_DENSITY_RANGE[0], SEEN_DENSITY_RANGE[1]), '',
            '## Collection process',
            'Simulated closed-loop trials of the core engine (`campaign --samples`, '
            'core::ClosedLoopEngine), the paper\'s peak-force protocol: the recognizer observes '
            'and the drill goes through the inner cortical layer, so each trial has every layer. '
            'One seed gives the same trial bit for bit. Base seed %d. The scenario (%s):'
            % (meta['base_seed'], meta['scenario']), '', '```yaml',
            meta['scenario_yaml'].rstrip(), '```', '',
            '## Labels',
            '`layer` is the simulator\'s ground truth at the deepest cut. The task of a '
            'recognizer is to stop while the label is 3 (inner cortical): a stop at 4 is a '
            'breakthrough; a stop at 1 or 2 an early stop.', '',
            '## Known limits', dataset_files.LIMITATIONS,
            'The recognizer in the loop is the paper\'s: `averaged_force_n` is its averaging; a '
            'learned recognizer should start from `raw_force_n`.', '',
            '## Licence',
            'The data are under the package\'s licence, %s (package.xml).'
            % meta['package']['license'], '',
            '## Maintenance', croissant.MAINTENANCE, '',
            '## Reading it', '```python', 'import h5py',
            'with h5py.File("dataset.h5", "r") as f:',
            '    force = f["train/samples/raw_force_n"][:]',
            '    label, trial = f["train/samples/layer"][:], f["train/samples/trial"][:]',
            '    unit = f["train/samples/raw_force_n"].attrs["unit"]',
            'import numpy as np',
            'z = np.load("train.npz")  # the same columns',
            '# pandas: pd.DataFrame({k: z[k] for k in z.files if not k.startswith("trial_")})',
            '# PyTorch: torch.from_numpy(z["raw_force_n"])', '```']


def command_line(argv):
    """The command as the files record it: the output folder as DIR (the files do not depend on
    where they are written)."""
    words = list(argv)
    for k, word in enumerate(words):
        if word == '--out' and k + 1 < len(words):
            words[k + 1] = 'DIR'
        elif word.startswith('--out='):
            words[k] = '--out=DIR'
    return ' '.join(['campaign_dataset'] + words)


def metadata(args, scenario, scenario_text, base_seed, argv):
    """What the files say of how the dataset was made."""
    return {'command': command_line(argv if argv is not None else sys.argv[1:]),
            'scenario': os.path.basename(args.scenario), 'scenario_yaml': scenario_text,
            'protocol': Scenario(scenario).protocol, 'base_seed': base_seed,
            'seed_space_bit': SEED_SPACE_BIT.bit_length() - 1,
            'package': dataset_files.package_info()}


def parse_args(argv):
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
    return args, scenario, scenario_text


def run_campaigns(args, base_seed):
    """The calibration and evaluation campaigns with samples; their folders, or None if one
    failed."""
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
            return None
        run_dirs.append(run_dir)
    return run_dirs


def main(argv=None):
    args, scenario, scenario_text = parse_args(argv)
    base_seed = args.seed if args.seed is not None else int(Scenario(scenario).seed)
    meta = metadata(args, scenario, scenario_text, base_seed, argv)
    os.makedirs(args.out, exist_ok=True)
    run_dirs = run_campaigns(args, base_seed)
    if run_dirs is None:
        return 1
    counts, writer = assemble(run_dirs, args.out, meta)
    with atomic_write(os.path.join(args.out, dataset_files.SPLIT_NAME)) as handle:
        listing = {split: [{'trial_id': i, 'seed': s} for i, s in counts[split]['ids']]
                   for split in SPLITS}
        listing['meta'] = {'base_seed': base_seed, 'scenario': meta['scenario'],
                           'validation_modulus': VALIDATION_MODULUS,
                           'protocol': meta['protocol'], 'dataset_version': writer.version,
                           'build_id': meta['package']['build_id'],
                           'hidden_conditions': hidden_rule(counts['hidden']['references'])}
        for name in ('hidden', 'test_hidden'):
            items = counts['hidden'][name]
            listing[name] = [{'trial_id': i, 'seed': s, 'reason': r} for i, s, r in items]
        json.dump(listing, handle, indent=1)
    with atomic_write(os.path.join(args.out, dataset_files.DATASHEET_NAME)) as handle:
        handle.write(datasheet(counts, meta, writer))
    croissant.write(args.out, meta, counts, writer)
    dataset_files.write_checksums(args.out)
    for split in SPLITS:
        sys.stderr.write('campaign_dataset: %s: %d trials, %d samples\n' % (
            split, counts[split]['trials'], counts[split]['samples']))
    sys.stderr.write('campaign_dataset: version %s\n' % writer.version)
    return 0
