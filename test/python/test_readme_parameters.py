"""The README's parameter tables against the shipped configuration (issue 12): every key a
nodelet's config/*.yaml sets is documented in that nodelet's README table (a wildcard row such as
`~trial_distribution/specimen/*` covers a group). The other direction, that every documented
parameter is checked by the code, is the rostest parameter_walk."""
import os
import sys

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(ROOT, 'test'))
from shipped_docs import readme_parameter_tables  # noqa: E402
CONFIGS = {
    'pedicle_drilling/Ventilator': 'ventilator.yaml',
    'pedicle_drilling/Simulator': 'simulator.yaml',
    'pedicle_drilling/MotionIdentification': 'motion_identification.yaml',
    'pedicle_drilling/StateRecognizer': 'recognizer.yaml',
    'pedicle_drilling/SafetyMonitor': 'safety_monitor.yaml',
    'pedicle_drilling/CompensationPlanner': 'compensation_planner.yaml',
    'pedicle_drilling/FaultInjector': 'fault_injector.yaml',
}


def readme_tables():
    return {node: [name for name, _, _ in rows] for node, rows in
            readme_parameter_tables(os.path.join(ROOT, 'README.md')).items()}


def flat_keys(data, prefix=''):
    for key, value in data.items():
        if isinstance(value, dict) and value:
            yield from flat_keys(value, prefix + key + '/')
        else:
            yield prefix + key


def documented(name, rows):
    for row in rows:
        if row == name:
            return True
        if row.endswith('/*') and name.startswith(row[:-1]):
            return True
        if '<' in row and name.startswith(row.split('<')[0]):
            return True
    return False


@pytest.mark.parametrize('node', sorted(CONFIGS))
def test_every_shipped_parameter_is_documented(node):
    rows = readme_tables().get(node, [])
    assert rows, 'no README parameter table for %s' % node
    with open(os.path.join(ROOT, 'config', CONFIGS[node])) as handle:
        config = yaml.safe_load(handle)
    missing = [k for k in flat_keys(config) if not documented(k, rows)]
    assert missing == [], '%s: in config/%s but not in the README: %s' % (
        node, CONFIGS[node], missing)
