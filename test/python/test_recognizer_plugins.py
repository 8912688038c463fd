"""Bring your own recognizer or compensator: the built-in recognizers and
compensators are pluginlib classes that rospack lists; the offline `recognize` tool, trial_engine
and the campaign run whichever class is named; plugins defined only in the test tree
(test/plugin/, built with the tests) are loaded by their names, which proves that an outside
class plugs in; a class that does not load is exit 2 naming it."""
import json
import os
import subprocess
import xml.etree.ElementTree as ET

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
TEST_PLUGIN_XML = os.path.join(ROOT, 'test', 'plugin', 'test_recognizer_plugins.xml')


def write_trace(path, levels):
    """t,force at 1 kHz: `levels` a list of (seconds, N) plateaus."""
    with open(path, 'w') as handle:
        handle.write('t,force\n')
        t = 0.0
        for seconds, level in levels:
            for _ in range(int(seconds * 1000)):
                handle.write('%.3f,%.4f\n' % (t, level))
                t += 1e-3


def recognize(bin_dir, *args, plugin_xml=None):
    env = dict(os.environ)
    env.pop('PEDICLE_DRILLING_PLUGIN_XML', None)
    if plugin_xml:
        env['PEDICLE_DRILLING_PLUGIN_XML'] = plugin_xml
    return subprocess.run([os.path.join(bin_dir, 'recognize')] + list(args),
                          capture_output=True, text=True, timeout=60, env=env)


def test_rospack_lists_both_recognizers_and_both_compensators_of_the_package():
    out = subprocess.run(['rospack', 'plugins', '--attrib=plugin', 'pedicle_drilling'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    xmls = [line.split(' ', 1)[1] for line in out.stdout.splitlines()
            if line.startswith('pedicle_drilling ')]
    assert xmls, out.stdout
    classes = [c.get('name') for x in xmls for c in ET.parse(x).getroot().iter('class')]
    assert 'pedicle_drilling/PaperRecognizer' in classes
    assert 'pedicle_drilling/ForceDifferenceRecognizer' in classes
    assert 'pedicle_drilling/PaperCompensator' in classes
    assert 'pedicle_drilling/TrackedMarkerCompensator' in classes


def trial_engine(bin_dir, *args, plugin_xml=None):
    env = dict(os.environ)
    env.pop('PEDICLE_DRILLING_PLUGIN_XML', None)
    if plugin_xml:
        env['PEDICLE_DRILLING_PLUGIN_XML'] = plugin_xml
    return subprocess.run([os.path.join(bin_dir, 'trial_engine')] + list(args),
                          capture_output=True, text=True, timeout=60, env=env)


def test_trial_engine_loads_a_compensator_by_name_and_refuses_a_bad_one(bin_dir):
    # Through pluginlib (not a built-in): the test tree's class, by its name.
    out = trial_engine(bin_dir, '--check-compensator', 'test_plugins/HoldStill', 'offset_mm=1',
                       plugin_xml=TEST_PLUGIN_XML)
    assert out.returncode == 0 and 'holds still' in out.stdout, out.stderr
    out = trial_engine(bin_dir, '--check-compensator', 'test_plugins/HoldStill')
    assert out.returncode == 2 and 'test_plugins/HoldStill' in out.stderr
    out = trial_engine(bin_dir, '--check-compensator', 'test_plugins/HoldStill', 'gain=2',
                       plugin_xml=TEST_PLUGIN_XML)
    assert out.returncode == 2 and 'gain' in out.stderr
    out = trial_engine(bin_dir, '--check-compensator', 'pedicle_drilling/TrackedMarkerCompensator',
                       'extrapolate=true')
    assert out.returncode == 0 and 'constant-velocity' in out.stdout, out.stderr
    out = trial_engine(bin_dir, '--check-compensator', 'pedicle_drilling/TrackedMarkerCompensator',
                       'max_horizon_s=0')
    assert out.returncode == 2 and 'max_horizon_s' in out.stderr
    out = trial_engine(bin_dir, '--check-compensator', 'pedicle_drilling/PaperCompensator',
                       'latency_s=1')
    assert out.returncode == 2 and 'latency_s' in out.stderr


def test_the_campaign_runs_the_named_compensator(tmp_path):
    """The tracker-feedback baseline drills compensated trials on the core engine; the design
    records the class; a class that does not load is exit 2 before anything is written."""
    out_dir = tmp_path / 'tracked'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'compensated', '--rpm', '12000',
         '--trials', '2', '--jobs', '1', '--seed', '78', '--out', str(out_dir),
         '--compensator', 'pedicle_drilling/TrackedMarkerCompensator'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out_dir / 'design.json') as handle:
        meta = json.load(handle)['meta']
    assert meta['compensator'] == 'pedicle_drilling/TrackedMarkerCompensator'
    assert meta['recognizer'] == 'pedicle_drilling/PaperRecognizer'
    import csv
    with open(out_dir / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 and all(r['error'] == '' for r in rows), rows
    bad = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'compensated', '--rpm', '12000',
         '--trials', '1', '--out', str(tmp_path / 'bad'), '--compensator', 'nobody/Nothing'],
        capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and 'nobody/Nothing' in bad.stderr, bad.stderr[-2000:]
    assert not (tmp_path / 'bad').exists()


def test_a_plugin_of_the_test_tree_is_loaded_by_name(bin_dir, tmp_path):
    trace = tmp_path / 'trace.csv'
    write_trace(trace, [(1.0, 0.0), (1.0, 2.0)])
    out = recognize(bin_dir, '--input', str(trace), '--json', '--recognizer',
                    'test_plugins/StopAfterSamples', '--param', 'samples=250',
                    plugin_xml=TEST_PLUGIN_XML)
    assert out.returncode == 0, out.stderr
    stop = json.loads(out.stdout)['stop']
    assert stop['index'] == 1000 + 249  # its 250th sample above 1 N
    # The same name without its plugin file: exit 2, the class named.
    out = recognize(bin_dir, '--input', str(trace), '--recognizer',
                    'test_plugins/StopAfterSamples')
    assert out.returncode == 2
    assert 'test_plugins/StopAfterSamples' in out.stderr
    # Its own parameters are checked by it: a bad one is exit 2 naming it.
    out = recognize(bin_dir, '--input', str(trace), '--recognizer',
                    'test_plugins/StopAfterSamples', '--param', 'samples=0',
                    plugin_xml=TEST_PLUGIN_XML)
    assert out.returncode == 2 and 'samples' in out.stderr, out.stderr


def test_the_baseline_judges_a_recorded_trace(bin_dir, tmp_path):
    trace = tmp_path / 'vertebra.csv'
    # Air, outer cortex 3.5 N, cancellous 1.2 N, inner cortex 4 N, canal 0 N (steps: the
    # force-difference detector sees each fall as a breakthrough).
    write_trace(trace, [(1.0, 0.0), (4.0, 3.5), (4.0, 1.2), (3.0, 4.0), (1.0, 0.0)])
    out = recognize(bin_dir, '--input', str(trace), '--json', '--recognizer',
                    'pedicle_drilling/ForceDifferenceRecognizer')
    assert out.returncode == 0, out.stderr
    stop = json.loads(out.stdout)['stop']
    assert stop is not None and 12.0 <= stop['t'] <= 12.5, stop  # the second fall, at 12 s
    out = recognize(bin_dir, '--input', str(trace), '--recognizer',
                    'pedicle_drilling/ForceDifferenceRecognizer', '--param', 'drop_confirm=0')
    assert out.returncode == 2 and 'drop_confirm' in out.stderr


def test_the_campaign_runs_the_named_recognizer(tmp_path):
    out_dir = tmp_path / 'baseline'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'stationary', '--rpm', '12000',
         '--trials', '2', '--jobs', '1', '--seed', '77', '--out', str(out_dir),
         '--recognizer', 'pedicle_drilling/ForceDifferenceRecognizer'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out_dir / 'design.json') as handle:
        assert json.load(handle)['meta']['recognizer'] == \
            'pedicle_drilling/ForceDifferenceRecognizer'
    import csv
    with open(out_dir / 'trials.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 and all(r['error'] == '' for r in rows), rows
    assert all('force-difference' in r['stop_reason'] or r['stop_source'] != '/state_recognizer'
               for r in rows), [r['stop_reason'] for r in rows]
    bad = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'stationary', '--rpm', '12000',
         '--trials', '1', '--out', str(tmp_path / 'bad'), '--recognizer', 'nobody/Nothing'],
        capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and 'nobody/Nothing' in bad.stderr, bad.stderr[-2000:]


def test_recognize_reads_a_recording_as_the_project_records_it(bin_dir, tmp_path):
    """`recognize --bag` judges the raw force of a campaign bag (/ft_sensor/wrench at 1 kHz),
    with exactly the result of the same samples given as CSV."""
    import rosbag
    import rospy
    from geometry_msgs.msg import WrenchStamped
    levels = [(1.0, 0.0), (4.0, 3.5), (4.0, 1.2), (3.0, 4.0), (1.0, 0.0)]
    trace = tmp_path / 'trace.csv'
    write_trace(trace, levels)
    bag_path = tmp_path / 'trial.bag'
    with open(trace) as handle, rosbag.Bag(str(bag_path), 'w') as bag:  # not atomic: a fixture
        next(handle)
        for line in handle:
            t, f = (float(v) for v in line.split(','))
            msg = WrenchStamped()
            msg.header.stamp = rospy.Time.from_sec(100.0 + t)
            msg.wrench.force.z = f
            bag.write('/ft_sensor/wrench', msg, msg.header.stamp)
    for recognizer in ('pedicle_drilling/PaperRecognizer',
                       'pedicle_drilling/ForceDifferenceRecognizer'):
        from_csv = recognize(bin_dir, '--input', str(trace), '--json', '--recognizer', recognizer)
        from_bag = recognize(bin_dir, '--bag', str(bag_path), '--json', '--recognizer', recognizer)
        assert from_csv.returncode == 0 and from_bag.returncode == 0, from_bag.stderr
        a, b = json.loads(from_csv.stdout), json.loads(from_bag.stdout)
        assert (a['stop'] is None) == (b['stop'] is None), (a, b)
        if a['stop']:
            assert a['stop']['index'] == b['stop']['index']
            assert abs((b['stop']['t'] - 100.0) - a['stop']['t']) < 1e-6
    out = recognize(bin_dir, '--bag', str(bag_path), '--topic', '/nothing')
    assert out.returncode == 2 and '/nothing' in out.stderr
    out = recognize(bin_dir, '--bag', str(bag_path), '--input', str(trace))
    assert out.returncode == 2


def test_the_campaign_passes_the_classes_parameters(tmp_path):
    """--compensator-param / --recognizer-param (or the scenario's *_params mappings) reach the
    class through trial_engine, are checked by it before anything runs and are recorded."""
    out_dir = tmp_path / 'extrapolating'
    result = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'compensated', '--rpm', '12000',
         '--trials', '1', '--jobs', '1', '--seed', '79', '--out', str(out_dir),
         '--compensator', 'pedicle_drilling/TrackedMarkerCompensator',
         '--compensator-param', 'extrapolate=true', '--compensator-param', 'max_horizon_s=0.3'],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    with open(out_dir / 'design.json') as handle:
        meta = json.load(handle)['meta']
    assert meta['compensator_params'] == {'extrapolate': 'true', 'max_horizon_s': '0.3'}
    assert 'recognizer_params' not in meta
    for bad, named in ((['--compensator-param', 'max_horizon_s=0'], 'max_horizon_s'),
                       (['--compensator-param', 'nonsense'], 'nonsense'),
                       (['--recognizer-param', 'window=0'], 'window')):
        out = subprocess.run(
            ['rosrun', 'pedicle_drilling', 'campaign', '--case', 'compensated', '--rpm', '12000',
             '--trials', '1', '--out', str(tmp_path / 'bad'),
             '--compensator', 'pedicle_drilling/TrackedMarkerCompensator'] + bad,
            capture_output=True, text=True, timeout=600)
        assert out.returncode == 2 and named in out.stderr, (bad, out.stderr[-2000:])
        assert not (tmp_path / 'bad').exists()
    # --engine ros checks them the same way (test_engine_agreement runs them on it).
    ros = subprocess.run(
        ['rosrun', 'pedicle_drilling', 'campaign', '--engine', 'ros', '--case', 'compensated',
         '--trials', '1', '--out', str(tmp_path / 'ros'), '--recognizer-param', 'window=0'],
        capture_output=True, text=True, timeout=600)
    assert ros.returncode == 2 and 'window' in ros.stderr, ros.stderr[-2000:]
    assert not (tmp_path / 'ros').exists()
