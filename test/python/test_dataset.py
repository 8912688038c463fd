"""The labelled force dataset: written by campaign_dataset, read back with numpy and with h5py
alone; the split by seed space; the labels against the ground truth; recording samples changes no
trial; the HDF5 attributes, the Croissant description, the checksums and doc/dataset.md's tables
against the one declaration of the columns; the dataset version."""
import csv
import hashlib
import json
import os
import re
import subprocess
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest

from pd_campaign import dataset
from pd_campaign.design import SEED_SPACE_BIT

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def _rows(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def test_the_splits_are_fixed_by_the_seed_space_and_the_index(small_dataset):
    splits = {name: np.load(small_dataset / (name + '.npz')) for name in dataset.SPLITS}
    assert [len(splits[s]['trial_trial_id']) for s in dataset.SPLITS] == [9, 3, 3]
    for name, z in splits.items():
        seeds = [int(s) for s in z['trial_seed']]
        evaluation = [bool(s & SEED_SPACE_BIT) for s in seeds]
        assert all(evaluation) if name == 'test' else not any(evaluation), name
        assert set(z['trial_seed_space']) == {'evaluation' if name == 'test' else 'calibration'}
        for index in z['trial_index']:
            assert dataset.split_of(
                'evaluation' if name == 'test' else 'calibration', int(index)) == name
        assert sorted(set(z['trial_case'])) == ['compensated', 'stationary', 'uncompensated']
    seeds = [{int(x) for x in splits[s]['trial_seed']} for s in dataset.SPLITS]
    assert not (seeds[0] & seeds[1]) and not (seeds[0] & seeds[2]) and not (seeds[1] & seeds[2])
    with open(small_dataset / 'split.json') as handle:
        listed = json.load(handle)
    for name, z in splits.items():
        assert [t['trial_id'] for t in listed[name]] == list(z['trial_trial_id'])
    # No training or validation trial under a hidden condition; the rule is recorded; a test
    # trial under one is listed.
    rule = listed['meta']['hidden_conditions']
    assert rule == dataset.hidden_rule(rule['density_reference_n'])
    assert [rpm for rpm, _ in rule['density_reference_n']] == [12000.0]
    for name in ('train', 'validation'):
        z = splits[name]
        rows = [{'rpm': r, 'seed': int(s), 'case': c, 'f_out_truth_n': f} for r, s, c, f in zip(
            z['trial_rpm'], z['trial_seed'], z['trial_case'], z['trial_f_out_truth_n'])]
        densities = dataset.specimen_densities(rows, rule['density_reference_n'])
        for row, volunteer in zip(rows, z['trial_volunteer_id']):
            assert dataset.hidden_reason(volunteer, densities[(row['rpm'], row['seed'])]) is None
    assert {t['trial_id'] for t in listed['test_hidden']} <= set(splits['test']['trial_trial_id'])
    assert listed['hidden'] == []  # none of the fixture's calibration specimens


def test_the_columns_read_back_with_numpy_and_the_labels_are_the_ground_truth(small_dataset):
    z = np.load(small_dataset / 'train.npz')
    for name in dataset.SAMPLE_COLUMNS + ['trial']:
        assert name in z.files, name
    n = len(z['trial'])
    assert all(len(z[name]) == n for name in dataset.SAMPLE_COLUMNS)
    assert n > 9 * 3000  # about 30 s per trial at 1000/3 Hz
    layer, depth, trial = z['layer'], z['max_depth_cut_m'], z['trial']
    assert set(np.unique(layer)) <= set(range(len(dataset.LAYERS)))
    for k in range(len(z['trial_trial_id'])):
        rows = trial == k
        assert rows.any()
        t = z['t'][rows]
        assert np.all(np.diff(t) > 0), 'samples of a trial in time order'
        # The peak-force protocol drills through: every layer in every trial, in order.
        seen = layer[rows]
        assert list(np.unique(seen)) == [0, 1, 2, 3, 4], z['trial_trial_id'][k]
        assert np.all(np.diff(seen) >= 0), 'the deepest cut only goes deeper'
        inner_start = z['trial_inner_start_mm'][k] / 1000.0
        inner = rows & (layer == 3)
        assert np.all(depth[inner] >= inner_start - 1e-9)
        assert np.all(depth[rows & (layer <= 2)] <= inner_start + 1e-9)
        # The input of a recognizer is the sensor's view of the true thrust: close on average
        # in the cortices (tare, noise and the anti-alias filter's lag apart).
        cortical = rows & (layer == 1) & (z['contact'] == 1)
        assert abs(np.mean(z['raw_force_n'][cortical] - z['true_force_n'][cortical])) < 0.3
    assert np.all((z['breath_phase'] >= 0) & (z['breath_phase'] <= 1))
    moving = np.isin(trial, np.flatnonzero(z['trial_case'] != 'stationary'))
    assert np.ptp(z['bone_ap_m'][moving]) > 1e-3, 'the vertebra breathes in the moving cases'
    assert np.isfinite(z['tracker_x_m'][-1])


def test_the_datasheet_lists_every_field_and_the_counts(small_dataset):
    text = (small_dataset / 'DATASHEET.md').read_text()
    for name in dataset.SAMPLE_COLUMNS:
        assert '`%s`' % name in text, name
    for name, _, _, _, _ in dataset.TRIAL_FIELDS:
        assert '`trial_%s`' % name in text, name
    z = np.load(small_dataset / 'test.npz')
    assert '| test | 3 | %d |' % len(z['trial']) in text
    assert 'protocol: peak_forces' in text


def test_recording_the_samples_changes_no_trial(small_dataset, tmp_path):
    run = small_dataset / 'runs' / 'evaluation'
    out = tmp_path / 'plain'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--scenario',
         os.path.join(ROOT, 'config', 'scenario_dataset.yaml'), '--seed-space', 'evaluation',
         '--trials', '1', '--rpm', '12000', '--jobs', '2', '--out', str(out)],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with_samples, plain = _rows(run / 'trials.csv'), _rows(out / 'trials.csv')
    for row in with_samples + plain:
        row.pop('wall_s')
    assert with_samples == plain
    assert not (out / 'samples').exists()


def test_bad_arguments_are_refused(tmp_path):
    result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign_dataset', '--out',
                             str(tmp_path / 'x'), '--trials', '2'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and '--trials' in result.stderr
    result = subprocess.run(['rosrun', 'pedicle_drilling', 'campaign', '--samples', '--engine',
                             'ros', '--out', str(tmp_path / 'y')],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode != 0 and '--samples' in result.stderr


# --- the HDF5 file, the Croissant description, the checksums, the version ----------------------

PAGE = os.path.join(ROOT, 'doc', 'dataset.md')

# Reads a written dataset with h5py, numpy and the standard library only, run as `python3 -I`
# (no PYTHONPATH: pd_campaign cannot be imported): the HDF5 attributes against doc/dataset.md's
# generated tables, every column against the .npz files, the content hash recomputed as the page
# defines it. Prints what the test compares further (JSON).
READER = r'''
import hashlib, json, sys
import h5py
import numpy as np

folder, page = sys.argv[1], sys.argv[2]
try:
    import pd_campaign  # noqa: F401
    sys.exit('the reader could import pd_campaign')
except ImportError:
    pass


def tables(path):
    """The rows (lists of cells) of each table of the page's generated column block."""
    text = open(path, encoding='utf-8').read()
    block = text.split('<!-- generated: dataset_columns -->')[1].split('<!-- end generated -->')[0]
    found, rows = [], None
    for line in block.splitlines():
        if not line.startswith('|'):
            rows = None
            continue
        if rows is None:
            rows = []
            found.append(rows)
        elif not set(line) <= set('|- '):
            rows.append([cell.strip() for cell in line.strip().strip('|').split('|')])
    return found


def plain(cell):
    return cell.strip('`')


def digest_column(digest, path, values):
    if values.dtype.kind == 'O':
        kind, data = 'text', '\0'.join(values).encode('utf-8')
    else:
        kind, data = values.dtype.str, np.ascontiguousarray(values).tobytes()
    digest.update(('%s %s %d\n' % (path, kind, len(values))).encode('utf-8'))
    digest.update(data)


def same(a, b):
    if a.dtype.kind in 'fc':
        return np.array_equal(a, b, equal_nan=True)
    return [str(x) for x in a] == [str(x) for x in b]


sample_rows, trial_rows, frame_rows, layer_rows = tables(page)
with h5py.File(folder + '/dataset.h5', 'r') as f:
    a = f.attrs
    assert json.loads(a['frames']) == {plain(r[0]): r[1] for r in frame_rows}
    assert json.loads(a['layer_labels']) == {
        r[0]: {'name': plain(r[1]), 'meaning': r[2]} for r in layer_rows}
    digest, rates = hashlib.sha256(), set()
    for split in a['splits']:
        z = np.load('%s/%s.npz' % (folder, split))
        for table, rows in (('samples', sample_rows), ('trials', trial_rows)):
            group = f[split][table]
            assert list(group) == [plain(r[0]) for r in rows], (split, table, list(group))
            for row in rows:
                column = group[plain(row[0])]
                text = h5py.check_string_dtype(column.dtype) is not None
                values = column.asstr()[:] if text else column[:]
                declared = row[1:4] if table == 'samples' else row[3:6]
                assert [column.attrs[k] for k in ('unit', 'frame', 'description')] == declared, \
                    (split, table, row)
                if table == 'trials':
                    assert (row[2] == 'text') if text else (np.dtype(row[2]) == column.dtype), row
                digest_column(digest, '%s/%s/%s' % (split, table, plain(row[0])), values)
                npz_name = plain(row[0]) if table == 'samples' else plain(row[1])
                if npz_name != '-':
                    assert same(values, z[npz_name]), (split, npz_name)
        trials = f[split]['trials']
        trial = z['trial']
        for k, (start, count) in enumerate(zip(trials['sample_start'][:],
                                               trials['sample_count'][:])):
            assert count > 0 and np.all(trial[start:start + count] == k), (split, k)
        assert trials['sample_count'][:].sum() == len(trial) == f[split].attrs['samples']
        assert f[split].attrs['trials'] == len(z['trial_trial_id'])
        rates |= set(trials['sample_rate_hz'][:].tolist())
    content = digest.hexdigest()
    assert a['content_sha256'] == content
    assert a['dataset_version'] == '%s+%s' % (a['format_version'], content[:12])
    assert sorted(rates) == sorted(a['sample_rates_hz'].tolist())
    layers = f['train/samples/layer'].attrs['labels']
    print(json.dumps({
        key: (a[key].tolist() if hasattr(a[key], 'tolist') else a[key])
        for key in a if key not in ('splits', 'sample_rates_hz')} | {
        'sample_rates_hz': a['sample_rates_hz'].tolist(), 'splits': list(a['splits']),
        'layer_column_labels': layers}))
'''


def _package_xml():
    root = ElementTree.parse(os.path.join(ROOT, 'package.xml')).getroot()
    return {key: root.findtext(key).strip() for key in ('name', 'version', 'license')}


def test_the_hdf5_file_reads_back_with_h5py_alone(small_dataset):
    result = subprocess.run(['/usr/bin/python3', '-I', '-c', READER, str(small_dataset), PAGE],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    attrs = json.loads(result.stdout)
    package = _package_xml()
    assert (attrs['package'], attrs['package_version'], attrs['license']) == (
        package['name'], package['version'], package['license'])
    assert re.fullmatch(r'[0-9a-f]{40}(-dirty)?|unknown', attrs['build_id']), attrs['build_id']
    assert re.fullmatch(r'[0-9a-f]{16}|unknown', attrs['build_digest'])
    assert attrs['format_version'] == dataset.FORMAT_VERSION
    assert attrs['splits'] == list(dataset.SPLITS)
    with open(small_dataset / 'split.json') as handle:
        meta = json.load(handle)['meta']
    assert attrs['base_seed'] == meta['base_seed'] == 3201
    assert attrs['dataset_version'] == meta['dataset_version']
    assert attrs['scenario'] == 'scenario_dataset.yaml' == meta['scenario']
    with open(os.path.join(ROOT, 'config', 'scenario_dataset.yaml')) as handle:
        assert attrs['scenario_yaml'] == handle.read()
    assert attrs['protocol'] == 'peak_forces'
    assert json.loads(attrs['split_seed_spaces']) == {
        'train': 'calibration', 'validation': 'calibration', 'test': 'evaluation'}
    assert 1 << attrs['seed_space_bit'] == SEED_SPACE_BIT
    assert attrs['sample_rates_hz'] == [pytest.approx(1000.0 / 3, abs=1e-5)]
    assert json.loads(attrs['layer_column_labels'])['3']['name'] == 'inner_cortical'
    assert '--out DIR' in attrs['command'] and str(small_dataset) not in attrs['command']
    assert 'simulator_physics.md' in attrs['limitations']


def _sha256(path):
    digest = hashlib.sha256()
    with open(path, 'rb') as handle:
        digest.update(handle.read())
    return digest.hexdigest()


def test_the_checksums_cover_every_file(small_dataset):
    lines = (small_dataset / 'SHA256SUMS').read_text().splitlines()
    listed = dict(reversed(re.fullmatch(r'([0-9a-f]{64})  (\S+)', line).groups())
                  for line in lines)
    assert sorted(listed) == sorted(['dataset.h5', 'train.npz', 'validation.npz', 'test.npz',
                                     'split.json', 'DATASHEET.md', 'croissant.json'])
    for name, digest in listed.items():
        assert _sha256(small_dataset / name) == digest, name


RAI_FIELDS = ('rai:dataCollection', 'rai:dataCollectionType', 'rai:dataLimitations',
              'rai:dataBiases', 'rai:personalSensitiveInformation', 'rai:dataUseCases',
              'rai:dataReleaseMaintenance', 'rai:annotationProtocol')


def _croissant_fields(document):
    """{field @id: field} of every record set, checked for the keys a field must have."""
    fields = {}
    for record_set in document['recordSet']:
        assert record_set['@type'] == 'cr:RecordSet' and record_set['name'] == record_set['@id']
        assert record_set['description'] and record_set['field']
        for field in record_set['field']:
            assert field['@type'] == 'cr:Field'
            assert field['@id'] == '%s/%s' % (record_set['@id'], field['name'])
            assert field['dataType'] in ('sc:Float', 'sc:Integer', 'sc:Text', 'sc:Boolean')
            assert field['description'], field['@id']
            assert field['@id'] not in fields
            fields[field['@id']] = field
    return fields


def test_the_croissant_file_describes_the_files_and_every_column(small_dataset):
    import h5py
    with open(small_dataset / 'croissant.json') as handle:
        document = json.load(handle)
    context = document['@context']
    assert context['@vocab'] == 'https://schema.org/' and context['sc'] == 'https://schema.org/'
    assert context['cr'] == 'http://mlcommons.org/croissant/'
    assert context['rai'] == 'http://mlcommons.org/croissant/RAI/'
    assert document['@type'] == 'sc:Dataset'
    assert document['conformsTo'] == 'http://mlcommons.org/croissant/1.0'
    for key in ('name', 'description', 'license', 'version', 'citeAs'):
        assert isinstance(document[key], str) and document[key], key
    assert document['license'] == 'https://spdx.org/licenses/%s.html' % _package_xml()['license']
    assert re.fullmatch(r'\d+\.\d+\.\d+\+[0-9a-f]{12}', document['version'])
    assert document['citeAs'].startswith('@misc{') and document['version'] in document['citeAs']
    for key in RAI_FIELDS:
        assert document[key], key
    assert 'simulator_physics.md' in document['rai:dataLimitations']
    files = {entry['@id']: entry for entry in document['distribution']}
    assert sorted(files) == sorted(['dataset.h5', 'train.npz', 'validation.npz', 'test.npz',
                                    'split.json', 'DATASHEET.md'])
    for name, entry in files.items():
        assert entry['@type'] == 'cr:FileObject' and entry['contentUrl'] == name
        assert entry['sha256'] == _sha256(small_dataset / name), name
        assert entry['contentSize'] == '%d B' % os.path.getsize(small_dataset / name)
    assert files['dataset.h5']['encodingFormat'] == 'application/x-hdf5'
    fields = _croissant_fields(document)
    with h5py.File(small_dataset / 'dataset.h5', 'r') as f:
        assert document['version'] == f.attrs['dataset_version']
        columns = [field for field in fields.values() if 'source' in field]
        for field in columns:
            assert field['source']['fileObject']['@id'] == 'dataset.h5'
            column = f[field['source']['extract']['column']]
            assert 'Unit: %s. Frame: %s.' % (column.attrs['unit'], column.attrs['frame']) \
                in field['description'], field['@id']
        assert len(columns) == sum(len(f[s][t]) for s in f.attrs['splits']
                                   for t in ('samples', 'trials'))
    for field in fields.values():
        if 'references' in field:
            assert field['references']['field']['@id'] in fields
    layers = next(r for r in document['recordSet'] if r['@id'] == 'layers')
    assert [row['layers/name'] for row in layers['data']] == list(dataset.LAYERS)
    try:
        import mlcroissant
    except ImportError:
        return  # not in Debian 12: the checks above stand for it
    mlcroissant.Dataset(jsonld=str(small_dataset / 'croissant.json'))  # raises on an error


def test_the_page_tables_are_the_declaration():
    with open(PAGE) as handle:
        text = handle.read()
    block = text.split('<!-- generated: dataset_columns -->\n')[1].split(
        '<!-- end generated -->')[0]
    assert block == dataset.columns_markdown(), 'doc/dataset.md: run make docs'


def _semver(version):
    return tuple(int(x) for x in version.split('.'))


def test_a_change_of_the_declaration_needs_a_new_format_version():
    history = dataset.FORMAT_HISTORY
    assert history[dataset.FORMAT_VERSION] == dataset.declaration_sha256(), (
        'the declaration of the columns changed: bump FORMAT_VERSION (dataset.py says how) and '
        'add %r: %r to FORMAT_HISTORY' % ('NEW.VERSION', dataset.declaration_sha256()))
    assert max(history, key=_semver) == dataset.FORMAT_VERSION
    assert len(set(history.values())) == len(history)


def _write_tiny(path, raw_force):
    """A one-trial, three-sample dataset through the HDF5 writer; its version."""
    from pd_campaign import dataset_files
    arrays = {name: np.arange(3, dtype=np.float64) for name in dataset.SAMPLE_COLUMNS}
    arrays.update(raw_force_n=np.array(raw_force), layer=np.array([0, 1, 3], np.int32),
                  contact=np.array([0, 1, 1], np.uint8), trial=np.zeros(3, np.int32))
    for name, kind, _, _, _ in dataset.TRIAL_FIELDS:
        arrays['trial_' + name] = np.array(['x' if kind is str else 1], dtype=(
            np.str_ if kind is str else kind))
    meta = {'command': 'campaign_dataset --out DIR', 'scenario': 's.yaml', 'scenario_yaml': 'x',
            'protocol': 'peak_forces', 'base_seed': 1, 'seed_space_bit': 62,
            'package': {'name': 'pedicle_drilling', 'version': '0', 'license': 'BSD-3-Clause',
                        'build_id': 'unknown', 'build_digest': 'unknown'}}
    with dataset_files.hdf5_writer(str(path), meta) as writer:
        for split in dataset.SPLITS:
            writer.add_split(split, arrays)
    return writer.version


def test_the_dataset_version_changes_with_any_sample_and_only_then(tmp_path):
    first = _write_tiny(tmp_path / 'a.h5', [0.0, 1.0, 2.0])
    assert first.startswith(dataset.FORMAT_VERSION + '+')
    assert _write_tiny(tmp_path / 'b.h5', [0.0, 1.0, 2.0]) == first
    assert (tmp_path / 'a.h5').read_bytes() == (tmp_path / 'b.h5').read_bytes(), \
        'the same values give the same file (no timestamps)'
    assert _write_tiny(tmp_path / 'c.h5', [0.0, 1.0, 2.0 + 1e-12]) != first
    assert sorted(os.listdir(tmp_path)) == ['a.h5', 'b.h5', 'c.h5']
