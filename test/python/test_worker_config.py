"""The --engine ros worker's class parameters (pd_campaign.worker_config.plugin_config): every
class's settings as text in ~recognizer_params / ~compensator_params, read by the class as the core
engine reads them (the paper recognizer by its ParamTable, whose refusals the nodelet's gtest and
rostests check); a paper recognizer's setting leaves the node's own key of the package file (the
node refuses a parameter given both ways); what the nodelet would not take by name is a
ValueError naming it."""
import os

import pytest
import yaml

from pd_campaign.worker_config import launch_arguments, plugin_config

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
PAPER = 'pedicle_drilling/PaperRecognizer'


def written(tmp_path, kind, class_name, settings):
    path = plugin_config(kind, class_name, settings, ROOT, str(tmp_path / 'node.yaml'))
    with open(path) as handle:
        return yaml.safe_load(handle)


CHANGED = ('inner_confirm', 'f_th', 'window', 'normalize_feature', 'gain', 'pre_average_s')


def test_the_paper_recognizers_settings_are_text_given_once(tmp_path):
    config = written(tmp_path, 'recognizer', PAPER,
                     ['inner_confirm=010', 'f_th=1e-3', 'window=12.0', 'normalize_feature=1',
                      'gain=2', 'pre_average_s=0.3'])
    assert config['recognizer_params'] == {
        'inner_confirm': '010', 'f_th': '1e-3', 'window': '12.0', 'normalize_feature': '1',
        'gain': '2', 'pre_average_s': '0.3'}
    # Each is given once: the node's own key leaves; the rest of the package's file is kept.
    with open(os.path.join(ROOT, 'config', 'recognizer.yaml')) as handle:
        package = yaml.safe_load(handle)
    assert {k: v for k, v in config.items() if k != 'recognizer_params'} == {
        k: v for k, v in package.items() if k not in CHANGED}


def test_another_class_gets_its_settings_as_text(tmp_path):
    config = written(tmp_path, 'recognizer', 'pedicle_drilling/ForceDifferenceRecognizer',
                     ['drop_confirm=010', 'stop_at_breakthrough=yes', 'model=a=b'])
    assert config['recognizer_params'] == {'drop_confirm': '010',
                                           'stop_at_breakthrough': 'yes', 'model': 'a=b'}
    config = written(tmp_path, 'compensator', 'pedicle_drilling/TrackedMarkerCompensator',
                     ['extrapolate=true'])
    assert config['compensator_params'] == {'extrapolate': 'true'}


def test_no_settings_no_file(tmp_path):
    assert plugin_config('recognizer', PAPER, [], ROOT, str(tmp_path / 'x.yaml')) is None
    assert not (tmp_path / 'x.yaml').exists()


@pytest.mark.parametrize('kind,class_name,setting,named', [
    ('recognizer', PAPER, 'nonsense=1', 'nonsense'),
    ('recognizer', PAPER, 'queue_size=10', 'queue_size'),  # the node's, not the recognizer's
    ('recognizer', PAPER, 'rate_tolerance=0.2', 'rate_tolerance'),
    # the simulated sensor's rate, set with it (launch_arguments: force_rate_hz)
    ('recognizer', PAPER, 'sensor_rate_hz=1000', 'sensor_rate_hz'),
    ('recognizer', PAPER, 'pre_average=50', 'pre_average'),  # retired: pre_average_s
    ('recognizer', PAPER, 'window', 'window'),
    ('compensator', 'pedicle_drilling/PaperCompensator', 'latency_s=1', 'latency_s'),
])
def test_what_the_nodelet_would_not_take_is_named(tmp_path, kind, class_name, setting, named):
    with pytest.raises(ValueError, match=named):
        plugin_config(kind, class_name, [setting], ROOT, str(tmp_path / 'x.yaml'))
    assert not (tmp_path / 'x.yaml').exists()


def test_every_launch_argument_of_a_worker_is_declared_by_its_launch_file():
    import argparse
    import xml.etree.ElementTree as ET
    args = argparse.Namespace(default_model='m.yaml', real_time_factor=0.0, bags=False,
                              segment_profile='rest_to_rest', depth_limit='false',
                              recognizer='pedicle_drilling/PaperRecognizer',
                              compensator='pedicle_drilling/PaperCompensator', out='out')
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    launch = ET.parse(os.path.join(root, 'launch_scripts', 'campaign_pipeline.launch')).getroot()
    declared = {arg.get('name') for arg in launch.findall('arg')}
    args.simulator_param = ['lockstep_every_step=true', 'force_sensor_rate_hz=1000']
    items = launch_arguments(args)
    # A simulated sensor rate declares the recognizer's and the monitor's rates with it.
    assert 'force_rate_hz:=1000' in items
    for item in items:
        name = item.split(':=', 1)[0]
        assert name in declared, '%s is not an argument of campaign_pipeline.launch' % name
    for kind, launch_arg in (('recognizer', 'recognizer_config'), ('compensator', 'planner_config')):
        assert launch_arg in declared, kind
