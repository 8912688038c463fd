"""The labelled dataset's self-describing files (doc/dataset.md, "Files"): the HDF5 file with its
metadata inside, the Croissant description and the checksums.

- ``dataset.h5``: every split's samples and trial table as one-dimensional columns, each with
  its unit, frame and meaning as attributes, and the dataset's metadata as attributes of the
  root group (HDF5_LAYOUT below). One file rather than one per split: the metadata, the version
  and the checksum are those of one dataset, and a reader takes a split by its group without
  reading the others (HDF5 reads a column, or a slice of one, without the rest of the file).
- ``croissant.json``: MLCommons Croissant 1.0 JSON-LD with the responsible-AI fields: the files
  with their SHA-256, one record set per split and table, the layer labels as an enumeration.
- ``SHA256SUMS``: `sha256sum -c SHA256SUMS` checks every file of the dataset.

Everything a column says of itself comes from pd_campaign.dataset's declaration (SAMPLE_FIELDS,
TRIAL_FIELDS, TRIAL_INDEX_FIELDS, FRAMES, LAYERS). The HDF5 file is written without timestamps,
so the same trials give the same file bit for bit."""
import contextlib
import hashlib
import json
import os
import subprocess
import xml.etree.ElementTree as ElementTree

import numpy as np

from pd_campaign import dataset, tools
from pd_campaign.atomic import atomic_path, atomic_write

HDF5_NAME = 'dataset.h5'
CROISSANT_NAME = 'croissant.json'
CHECKSUMS_NAME = 'SHA256SUMS'
DATASHEET_NAME = 'DATASHEET.md'
SPLIT_NAME = 'split.json'
# The files SHA256SUMS covers (croissant.json lists all but itself), with their media types.
MEDIA_TYPES = [(HDF5_NAME, 'application/x-hdf5')] + [
    ('%s.npz' % split, 'application/zip') for split in dataset.SPLITS] + [
    (SPLIT_NAME, 'application/json'), (DATASHEET_NAME, 'text/markdown')]
HDF5_LAYOUT = ('for each split (train, validation, test), `/<split>/samples/<column>` holds one '
               'row per force-sensor sample (the per-sample columns and `trial`) and '
               '`/<split>/trials/<column>` one row per trial (the trial table and where its '
               'samples are)')
SPDX_URL = 'https://spdx.org/licenses/%s.html'
SIMULATOR_PHYSICS = 'doc/simulator_physics.md'


def package_info():
    """{'name', 'version', 'license', 'maintainer', 'build_id', 'build_digest'} of the package
    that makes the data: package.xml of the package's folder (rospack's, else this source
    tree's); build_id the git commit of that folder (with -dirty when tracked files differ from
    it), "unknown" outside a git checkout; build_digest tools.build_id() (the executables,
    libraries and Python sources), "unknown" when trial_engine is not found in a folder."""
    try:
        folder = tools.package_dir()
    except tools.PackageNotFound:
        folder = dataset.PACKAGE_ROOT
    manifest = os.path.realpath(os.path.join(folder, 'package.xml'))
    root = ElementTree.parse(manifest).getroot()
    info = {key: (root.findtext(key) or '').strip()
            for key in ('name', 'version', 'license', 'maintainer')}
    info['build_id'] = git_commit(os.path.dirname(manifest))
    info['build_digest'] = tools.build_id() or 'unknown'
    return info


def git_commit(folder):
    """The commit checked out in `folder`'s git work tree, with '-dirty' when a tracked file
    differs from it; 'unknown' when there is none (no git, not a checkout)."""
    def git(*args):
        return subprocess.run(['git', '-C', folder] + list(args), capture_output=True,
                              text=True, timeout=60)
    try:
        head = git('rev-parse', '--verify', 'HEAD')
        if head.returncode != 0:
            return 'unknown'
        status = git('status', '--porcelain', '--untracked-files=no')
    except (OSError, subprocess.SubprocessError):
        return 'unknown'
    dirty = status.returncode != 0 or status.stdout.strip()
    return head.stdout.strip() + ('-dirty' if dirty else '')


def update_content_digest(digest, path, values):
    """`digest` (hashlib) updated with one column, as doc/dataset.md defines the content hash:
    the line `<path> <type> <length>\\n`, then the values: numbers as the little-endian bytes of
    their type (type: the NumPy type string, e.g. <f8), text (type: text) as UTF-8 joined by NUL."""
    values = np.asarray(values)
    if values.dtype.kind in 'OUS':
        kind, data = 'text', '\0'.join(str(v) for v in values).encode('utf-8')
    else:
        little = values.astype(values.dtype.newbyteorder('<'), copy=False)
        kind, data = little.dtype.str, np.ascontiguousarray(little).tobytes()
    digest.update(('%s %s %d\n' % (path, kind, len(values))).encode('utf-8'))
    digest.update(data)


def dataset_version(content_sha256):
    """The dataset's version: FORMAT_VERSION, then as semantic versioning's build metadata the
    first 12 hex digits of the content hash (changes with any sample)."""
    return '%s+%s' % (dataset.FORMAT_VERSION, content_sha256[:12])


def trial_index(trial, t, trials):
    """{sample_start, sample_count, sample_rate_hz} of each of `trials` trials of a split whose
    samples' trial column is `trial` (in trial order) and time column `t`."""
    start = np.searchsorted(trial, np.arange(trials), side='left').astype(np.int64)
    end = np.searchsorted(trial, np.arange(trials), side='right').astype(np.int64)
    rates = []
    for a, b in zip(start, end):
        steps = np.diff(t[a:b])
        rates.append(round(1.0 / float(np.median(steps)), 6) if len(steps) else float('nan'))
    return {'sample_start': start, 'sample_count': end - start,
            'sample_rate_hz': np.array(rates, dtype=np.float64)}


def _group(parent, name):
    """A new group of `parent` that keeps its members in creation order, without timestamps."""
    import h5py
    gcpl = h5py.h5p.create(h5py.h5p.GROUP_CREATE)
    gcpl.set_obj_track_times(False)
    gcpl.set_link_creation_order(h5py.h5p.CRT_ORDER_TRACKED | h5py.h5p.CRT_ORDER_INDEXED)
    h5py.h5g.create(parent.id, name.encode('utf-8'), gcpl=gcpl)
    return parent[name]


class Hdf5Writer:
    """Writes the splits into an open h5py.File, hashing every value as it goes; `finish`
    writes the content hash and the version. `columns` holds {split: {'samples'|'trials':
    [(name, numpy kind or 'text')]}} for the Croissant file."""

    def __init__(self, h5, meta):
        self.h5, self.digest, self.rates, self.columns = h5, hashlib.sha256(), set(), {}
        self.content_sha256 = self.version = None
        for key, value in root_attributes(meta).items():
            h5.attrs[key] = value

    def _column(self, group, name, values, unit, frame, meaning):
        import h5py
        values = np.asarray(values)
        if values.dtype.kind in 'OUS':
            data, options = np.array([str(v) for v in values], dtype=object), {}
            options['dtype'] = h5py.string_dtype('utf-8')
        else:
            data = values.astype(values.dtype.newbyteorder('<'), copy=False)
            options = dict(compression='gzip', compression_opts=4, shuffle=True) if len(data) \
                else {}
        column = group.create_dataset(name, data=data, track_times=False, **options)
        column.attrs.update({'unit': unit, 'frame': frame, 'description': meaning})
        path = group.name.strip('/') + '/' + name
        update_content_digest(self.digest, path, data)
        split, table = path.split('/')[:2]
        self.columns.setdefault(split, {}).setdefault(table, []).append(
            (name, 'text' if values.dtype.kind in 'OUS' else values.dtype.kind))
        return column

    def add_split(self, split, arrays):
        """One split, from its .npz arrays (the sample columns, `trial`, `trial_<field>`)."""
        group = _group(self.h5, split)
        samples, trials = _group(group, 'samples'), _group(group, 'trials')
        for name, unit, frame, meaning in dataset.SAMPLE_FIELDS + [dataset.TRIAL_COLUMN]:
            self._column(samples, name, arrays[name], unit, frame, meaning)
        samples['layer'].attrs['labels'] = json.dumps(layer_labels())
        count = len(arrays['trial_trial_id'])
        for name, _, unit, frame, meaning in dataset.TRIAL_FIELDS:
            self._column(trials, name, arrays['trial_' + name], unit, frame, meaning)
        index = trial_index(arrays['trial'], arrays['t'], count)
        for name, _, unit, frame, meaning in dataset.TRIAL_INDEX_FIELDS:
            self._column(trials, name, index[name], unit, frame, meaning)
        rates = sorted({float(r) for r in index['sample_rate_hz'] if np.isfinite(r)})
        self.rates.update(rates)
        group.attrs.update({'seed_space': 'evaluation' if split == 'test' else 'calibration',
                            'trials': count, 'samples': len(arrays['trial']),
                            'sample_rates_hz': np.array(rates, dtype=np.float64)})

    def finish(self):
        self.content_sha256 = self.digest.hexdigest()
        self.version = dataset_version(self.content_sha256)
        self.h5.attrs.update({'content_sha256': self.content_sha256,
                              'dataset_version': self.version,
                              'sample_rates_hz': np.array(sorted(self.rates), dtype=np.float64)})


@contextlib.contextmanager
def hdf5_writer(path, meta):
    """An Hdf5Writer on a new HDF5 file at `path`, written through a temporary file and renamed
    when the block ends normally (pd_campaign.atomic); finished before the rename."""
    import h5py
    with atomic_path(path) as tmp:
        fcpl = h5py.h5p.create(h5py.h5p.FILE_CREATE)
        fcpl.set_obj_track_times(False)
        fcpl.set_link_creation_order(h5py.h5p.CRT_ORDER_TRACKED | h5py.h5p.CRT_ORDER_INDEXED)
        with h5py.File(h5py.h5f.create(tmp.encode('utf-8'), h5py.h5f.ACC_TRUNC, fcpl=fcpl)) as h5:
            writer = Hdf5Writer(h5, meta)
            yield writer
            writer.finish()


def layer_labels():
    """{label: {'name', 'meaning'}} of the `layer` column (JSON keys are text)."""
    return {str(k): {'name': name, 'meaning': meaning}
            for k, (name, meaning) in enumerate(zip(dataset.LAYERS, dataset.LAYER_MEANINGS))}


def root_attributes(meta):
    """The root group's attributes before the data: what the dataset is, what made it, how it is
    split, its frames and labels (`meta`: dataset_build.main's)."""
    package = meta['package']
    return {
        'title': TITLE, 'description': DESCRIPTION, 'format_version': dataset.FORMAT_VERSION,
        'layout': HDF5_LAYOUT, 'splits': list(dataset.SPLITS),
        'package': package['name'], 'package_version': package['version'],
        'license': package['license'], 'build_id': package['build_id'],
        'build_digest': package['build_digest'], 'command': meta['command'],
        'scenario': meta['scenario'], 'scenario_yaml': meta['scenario_yaml'],
        'protocol': meta['protocol'],
        'base_seed': (np.uint64 if meta['base_seed'] >= 0 else np.int64)(meta['base_seed']),
        'seed_space_bit': meta['seed_space_bit'],
        'split_seed_spaces': json.dumps({split: 'evaluation' if split == 'test' else 'calibration'
                                         for split in dataset.SPLITS}),
        'validation_modulus': dataset.VALIDATION_MODULUS,
        'layer_labels': json.dumps(layer_labels()), 'frames': json.dumps(dataset.FRAMES),
        'datasheet': '%s beside this file; doc/dataset.md of the package' % DATASHEET_NAME,
        'limitations': LIMITATIONS,
    }


TITLE = 'Simulated pedicle-drilling force dataset'
DESCRIPTION = (
    'Every force-sensor sample of simulated robot-assisted pedicle drilling trials on a vertebra '
    'that moves with breathing, labelled with the bone layer at the deepest cut (air, outer '
    'cortical, cancellous, inner cortical, canal), with the true thrust, the depth, the bone\'s '
    'motion and what the pipeline knew (the paper recognizer\'s average, the planner\'s '
    'prediction, the tracker). Train a drilling-state recognizer on the train split, choose its '
    'settings on the validation split, report on the test split (other seeds).')
LIMITATIONS = (
    'Simulated, not measured. Not modelled: tissue other than the three-layer bone (no soft '
    'tissue, no pedicle geometry or oblique entry: a one-dimensional force law along the drill '
    'axis), bone texture beyond the drawn layer thicknesses, densities and noise, drill wear, '
    'heating, chip clogging, more than one drill and feed rate, vibration, acoustic or motor '
    'current channels, and patient motion other than breathing (the AP axis moves the bone; '
    'a small drift, cardiac component and small movements are drawn). Each constant of the force '
    'model, the sensor chain and the specimens, with its source or marked as an assumption: '
    + SIMULATOR_PHYSICS + ' of the package.')


def sha256_of(path):
    digest = hashlib.sha256()
    tools.update_digest(digest, path)
    return digest.hexdigest()


def write_checksums(out_dir):
    """SHA256SUMS of the dataset's files and its Croissant file, as `sha256sum` writes it (the
    format `sha256sum -c` reads); returns {name: sha256} of the files."""
    names = [name for name, _ in MEDIA_TYPES] + [CROISSANT_NAME]
    sums = {name: sha256_of(os.path.join(out_dir, name)) for name in names}
    with atomic_write(os.path.join(out_dir, CHECKSUMS_NAME)) as handle:
        handle.write(''.join('%s  %s\n' % (sums[name], name) for name in names))
    return sums
