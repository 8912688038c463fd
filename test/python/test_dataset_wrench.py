"""The dataset's whole sample (format 1.1.0): the sensor's whole wrench and the drill's context
as the recognizer was given them, in the .npz files, the HDF5 file (read with h5py alone) and
the Croissant description; the offline replay gives them to a push_sample recognizer (in Python,
pd_campaign.offline, and through the `recognize` tool the leaderboard tunes with), and a format
1.0.0 dataset (the thrust only) still replays a thrust-only recognizer and refuses a push_sample
one, naming the missing columns."""
import json
import subprocess

import numpy as np
import pytest

from pd_campaign import api, dataset, offline

UNITS = {'force_x_n': 'N', 'force_y_n': 'N', 'torque_x_nm': 'N m', 'torque_y_nm': 'N m',
         'torque_z_nm': 'N m', 'feed_depth_m': 'm', 'spindle_rpm': 'rpm', 'feed_command_m': 'm',
         'tracker_stamp_s': 's'}


def test_the_declaration_holds_the_whole_sample():
    assert dataset.FORMAT_VERSION == '1.1.0'
    # The columns 1.1.0 adds, after the 1.0.0 ones; the whole sample also reads the tracker's.
    assert dataset.SAMPLE_COLUMNS[15:] == list(UNITS)
    assert set(dataset.WRENCH_COLUMNS) == set(UNITS) | {'tracker_x_m', 'tracker_y_m',
                                                       'tracker_z_m'}
    declared = {name: (unit, frame) for name, unit, frame, _ in dataset.SAMPLE_FIELDS}
    for name, unit in UNITS.items():
        assert declared[name][0] == unit, name
        assert declared[name][1] in dataset.FRAMES, name
    # The 1.0.0 columns first, in their order: a 1.0.0 reader's columns keep their places.
    assert dataset.SAMPLE_COLUMNS[:15] == [
        't', 'raw_force_n', 'true_force_n', 'averaged_force_n', 'tip_depth_m', 'max_depth_cut_m',
        'layer', 'contact', 'bone_ap_m', 'predicted_ap_m', 'tracker_x_m', 'tracker_y_m',
        'tracker_z_m', 'breath_phase', 'tidal_volume_ml']


def test_the_npz_files_carry_the_wrench_and_the_context(small_dataset):
    z = np.load(small_dataset / 'train.npz')
    for name in UNITS:
        assert z[name].dtype == np.float64 and len(z[name]) == len(z['t']), name
    cutting = (z['contact'] == 1) & (z['layer'] == 1)
    thrust, torque = z['raw_force_n'][cutting], z['torque_z_nm'][cutting]
    # Tz = 1.6 * 1.25 mm * thrust while the spindle turns (doc/simulator_physics.md §2c), the
    # sensor's noise and tare apart: its sign and size follow the thrust.
    assert np.median(torque) > 0.002
    assert np.median(torque / thrust) == pytest.approx(0.002, rel=0.2)
    rpm = z['spindle_rpm'][cutting]
    assert np.all(np.isfinite(rpm)) and np.median(rpm) == pytest.approx(12000.0, rel=0.01)
    feed = z['feed_depth_m'][cutting]
    assert np.all(np.isfinite(feed)) and np.all((feed >= -1e-6) & (feed <= 0.06 + 1e-6))
    for k in range(len(z['trial_trial_id'])):
        rows = cutting & (z['trial'] == k)
        assert z['feed_depth_m'][rows][-1] > z['feed_depth_m'][rows][0], 'the feed advances'
    assert np.all(np.isfinite(z['force_x_n'])) and np.all(np.isfinite(z['torque_x_nm']))


# Reads the new columns' attributes with h5py alone (`python3 -I`: pd_campaign not importable).
READER = r'''
import json, sys
import h5py
with h5py.File(sys.argv[1], 'r') as f:
    out = {'format_version': str(f.attrs['format_version']),
           'frames': json.loads(f.attrs['frames'])}
    for split in f.attrs['splits']:
        samples = f[split]['samples']
        out[split] = {name: [str(samples[name].attrs['unit']), str(samples[name].attrs['frame']),
                             str(samples[name].dtype), int(samples[name].shape[0])]
                      for name in samples}
print(json.dumps(out))
'''


def test_the_hdf5_file_and_croissant_carry_the_new_columns_with_their_units(small_dataset):
    result = subprocess.run(['/usr/bin/python3', '-I', '-c', READER,
                             str(small_dataset / 'dataset.h5')],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    read = json.loads(result.stdout)
    assert read['format_version'] == '1.1.0'
    assert 'feed_joint' in read['frames']
    declared = {name: frame for name, _, frame, _ in dataset.SAMPLE_FIELDS}
    for split in dataset.SPLITS:
        columns = read[split]
        assert list(columns)[:len(dataset.SAMPLE_COLUMNS)] == dataset.SAMPLE_COLUMNS
        with np.load(small_dataset / (split + '.npz')) as z:
            for name, unit in UNITS.items():
                assert columns[name] == [unit, declared[name], 'float64', len(z['t'])], name
    with open(small_dataset / 'croissant.json') as handle:
        document = json.load(handle)
    fields = {field['@id']: field for record in document['recordSet']
              for field in record['field']}
    for split in dataset.SPLITS:
        for name, unit in UNITS.items():
            field = fields['%s_samples/%s' % (split, name)]
            assert field['dataType'] == 'sc:Float'
            assert 'Unit: %s. Frame: %s.' % (unit, declared[name]) in field['description']
            assert field['source']['extract']['column'] == '/%s/samples/%s' % (split, name)


class TorqueReader:
    """A push_sample recognizer: records every sample it is given, stops at the first whose
    torque about the drill axis exceeds `torque_nm` (it never looks at the thrust)."""

    def __init__(self, torque_nm=0.004):
        self.torque_nm = torque_nm
        self.seen = []

    def reset(self):
        self.seen = []

    def push_sample(self, sample):
        self.seen.append(sample)
        stop = sample['torque'][2] > self.torque_nm
        return {'new_average': True, 'state': 'inner_cortical' if stop else 'idle',
                'stop': stop}


class ThrustOnly:
    """A thrust-only recognizer: stops at the first thrust above `force_n`."""

    def __init__(self, force_n=1.0):
        self.force_n = force_n
        self.seen = []

    def reset(self):
        self.seen = []

    def push(self, t, f):
        self.seen.append((t, f))
        return {'stop': f > self.force_n, 'state': 'idle'}


def _tiny(with_wrench=True):
    """Two trials of five samples as a split's arrays; the torque rises in each."""
    n = 10
    data = {'t': np.arange(n, dtype=float) * 0.003, 'raw_force_n': np.tile([0.0, 0.5, 0.8, 1.5, 2.0], 2),
            'layer': np.array([0, 1, 2, 3, 4] * 2, np.int32), 'trial': np.repeat([0, 1], 5),
            'trial_trial_id': np.array(['a', 'b']), 'trial_case': np.array(['x', 'y']),
            'trial_rpm': np.array([12000.0, 12000.0])}
    if with_wrench:
        data.update(force_x_n=np.full(n, 0.1), force_y_n=np.full(n, -0.2),
                    torque_x_nm=np.full(n, 0.01), torque_y_nm=np.full(n, 0.02),
                    torque_z_nm=np.tile([0.0, 0.001, 0.002, 0.005, 0.009], 2),
                    feed_depth_m=np.linspace(0.01, 0.02, n),
                    spindle_rpm=np.array([np.nan] + [12000.0] * (n - 1)),
                    feed_command_m=np.linspace(0.0105, 0.0205, n),
                    tracker_x_m=np.full(n, 0.3), tracker_y_m=np.full(n, -0.1),
                    tracker_z_m=np.full(n, 1.2), tracker_stamp_s=np.full(n, 2.875))
    return data


def test_the_offline_replay_gives_a_push_sample_recognizer_the_whole_sample():
    data = _tiny()
    reader = TorqueReader()
    stop = offline.offline_stop(reader, data['t'][:5], data['raw_force_n'][:5],
                                {name: data[name][:5] for name in dataset.WRENCH_COLUMNS})
    assert stop == 3
    first = reader.seen[1]
    assert set(first) == {'t', 'thrust', 'force', 'torque', 'feed_depth_m', 'spindle_rpm',
                          'feed_command_m', 'tracker', 'tracker_stamp'}
    assert first['feed_command_m'] == data['feed_command_m'][1]
    assert first['tracker'] == (0.3, -0.1, 1.2) and first['tracker_stamp'] == 2.875
    assert first['t'] == data['t'][1] and first['thrust'] == data['raw_force_n'][1]
    assert first['force'] == (0.1, -0.2, data['raw_force_n'][1])
    assert first['torque'] == (0.01, 0.02, 0.001)
    assert first['feed_depth_m'] == data['feed_depth_m'][1] and first['spindle_rpm'] == 12000.0
    assert all(type(v) is float for v in first['force'] + first['torque'])
    assert np.isnan(reader.seen[0]['spindle_rpm'])
    counts, per_trial = offline.evaluate_offline(TorqueReader, data)
    assert counts['correct'] == 2 and [p['stop_index'] for p in per_trial] == [3, 3]


def test_a_format_1_0_0_dataset_replays_thrust_only_and_names_the_missing_columns(tmp_path):
    old = _tiny(with_wrench=False)
    np.savez(tmp_path / 'old.npz', **old)
    counts, per_trial = offline.evaluate_offline(ThrustOnly, str(tmp_path / 'old.npz'))
    assert counts['trials'] == 2 and [p['stop_index'] for p in per_trial] == [3, 3]
    assert offline.offline_stop(ThrustOnly(), old['t'], old['raw_force_n']) == 3
    with pytest.raises(offline.MissingColumnsError) as error:
        offline.evaluate_offline(TorqueReader, str(tmp_path / 'old.npz'))
    for name in dataset.WRENCH_COLUMNS:
        assert name in str(error.value)
    assert 'push_sample' in str(error.value) and '1.0.0' in str(error.value)
    with pytest.raises(offline.MissingColumnsError, match='torque_z_nm'):
        offline.offline_stop(TorqueReader(), old['t'], old['raw_force_n'])
    partial = {name: old['t'] for name in dataset.WRENCH_COLUMNS if name != 'spindle_rpm'}
    with pytest.raises(offline.MissingColumnsError) as error:
        offline.offline_stop(TorqueReader(), old['t'], old['raw_force_n'], partial)
    assert 'no column spindle_rpm:' in str(error.value)
    # The same dataset with the columns: the thrust-only recognizer stops where it did.
    assert offline.evaluate_offline(ThrustOnly, _tiny())[1] == per_trial


MODULE = '''
class TorqueStop:
    """Stops at the first sample whose torque about the drill axis exceeds 4 N mm and whose
    spindle turns; never reads the thrust."""
    PARAMETERS = {}

    def configure(self, params):
        pass

    def reset(self):
        self.stopped = False

    def push(self, t, raw_force):  # the contract asks for it; never called here
        raise RuntimeError('TorqueStop reads the whole sample')

    def push_sample(self, sample):
        rpm = sample['spindle_rpm']
        self.stopped = self.stopped or (sample['torque'][2] > 0.004 and rpm == rpm and rpm > 0)
        return {'new_average': True, 'state': 'inner_cortical' if self.stopped else 'idle',
                'stop': self.stopped}
'''


def test_the_dataset_replays_the_torque_offline_and_through_recognize(small_dataset, tmp_path):
    counts, per_trial = offline.evaluate_offline(lambda: TorqueReader(0.004),
                                                 small_dataset / 'validation.npz')
    assert counts['trials'] == 3 and counts['none'] == 0
    with np.load(small_dataset / 'validation.npz') as z:
        for item in per_trial:
            rows = np.flatnonzero(z['trial'] == item['trial'])
            torque = z['torque_z_nm'][rows]
            assert torque[item['stop_index']] > 0.004
            assert np.all(torque[:item['stop_index']] <= 0.004)
    # The leaderboard's tuning path: `recognize` over the traces offline.export_traces
    # writes (the whole sample), the class's push_sample run by the closed loop's
    # PythonRecognizer. It stops where the Python replay stops.
    path = tmp_path / 'torque_stop.py'
    path.write_text(MODULE)
    name = api.add_module(str(path))
    scores = api.score_offline('python:%s.TorqueStop' % name, small_dataset, 'validation')
    assert sum(scores.values()) == 3 and scores['none'] == 0
    expected = {}
    for item in per_trial:
        outcome = item['outcome']
        if outcome == 'correct' and item['residual_mm'] > offline.MAX_RESIDUAL_MM:
            outcome = 'shallow'
        expected[outcome] = expected.get(outcome, 0) + 1
    assert {k: v for k, v in scores.items() if v} == expected
