"""The node reference's parameter tables (doc/nodes.md) against the code's declarations and the
shipped configuration. Each nodelet's parameters are declared once in C++ (core::ParamTable,
through ros/node_params.hpp); `param_docs --format json` prints them. Every declared parameter has
a row in doc/nodes.md with the same type, default and allowed values (the range column starts with
the declared rule; notes may follow after "; "), and every row is declared: a range changed in the
code and not in the document, or the reverse, fails here. A wildcard row (`~ventilator/*`) covers
a declared group. Every key a config/*.yaml sets is documented. The README holds no parameter
table (the reference is doc/nodes.md). That the nodelets refuse what the document calls out of
range is the rostest parameter_walk."""
import json
import os
import subprocess

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
from shipped_docs import NODE_REFERENCE, parameter_rows, parameter_tables  # noqa: E402
CONFIGS = {
    'pedicle_drilling/Ventilator': 'ventilator.yaml',
    'pedicle_drilling/Simulator': 'simulator.yaml',
    'pedicle_drilling/MotionIdentification': 'motion_identification.yaml',
    'pedicle_drilling/StateRecognizer': 'recognizer.yaml',
    'pedicle_drilling/SafetyMonitor': 'safety_monitor.yaml',
    'pedicle_drilling/CompensationPlanner': 'compensation_planner.yaml',
    'pedicle_drilling/FaultInjector': 'fault_injector.yaml',
    'pedicle_drilling/TfPoseRelay': 'tf_pose_relay.yaml',
    'pedicle_drilling/ForceTare': 'force_tare.yaml',
    'pedicle_drilling/TrialAction': 'trial_action.yaml',
}


REFERENCE = os.path.join(ROOT, NODE_REFERENCE)


def reference_tables():
    return {node: [name for name, _, _ in rows] for node, rows in
            parameter_tables(REFERENCE).items()}


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
    rows = reference_tables().get(node, [])
    assert rows, 'no parameter table for %s in %s' % (node, NODE_REFERENCE)
    with open(os.path.join(ROOT, 'config', CONFIGS[node])) as handle:
        config = yaml.safe_load(handle)
    missing = [k for k in flat_keys(config) if not documented(k, rows)]
    assert missing == [], '%s: in config/%s but not in %s: %s' % (
        node, CONFIGS[node], NODE_REFERENCE, missing)


@pytest.fixture(scope='module')
def declared(bin_dir):
    out = subprocess.run([os.path.join(bin_dir, 'param_docs'), '--format', 'json'],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def reference_rows():
    """{node: {name: (type, default, range column)}} with the document's default column kept."""
    return {node: {name: (kind, default, rule) for name, kind, default, rule in rows}
            for node, rows in parameter_rows(REFERENCE).items()}


def test_every_nodelet_declares_its_parameters(declared):
    assert sorted(declared) == sorted(CONFIGS)
    assert sorted(reference_rows()) == sorted(CONFIGS)


def row_problems(rows, params):
    """What differs between a node's documented rows {name: (type, default, range column)} and
    its declared parameters {name: param_docs entry}."""
    problems = []
    for name, p in params.items():
        wildcard = [r for r in rows if r.endswith('/*') and name.startswith(r[:-1])]
        if wildcard:
            continue
        if name not in rows:
            problems.append('~%s is declared (%s, default %r, %s) but has no row' % (
                name, p['type'], p['default'], p['rule']))
            continue
        kind, default, rule = rows[name]
        expected_default = '`%s`' % p['default'] if p['default'] else '`""`'
        if kind != p['type']:
            problems.append('~%s: documented type %r, declared %r' % (name, kind, p['type']))
        if default != expected_default:
            problems.append('~%s: documented default %s, declared %s' % (name, default,
                                                                        expected_default))
        if not (rule == p['rule'] or rule.startswith(p['rule'] + '; ')):
            problems.append('~%s: documented range %r does not start with the declared %r' % (
                name, rule, p['rule']))
    for name in rows:
        if name.endswith('/*'):
            if not any(n.startswith(name[:-1]) for n in params):
                problems.append('wildcard row ~%s covers no declared parameter' % name)
        elif name not in params:
            problems.append('row ~%s is not a declared parameter' % name)
    return problems


@pytest.mark.parametrize('node', sorted(CONFIGS))
def test_reference_table_matches_the_declarations(node, declared):
    problems = row_problems(reference_rows()[node], {p['name']: p for p in declared[node]})
    assert problems == [], node + ':\n' + '\n'.join(problems)


def test_the_check_sees_a_changed_range(declared, tmp_path):
    """The comparison itself: a declared range that differs from the document's is reported."""
    node = 'pedicle_drilling/SafetyMonitor'
    changed = json.loads(json.dumps(declared))
    for p in changed[node]:
        if p['name'] == 'position_threshold_m':
            p['rule'] = '(0, 0.2] m'
    with pytest.raises(AssertionError, match='position_threshold_m'):
        test_reference_table_matches_the_declarations(node, changed)


def test_the_check_sees_a_changed_default(declared):
    """A default written wrong in the document is reported (the document's rows, one changed)."""
    node = 'pedicle_drilling/SafetyMonitor'
    rows = reference_rows()
    kind, default, rule = rows[node]['force_timeout_s']
    assert default == '`0.1`'
    rows[node]['force_timeout_s'] = (kind, '`0.2`', rule)
    problems = row_problems(rows[node], {p['name']: p for p in declared[node]})
    assert any('force_timeout_s' in p and 'default' in p for p in problems)


def test_the_readme_holds_no_parameter_table():
    """The parameter tables are the node reference's only: a table in the README would go
    unchecked here."""
    assert parameter_rows(os.path.join(ROOT, 'README.md')) == {}


# Shipped settings that differ from the declared default on purpose, with the reason. Any other
# difference is a default written twice.
SHIPPED_DIFFERENCES = {
    ('pedicle_drilling/CompensationPlanner', 'retreat_distance_m'):
        'the workcell pipeline retreats 25 mm (its feed travel allows it); the core default of '
        '10 mm is the closed-loop engine\'s',
    ('pedicle_drilling/Simulator', 'drive_guard_timeout_s'):
        'the pipeline\'s simulated drivers watch the drill guard (0.08 s, what a lab\'s drivers '
        'must do); the core default 0 is for a DrillingSimulation without a guard on the graph',
}


def same_value(text, value):
    if isinstance(value, bool):
        return text == str(value).lower()
    if isinstance(value, (int, float)):
        try:
            return float(text) == float(value)
        except ValueError:
            return False
    if isinstance(value, list):
        joined = ','.join(str(v) for v in value)
        return text in (joined, '[%s]' % ', '.join(str(v) for v in value))
    return text == str(value)


@pytest.mark.parametrize('node', sorted(CONFIGS))
def test_shipped_config_repeats_no_default_differently(node, declared):
    """config/*.yaml sets the declared default unless SHIPPED_DIFFERENCES says why not."""
    defaults = {p['name']: p['default'] for p in declared[node]}
    with open(os.path.join(ROOT, 'config', CONFIGS[node])) as handle:
        config = yaml.safe_load(handle)
    differ = []
    for key in flat_keys(config):
        value = config
        for part in key.split('/'):
            value = value[part]
        if key in defaults and not same_value(defaults[key], value) and \
                (node, key) not in SHIPPED_DIFFERENCES:
            differ.append('%s: config %r, declared default %r' % (key, value, defaults[key]))
    assert differ == [], node + ': ' + '; '.join(differ)
