"""The labelled force dataset (doc/dataset.md): its one declaration (the columns, layers, frames,
splits and format version) here; its making, `campaign_dataset`, in dataset_build.py.

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
training split; the test split is the evaluation-space trials only. A calibration-space trial
under a hidden condition (HIDDEN_VOLUNTEERS, SEEN_DENSITY_RANGE) is in neither."""

import hashlib
import json
import os

import numpy as np

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
    'feed_joint': 'the drilling device\'s feed axis (URDF joint `feed_joint`, prismatic along '
                  'the drill axis): its joint position, 0 to 0.06 m of travel, positive towards '
                  'the bone',
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
    # Since 1.1.0: the rest of the whole sample the recognizer was given (its push_sample /
    # core::RecognizerSample), the thrust being raw_force_n.
    ('force_x_n', 'N', 'ft_sensor', 'the F/T sensor\'s x force as the recognizer was given it '
     '(tared, faults applied)'),
    ('force_y_n', 'N', 'ft_sensor', 'the F/T sensor\'s y force, the same'),
    ('torque_x_nm', 'N m', 'ft_sensor', 'the F/T sensor\'s torque about x as the recognizer was '
     'given it'),
    ('torque_y_nm', 'N m', 'ft_sensor', 'the F/T sensor\'s torque about y, the same'),
    ('torque_z_nm', 'N m', 'ft_sensor', 'the F/T sensor\'s torque about z, the drill axis (the '
     'cutting torque while the spindle turns), the same'),
    ('feed_depth_m', 'm', 'feed_joint', 'the feed joint\'s position as the recognizer last heard '
     'it on the joint states (NaN: not yet heard)'),
    ('spindle_rpm', 'rpm', '-', 'the spindle\'s speed as the recognizer last heard it on the '
     'joint states (NaN: not yet heard)'),
    ('feed_command_m', 'm', 'feed_joint', 'the feed joint\'s commanded position (its '
     'controller\'s desired) as the recognizer last heard it on the feed controller\'s state '
     '(NaN: not yet heard)'),
    ('tracker_stamp_s', 's', '-', 'the stamp of the tracker sample in tracker_x_m .. tracker_z_m, '
     'the one the recognizer last heard (NaN before the first)'),
]
# The sample columns a recognizer's whole sample (push_sample) is built from; a format 1.0.0
# dataset has none of them (pd_campaign.offline replays thrust-only recognizers on it).
WRENCH_COLUMNS = ('force_x_n', 'force_y_n', 'torque_x_nm', 'torque_y_nm', 'torque_z_nm',
                  'feed_depth_m', 'spindle_rpm', 'feed_command_m', 'tracker_x_m', 'tracker_y_m',
                  'tracker_z_m', 'tracker_stamp_s')
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
FORMAT_VERSION = '1.1.0'
# FORMAT_VERSION -> declaration_sha256() of the declaration above at that version: a change of the
# declaration without a new version fails test_dataset.py.
FORMAT_HISTORY = {
    '1.0.0': '81c9097c56787ad0a97dee733b36d2a61babe87b168d8c795437dd72ffb943c1',
    # 1.1.0: the whole sample the recognizer was given (force_x_n ... tracker_stamp_s,
    # WRENCH_COLUMNS) and the frame feed_joint.
    '1.1.0': 'af821055eee2b719021a9e4fdab3a6fde89f5ac36a37f9b304afe7254c9723b6',
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


# The hidden conditions: specimens whose breathing pattern or bone density the training and
# validation splits never hold. A calibration-space trial under a hidden condition is left out of
# both (split.json lists it under `hidden`); an evaluation-space one stays in the test split
# (listed under `test_hidden`) and the leaderboard's hidden-condition board is made of such
# trials. The breathing pattern is the virtual volunteer's: volunteer 4, the one whose motion
# departs most from the linear model (the widest hysteresis loop, Table II: AP R2 0.927 linear,
# doc/identification.md). The bone density is the specimen's outer-cortex true peak thrust
# (specimen_peaks; the BV/TV the simulator draws is not in trials.csv) over the reference at its
# speed: the median of the calibration-space specimens' peaks there (density_references,
# recorded in split.json's rule); a ratio outside SEEN_DENSITY_RANGE (about 1.8 sd of the
# specimens' spread each way) is hidden. Fixed by the specimen, never by an outcome.
HIDDEN_VOLUNTEERS = (4,)
SEEN_DENSITY_RANGE = (0.92, 1.08)


def specimen_peaks(rows):
    """{(rpm, seed): outer-cortex true peak [N]} of the specimens of trial rows (dicts with rpm,
    seed, case and f_out_truth_n; a seed is one specimen at a speed, whatever the case or the
    recognizer): the highest f_out_truth_n of its stationary trials (a trial stopped inside the
    outer cortex records a lower, partial peak), else of its compensated ones, else the median
    of its trials (the uncompensated thrust carries the breathing)."""
    found = {}
    for row in rows:
        try:
            value = float(row.get('f_out_truth_n'))
        except (TypeError, ValueError):
            continue
        if not np.isfinite(value):
            continue
        key = (float(row['rpm']), int(row['seed']))
        kind = {'stationary': 0, 'compensated': 1}.get(row.get('case'), 2)
        found.setdefault(key, ([], [], []))[kind].append(value)
    return {key: float(max(still) if still else max(followed) if followed else np.median(moving))
            for key, (still, followed, moving) in found.items()}


def density_references(peaks):
    """[[rpm, reference peak N]]: the median specimen peak (specimen_peaks) per speed."""
    speeds = sorted({rpm for rpm, _ in peaks})
    return [[rpm, float(np.median([v for (r, _), v in peaks.items() if r == rpm]))]
            for rpm in speeds]


def specimen_densities(rows, references=None):
    """{(rpm, seed): density ratio}: each specimen's peak over the reference at its speed
    (`references` [[rpm, N]], linear in between and held beyond the ends; default: the rows'
    own density_references)."""
    peaks = specimen_peaks(rows)
    references = references or density_references(peaks)
    if not references:
        return {}
    speeds, forces = zip(*sorted((float(r), float(f)) for r, f in references))
    return {key: value / float(np.interp(key[0], speeds, forces))
            for key, value in peaks.items()}


def hidden_reason(volunteer_id, density):
    """Why a specimen's conditions are hidden ('breathing ...', 'density ...'), or None."""
    reasons = []
    try:
        if int(volunteer_id) in HIDDEN_VOLUNTEERS:
            reasons.append('breathing of volunteer %d' % int(volunteer_id))
    except (TypeError, ValueError):
        pass
    low, high = SEEN_DENSITY_RANGE
    if density is not None and not low <= density <= high:
        reasons.append('density %.3f x the reference' % density)
    return '; '.join(reasons) or None


def hidden_rule(references):
    """The hidden conditions as split.json and the leaderboard record them, with the density
    references (density_references of the calibration-space specimens)."""
    return {'volunteers': list(HIDDEN_VOLUNTEERS), 'seen_density_range': list(SEEN_DENSITY_RANGE),
            'density_reference_n': [list(pair) for pair in references]}


def convert(kind, text):
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
