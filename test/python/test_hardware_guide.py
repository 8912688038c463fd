"""doc/hardware.md, the bring-up guide, against what it describes: its tables of arguments list
every argument of launch_scripts/hardware.launch with the launch file's default, and nothing
else; and every row of its numbers table ("| what | value | node/parameter |") quotes the
parameter's value as shipped (config/*.yaml, else the declared default from `param_docs`, or
for `hardware.launch/NAME` the launch file's default), so a number changed in one place only
fails here."""
import json
import os
import re
import subprocess
import xml.etree.ElementTree as ET

import pytest
import yaml

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
GUIDE = os.path.join(ROOT, 'doc', 'hardware.md')
LAUNCH = os.path.join(ROOT, 'launch_scripts', 'hardware.launch')
# node name in the guide -> (its parameter file in config/, its nodelet class)
NODES = {
    'compensation_planner': ('compensation_planner.yaml', 'pedicle_drilling/CompensationPlanner'),
    'safety_monitor': ('safety_monitor.yaml', 'pedicle_drilling/SafetyMonitor'),
    'state_recognizer': ('recognizer.yaml', 'pedicle_drilling/StateRecognizer'),
    'ventilator': ('ventilator.yaml', 'pedicle_drilling/Ventilator'),
    'force_tare': ('force_tare.yaml', 'pedicle_drilling/ForceTare'),
    'simulator': ('simulator.yaml', 'pedicle_drilling/Simulator'),
}
ARGUMENT_ROW = re.compile(r'^\| `(\w+)` \| `([^`]*)` \| (.*) \|$')
NUMBERS_HEADER = '| what a driver meets | value | parameter |'
CELL_SEPARATOR = re.compile(r'(?<!\\)\|')  # a cell may hold an escaped \|


def guide_lines():
    with open(GUIDE, encoding='utf-8') as handle:
        return handle.read().splitlines()


def launch_arguments():
    """{name: default} of every argument of hardware.launch (not its constants, value=)."""
    return {a.get('name'): a.get('default').replace('$(find pedicle_drilling)/', '')
            for a in ET.parse(LAUNCH).getroot().iter('arg') if a.get('value') is None}


def documented_arguments(lines):
    """{name: default} of the guide's argument rows ("| `name` | `default` | what |")."""
    return {m.group(1): m.group(2) for m in map(ARGUMENT_ROW.match, lines) if m}


def test_every_argument_is_in_the_guide_with_its_default():
    documented, launch = documented_arguments(guide_lines()), launch_arguments()
    assert sorted(documented) == sorted(launch)
    assert [n for n in launch if documented[n] != launch[n]] == []


def test_the_argument_check_sees_a_wrong_default():
    lines = [line.replace('| `tare_samples` | `100` |', '| `tare_samples` | `50` |')
             for line in guide_lines()]
    assert documented_arguments(lines)['tare_samples'] != launch_arguments()['tare_samples']


@pytest.fixture(scope='module')
def declared(bin_dir):
    out = subprocess.run([os.path.join(bin_dir, 'param_docs'), '--format', 'json'],
                         check=True, capture_output=True, text=True).stdout
    return {node: {p['name']: p['default'] for p in params}
            for node, params in json.loads(out).items()}


def shipped_value(parameter, declared):
    """The value of `node/name` as hardware.launch loads it."""
    node, name = parameter.split('/', 1)
    if node == 'hardware.launch':
        return float(launch_arguments()[name])
    config_file, node_class = NODES[node]
    with open(os.path.join(ROOT, 'config', config_file)) as handle:
        value = yaml.safe_load(handle)
    for part in name.split('/'):
        value = value.get(part) if isinstance(value, dict) else None
    return float(declared[node_class][name] if value is None else value)


def number_rows(lines):
    """[(what, value quoted, parameter)] of the guide's numbers table, every row of it: a row
    whose value does not start with a number or whose parameter is not `node/name` fails."""
    start = lines.index(NUMBERS_HEADER) + 2
    rows = []
    for line in lines[start:]:
        if not line.startswith('|'):
            break
        what, value, parameter = [c.strip() for c in CELL_SEPARATOR.split(line)[1:-1]]
        number = re.match(r'-?[0-9]+(\.[0-9]+)?(?![0-9.])', value)
        assert number, 'no number first in %r' % line
        assert re.fullmatch(r'`[\w.]+/[\w/]+`', parameter), 'no `node/name` in %r' % line
        rows.append((what, float(number.group(0)), parameter.strip('`')))
    return rows


def wrong_numbers(lines, declared):
    return ['%s: %s quoted %g, shipped %g' % (what, parameter, value,
                                              shipped_value(parameter, declared))
            for what, value, parameter in number_rows(lines)
            if abs(value - shipped_value(parameter, declared)) > 1e-9 * max(1.0, abs(value))]


def test_every_number_is_the_shipped_one(declared):
    rows = number_rows(guide_lines())
    assert len(rows) >= 45, rows
    assert wrong_numbers(guide_lines(), declared) == []


def test_the_number_check_sees_a_wrong_number(declared):
    lines = [line.replace('| 0.1 s | `safety_monitor/force_timeout_s` |',
                          '| 0.2 s | `safety_monitor/force_timeout_s` |') for line in guide_lines()]
    assert lines != guide_lines()
    assert [w for w in wrong_numbers(lines, declared) if 'force_timeout_s' in w]
