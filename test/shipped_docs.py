"""What the tests read from the shipped files, read once for all of them: the node reference's
per-node parameter tables (doc/nodes.md), the launch files' required arguments, and a node's
declared parameter defaults (param_docs). Imported by the python
tests (test/python) and the rostest scripts (test/rostest) with test/ on sys.path."""
import json
import os
import re
import subprocess
import xml.etree.ElementTree as ET

# The document with every node's parameter tables, relative to the repository root.
NODE_REFERENCE = os.path.join('doc', 'nodes.md')


def declared_default(node, name):
    """The declared default of parameter `name` of nodelet class `node` (e.g.
    'pedicle_drilling/Simulator'), as a float, read from `param_docs --format json` (the
    declaration itself)."""
    out = subprocess.run(['rosrun', 'pedicle_drilling', 'param_docs', '--node', node, '--format',
                          'json'], capture_output=True, text=True, check=True).stdout
    return float([r for r in json.loads(out)[node] if r['name'] == name][0]['default'])


def parameter_rows(path):
    """{node type: [(parameter name without ~, type, default, range text)]} from the tables of a
    document (the node reference, NODE_REFERENCE) under each `### pedicle_drilling/<Node>` heading (rows `| `~name` [, `~name`] | type |
    default | range |`; a row naming several parameters gives one entry per name)."""
    tables, node = {}, None
    with open(path) as handle:
        for line in handle:
            heading = re.match(r'^### (pedicle_drilling/\w+)', line)
            if heading:
                node = heading.group(1)
            elif line.startswith('## '):
                node = None
            # Cells may be empty (a row of several parameters of mixed types leaves `type` blank).
            row = re.match(r'^\|\s*(`~[^|]+?)\s*\|([^|]*)\|([^|]*)\|(.*)\|\s*$', line)
            if node and row:
                for name in re.findall(r'`~([^`]+)`', row.group(1)):
                    tables.setdefault(node, []).append(
                        (name, row.group(2).strip(), row.group(3).strip(), row.group(4).strip()))
    return tables


def parameter_tables(path):
    """{node type: [(parameter name without ~, type, range text)]}: parameter_rows without the
    default column."""
    return {node: [(name, kind, rule) for name, kind, _, rule in rows]
            for node, rows in parameter_rows(path).items()}


def required_launch_args(path):
    """name:=placeholder for every <arg> of a launch file without a default or value
    (replay.launch's bag), so that it loads without a real value."""
    return ['%s:=placeholder' % a.get('name') for a in ET.parse(path).getroot().iter('arg')
            if a.get('default') is None and a.get('value') is None]
