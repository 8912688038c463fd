"""The labelled force dataset (doc/dataset.md).

    rosrun pedicle_drilling campaign_dataset --out DIR [--trials N] [--test-trials M] [--large]

runs the dataset's campaign twice on the core engine with every force-sensor sample recorded
(`campaign --samples`): once on calibration seeds (the train and validation splits) and once on
evaluation seeds (the test split), and writes

- ``DIR/dataset.h5``: every split's samples and trial table, with the metadata inside as HDF5
  attributes (each column's unit, frame and meaning; the sample rates, layer labels, scenario,
  seeds, package version, build and dataset version): pd_campaign.dataset_files;
- ``DIR/train.npz``, ``DIR/validation.npz``, ``DIR/test.npz``: the same columns, one row per
  force-sensor sample (the SAMPLE_FIELDS columns, plus ``trial``: the row's index into the
  split's trial table) and the trial table (the TRIAL_FIELDS columns, prefixed ``trial_``);
  numpy.load reads them, and ``pandas.DataFrame({k: z[k] for k in SAMPLE_COLUMNS})`` or
  ``torch.from_numpy(z[k])`` take the columns as they are;
- ``DIR/split.json``: each split's trial ids and seeds (the split is fixed by the seed space and
  the trial's index, never by an outcome), and under ``meta`` the base seed, the scenario, the
  dataset version and the build;
- ``DIR/DATASHEET.md``: the fields, their units and frames, how the data were made, the counts,
  the simulator's known limits, the licence and the maintenance;
- ``DIR/croissant.json``: the Croissant 1.0 description (pd_campaign.croissant);
- ``DIR/SHA256SUMS``: the SHA-256 of each of those files (``sha256sum -c SHA256SUMS``);
- ``DIR/runs/{calibration,evaluation}/``: the two campaigns, with their reports.

The protocol is the paper's peak-force protocol (Sec. V-D): the recognizer observes and every
trial drills through the inner cortical layer, so every trial holds every layer. The split: the
calibration-space trials whose index is 3 modulo 4 form the validation split, the other ones the
training split; the test split is the evaluation-space trials only."""

import argparse
import csv
import hashlib
import json
import os
import subprocess
import sys

import numpy as np
import yaml

from pd_campaign import tools
from pd_campaign.atomic import atomic_write

PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The one declaration of the dataset's columns: the HDF5 file's attributes (dataset_files), the
# Croissant fields, the written DATASHEET.md and doc/dataset.md's generated tables all come from
# it. A change of a name, unit, frame or meaning bumps FORMAT_VERSION (see there).

# frame -> what a column's coordinates are taken in ('-': not a spatial quantity).
FRAMES = {
    '-': 'not a spatial quantity (a time, a label, a flag, a phase, a volume, a setting)',
    'ft_sensor': 'the force/torque sensor (URDF link `ft_sensor`): its z axis is the drill axis; '
                 'a thrust is the force along it, positive when the bone resists the feed',
    'bone': 'the bone specimen (URDF link `bone`): origin on the bone\'s top surface, z its '
            'outward normal; a depth is -z of the drill tip, along the drill axis (the drilling '
            'pose is perpendicular to the surface)',
    'world': 'the workcell (URDF link `world`): its z axis is the prone patient\'s '
             'anterior-posterior (AP) axis, the SPMS platform\'s heave',
    'tracker_camera': 'the tracking camera as registered (URDF link `tracker_camera`, the pose the '
                      'pipeline uses; a registration error moves the true camera from it)',
}

# (name, unit, frame, meaning) per force-sensor sample. The order is the .npy files'
# (trial_engine's kSampleFields).
SAMPLE_FIELDS = [
    ('t', 's', '-', 'simulation time (the trial starts a few seconds in)'),
    ('raw_force_n', 'N', 'ft_sensor', 'thrust the recognizer is given: the F/T sensor\'s z '
     'force, tared, at the DAQ rate, faults applied (the input of a recognizer)'),
    ('true_force_n', 'N', 'ft_sensor', 'the simulator\'s true thrust (no sensor chain, no noise)'),
    ('averaged_force_n', 'N', 'ft_sensor', 'the paper recognizer\'s latest averaged force, held '
     'between its block means (what its DrillingState publishes)'),
    ('tip_depth_m', 'm', 'bone', 'tip depth below the bone\'s top surface (negative: in front '
     'of it)'),
    ('max_depth_cut_m', 'm', 'bone', 'deepest point cut so far'),
    ('layer', '-', '-', 'the label: material at the deepest cut (see the layer labels)'),
    ('contact', '-', '-', '1 while the drill\'s lips cut, else 0'),
    ('bone_ap_m', 'm', 'world', 'true vertebra AP displacement from its home pose'),
    ('predicted_ap_m', 'm', 'world', 'the planner\'s predicted AP bone displacement since the '
     'trial\'s start (NaN before it plans)'),
    ('tracker_x_m', 'm', 'tracker_camera', 'last tracked marker position as the pipeline '
     'received it, x (NaN before the first)'),
    ('tracker_y_m', 'm', 'tracker_camera', 'the same marker position, y'),
    ('tracker_z_m', 'm', 'tracker_camera', 'the same marker position, z'),
    ('breath_phase', '-', '-', 'fraction of the current ventilator breath elapsed, [0, 1]'),
    ('tidal_volume_ml', 'ml', '-', 'patient tidal volume'),
]
SAMPLE_COLUMNS = [name for name, _, _, _ in SAMPLE_FIELDS]
# The column that ties a sample to its trial, after the sample fields.
TRIAL_COLUMN = ('trial', '-', '-', 'index of the sample\'s trial in the trial table of its split')

# label -> (name, meaning) of the `layer` column.
LAYERS = ('air', 'outer_cortical', 'cancellous', 'inner_cortical', 'canal')
LAYER_MEANINGS = (
    'no bone cut yet (the tip in front of the surface)',
    'the outer cortical shell',
    'the cancellous core',
    'the inner cortical layer: the stop layer (a stop here is correct)',
    'through the inner cortical layer (broken through: a stop here is late)',
)
INNER_CORTICAL = LAYERS.index('inner_cortical')  # the stop layer's label
CANAL = LAYERS.index('canal')  # broken through

# trials.csv column -> (numpy type, unit, frame, meaning); in the .npz files trial_<column>, in
# the HDF5 file <split>/trials/<column>.
TRIAL_FIELDS = [
    ('trial_id', str, '-', '-', 'the campaign\'s trial id (case-rpm-index)'),
    ('case', str, '-', '-', 'stationary, uncompensated or compensated (paper cases a-c)'),
    ('rpm', float, 'rpm', '-', 'spindle speed'),
    ('index', int, '-', '-', 'trial index in its campaign'),
    ('seed', np.uint64, '-', '-', 'the trial\'s seed: the same seed gives the same trial'),
    ('seed_space', str, '-', '-', 'calibration or evaluation'),
    ('volunteer_id', int, '-', '-', 'the virtual volunteer breathing under the bone'),
    ('amplitude_scale', float, '-', '-', 'the patient\'s breathing amplitude factor'),
    ('ventilator_rate_bpm', float, '1/min', '-', 'ventilator rate'),
    ('tidal_volume_ml', float, 'ml', '-', 'ventilator tidal volume setting'),
    ('force_noise_sd_n', float, 'N', 'ft_sensor', 'the sensor\'s white noise of this trial'),
    ('inner_start_mm', float, 'mm', 'bone', 'depth where the inner cortical layer starts'),
    ('inner_cortical_mm', float, 'mm', 'bone', 'inner cortical thickness'),
    ('f_out_truth_n', float, 'N', 'ft_sensor', 'true peak block-mean thrust in the outer cortex'),
    ('f_in_truth_n', float, 'N', 'ft_sensor', 'true peak block-mean thrust in the inner cortex'),
]
# The HDF5 trial table's columns that locate each trial's samples (not in the .npz files).
TRIAL_INDEX_FIELDS = [
    ('sample_start', np.int64, '-', '-', 'row of the trial\'s first sample in its split\'s '
     'samples'),
    ('sample_count', np.int64, '-', '-', 'number of the trial\'s samples (its rows are '
     'sample_start to sample_start + sample_count - 1)'),
    ('sample_rate_hz', float, 'Hz', '-', 'the trial\'s force-sample rate: 1 / the median '
     'spacing of its `t`'),
]

# The dataset's format version (semantic versioning), bumped by hand: MAJOR when a column is
# removed or renamed, or its type, unit, frame or meaning changes, or the files' layout changes
# so that a reader breaks; MINOR when a column, an attribute or a file is added; PATCH when a
# description is reworded without a change of meaning. The dataset's version is this version and
# the content hash of its values (dataset_files.dataset_version): it changes with any sample.
FORMAT_VERSION = '1.0.0'
# FORMAT_VERSION -> declaration_sha256() of the declaration above at that version: a change of the
# declaration without a new version fails test_dataset.py.
FORMAT_HISTORY = {
    '1.0.0': '81c9097c56787ad0a97dee733b36d2a61babe87b168d8c795437dd72ffb943c1',
}
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


def type_name(kind):
    """A trial field's type as the files store it: text, int64, uint64 or float64."""
    return 'text' if kind is str else np.dtype(kind).name


def declaration_sha256():
    """SHA-256 of the declaration (frames, fields, units, meanings, types of the trial table,
    layer labels): FORMAT_HISTORY keeps it per format version."""
    declared = {
        'frames': FRAMES, 'samples': SAMPLE_FIELDS + [TRIAL_COLUMN],
        'layers': list(zip(LAYERS, LAYER_MEANINGS)),
        'trials': [[name, type_name(kind), unit, frame, meaning] for name, kind, unit, frame,
                   meaning in TRIAL_FIELDS + TRIAL_INDEX_FIELDS]}
    return hashlib.sha256(json.dumps(declared, sort_keys=True).encode('utf-8')).hexdigest()


def _table(header, rows):
    return (['| %s |' % ' | '.join(header), '|' + '---|' * len(header)]
            + ['| %s |' % ' | '.join(str(cell) for cell in row) for row in rows])


def columns_markdown():
    """The tables of the columns, their units, frames and meanings, the frames and the layer
    labels, from the declaration: in DATASHEET.md and doc/dataset.md's generated block
    `dataset_columns` (scripts/dev/make_docs.py)."""
    lines = ['Per-sample columns, one row per force-sensor sample (`.npz`: `<column>`; HDF5: '
             '`/<split>/samples/<column>`):', '']
    lines += _table(('column', 'unit', 'frame', 'meaning'),
                    [('`%s`' % name, unit, frame, meaning)
                     for name, unit, frame, meaning in SAMPLE_FIELDS + [TRIAL_COLUMN]])
    lines += ['', 'Trial table, one row per trial (`.npz`: `trial_<column>`; HDF5: '
              '`/<split>/trials/<column>`; the last three in the HDF5 file only):', '']
    lines += _table(('column', '`.npz` name', 'type', 'unit', 'frame', 'meaning'),
                    [('`%s`' % name, '`trial_%s`' % name, type_name(kind), unit, frame, meaning)
                     for name, kind, unit, frame, meaning in TRIAL_FIELDS]
                    + [('`%s`' % name, '-', type_name(kind), unit, frame, meaning)
                       for name, kind, unit, frame, meaning in TRIAL_INDEX_FIELDS])
    lines += ['', 'Frames:', '']
    lines += _table(('frame', 'definition'), sorted(FRAMES.items()))
    lines += ['', 'Layer labels (`layer`):', '']
    lines += _table(('label', 'name', 'meaning'),
                    [(k, '`%s`' % name, meaning)
                     for k, (name, meaning) in enumerate(zip(LAYERS, LAYER_MEANINGS))])
    return '\n'.join(lines) + '\n'


def _trial_rows(run_dirs):
    """{split: [(trials.csv row, samples .npy path)]} in (rpm, index, case) order. A trial that
    errored is left out (its row stays in its campaign's trials.csv)."""
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
    return {split: sorted(rows, key=lambda item: (float(item[0]['rpm']), int(item[0]['index']),
                                                  item[0]['case']))
            for split, rows in tables.items()}


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
        values = [_convert(kind, row[name]) for row, _ in rows]
        arrays['trial_' + name] = np.array(values, dtype=(
            np.uint64 if kind is np.uint64 else None if kind is not str else np.str_))
    return arrays


def assemble(run_dirs, out_dir, meta):
    """Reads the campaigns' trials.csv and samples, writes the three splits as .npz files and
    the HDF5 file (dataset_files, with `meta`: main's); returns the counts {split: {'trials': n,
    'samples': n, 'cases': {case: n}, 'ids': [(trial id, seed)]}} and the finished
    dataset_files.Hdf5Writer (its version, content hash and columns)."""
    from pd_campaign import dataset_files
    tables = _trial_rows(run_dirs)
    counts = {}
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
    from pd_campaign import dataset_files
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
    from pd_campaign import croissant, dataset_files
    return ['', '## Split',
            'Fixed by the seed, never by an outcome: the evaluation seed space (bit 62 of the '
            'seed set; doc/experiments.md, "Seed spaces") is the test split; calibration-space '
            'trials whose index is 3 modulo 4 are the validation split, the others the training '
            'split. `split.json` lists every split\'s trial ids and seeds.', '',
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
    from pd_campaign import dataset_files
    from pd_campaign.design import SEED_SPACE_BIT
    return {'command': command_line(argv if argv is not None else sys.argv[1:]),
            'scenario': os.path.basename(args.scenario), 'scenario_yaml': scenario_text,
            'protocol': scenario.get('protocol', 'recognition'), 'base_seed': base_seed,
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
    from pd_campaign import croissant, dataset_files
    args, scenario, scenario_text = parse_args(argv)
    base_seed = args.seed if args.seed is not None else int(scenario.get('seed', 1))
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
                           'build_id': meta['package']['build_id']}
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
