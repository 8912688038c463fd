"""The sweep file (config/sensitivity.yaml): its entries read and checked, resolved against the
nominal bench and the Simulator's declarations, and the benches (one campaign each) they make."""
import copy
import json
import math
import os
import re
import subprocess

import yaml

from .. import engine_core, tools
from ..scenario import PACKAGE_ROOT

KINDS = ('simulator_params', 'engine_delays')
ENTRY_KEYS = ('name', 'kind', 'low', 'high', 'nominal', 'unit', 'source', 'with')
# What an entry's `with` may set besides its constant at its swept ends (a setting a lab would
# change with it, e.g. the controller watch's tolerance on a controller with a long latency).
WITH_KINDS = ('simulator_params', 'engine_delays', 'planner_params')
REQUIRED_KEYS = ('name', 'low', 'high', 'unit', 'source')
SWEEP_VERSION = 1
ENDS = ('low', 'high')
ALPHA = 0.05  # every verdict: two-sided exact tests at 5 %, no correction for multiplicity
BEST_RPM = 12000.0  # the paper's chosen speed (Sec. V-C)
SPEED_CASE = 'compensated'  # the case whose success the paper compares across speeds (Fig. 15)
DEFAULT_SWEEP = os.path.join(PACKAGE_ROOT, 'config', 'sensitivity.yaml')
DELAY_RANGE = (0.0, 1.0)  # engine_delays, s (the campaign's scenario check)

TOOL = 'campaign_sensitivity'  # the progress lines' and derived scenarios' prefix


class SweepError(ValueError):
    """A sweep file, or an entry of it, that cannot be run; the message names the entry."""


# --- the sweep file -----------------------------------------------------------------------------

def load_sweep(path):
    """The constants of a sweep file, checked in form: a list of {key, kind, name, low, high,
    nominal (None: the bench's), unit, source}. Raises SweepError naming the offending entry."""
    try:
        with open(path) as handle:
            data = yaml.safe_load(handle)
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as error:
        raise SweepError('--sweep %s: cannot read: %s' % (path, ' '.join(str(error).split())))
    if not isinstance(data, dict):
        raise SweepError('--sweep %s: not a mapping with a list under "constants"' % path)
    unknown = sorted(set(data) - {'version', 'constants'})
    if unknown:
        raise SweepError('--sweep %s: unknown key %r (known: constants, version)'
                         % (path, unknown[0]))
    if data.get('version', SWEEP_VERSION) != SWEEP_VERSION:
        raise SweepError('--sweep %s: version %r is not supported (this tool reads version %d)'
                         % (path, data['version'], SWEEP_VERSION))
    constants = data.get('constants')
    if not isinstance(constants, list) or not constants:
        raise SweepError('--sweep %s: "constants" must be a non-empty list' % path)
    entries = [_entry(path, index, raw) for index, raw in enumerate(constants, 1)]
    seen = set()
    for index, entry in enumerate(entries, 1):
        if entry['key'] in seen:
            raise SweepError('--sweep %s: constant %d (%s) is listed twice'
                             % (path, index, entry['key']))
        seen.add(entry['key'])
    return entries


def entry_form(where, raw, known, required, error=SweepError):
    """`where`, extended with the entry's name, of one mapping entry of a sweep file (this
    tool's constants, campaign_robustness's errors). Raises `error` when it is not a mapping,
    has a key not in `known` or lacks one of `required`."""
    if not isinstance(raw, dict):
        raise error('%s: not a mapping' % where)
    if isinstance(raw.get('name'), str) and raw['name']:
        where += ' (%s)' % raw['name']
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise error('%s: unknown key %r (known: %s)' % (where, unknown[0], ', '.join(known)))
    missing = [key for key in required if key not in raw]
    if missing:
        raise error('%s: %s missing' % (where, ', '.join(missing)))
    return where


def is_finite_number(value):
    """A YAML number that is finite (not a bool)."""
    return not isinstance(value, bool) and isinstance(value, (int, float)) \
        and math.isfinite(value)


def _entry(path, index, raw):
    """One entry of the sweep file, checked in form (not yet against the declarations)."""
    where = entry_form('--sweep %s: constant %d' % (path, index), raw, ENTRY_KEYS, REQUIRED_KEYS)
    kind, name = _kind_and_name(where, raw)
    low, high = _number(where, raw, 'low'), _number(where, raw, 'high')
    nominal = _number(where, raw, 'nominal') if raw.get('nominal') is not None else None
    if not low < high:
        raise SweepError('%s: low %s is not below high %s'
                         % (where, number_text(low), number_text(high)))
    if nominal is not None and not low <= nominal <= high:
        raise SweepError('%s: nominal %s is outside [%s, %s]' % (
            where, number_text(nominal), number_text(low), number_text(high)))
    if not isinstance(raw['unit'], str):
        raise SweepError('%s: unit must be a text (\'\' for none)' % where)
    if not isinstance(raw['source'], str) or not raw['source'].strip():
        raise SweepError('%s: source must name the document row the range comes from' % where)
    also = raw.get('with') or {}
    if not isinstance(also, dict) or any(
            k not in WITH_KINDS or not isinstance(v, dict) or not v for k, v in also.items()):
        raise SweepError('%s: with must map %s to {name: value} (the settings a swept end '
                         'takes besides the constant)' % (where, ' | '.join(WITH_KINDS)))
    return {'key': '%s.%s' % (kind, name), 'kind': kind, 'name': name, 'low': low, 'high': high,
            'nominal': nominal, 'unit': raw['unit'], 'source': raw['source'].strip(),
            'with': {k: dict(v) for k, v in sorted(also.items())}}


def _kind_and_name(where, raw):
    """(kind, name) of an entry: a dotted name (simulator_params.X) or a name with kind: X."""
    name = raw['name']
    if not isinstance(name, str) or not name.strip():
        raise SweepError('%s: name must be a non-empty text' % where)
    prefix, dot, rest = name.partition('.')
    if dot and prefix in KINDS:
        if raw.get('kind') not in (None, prefix):
            raise SweepError('%s: kind %r contradicts the name\'s %s' % (where, raw['kind'],
                                                                         prefix))
        kind, name = prefix, rest
    else:
        kind = raw.get('kind')
    if kind not in KINDS:
        raise SweepError('%s: say which constant it is: kind: %s, or a dotted name such as '
                         'simulator_params.chisel_edge_share' % (where, ' | '.join(KINDS)))
    if not name:
        raise SweepError('%s: the name after %s. is empty' % (where, kind))
    return kind, name


def _number(where, raw, key):
    value = raw[key]
    if not is_finite_number(value):
        raise SweepError('%s: %s %r is not a finite number' % (where, key, value))
    return float(value)


def number_text(value):
    """A number as %g writes it."""
    return '%g' % value


# --- the constants against the bench and the declarations --------------------------------------

def declared_defaults():
    """{kind: {name: default}}: the Simulator's parameter declaration (`param_docs --format
    json`, the one both engines use) and the core engine's transport delays (`trial_engine
    --help`)."""
    out = subprocess.run(tools.tool('param_docs') + ['--node', 'pedicle_drilling/Simulator',
                                                     '--format', 'json'],
                         capture_output=True, text=True, check=True).stdout
    simulator = {}
    for row in json.loads(out)['pedicle_drilling/Simulator']:
        if row.get('type') in ('double', 'int'):
            simulator[row['name']] = float(row['default'])
    usage = subprocess.run(tools.tool('trial_engine') + ['--help'], capture_output=True,
                           text=True).stdout
    delays = {}
    for name, option in engine_core.DELAY_OPTIONS.items():
        found = re.search(r'^\s*%s [^\n]*=([-+0-9.eE]+)\s*$' % re.escape(option), usage, re.M)
        if not found:
            raise RuntimeError('trial_engine --help gives no default for %s' % option)
        delays[name] = float(found.group(1))
    return {'simulator_params': simulator, 'engine_delays': delays}


def check_simulator_setting(name, value):
    """None if the Simulator's declaration takes `name` = `value` (trial_engine
    --check-simulator, as the campaign asks it), else its message."""
    result = subprocess.run(tools.tool('trial_engine') + ['--check-simulator',
                                                          '%s=%r' % (name, value)],
                            capture_output=True, text=True)
    if result.returncode == 0:
        return None
    lines = result.stderr.strip().splitlines()
    return lines[-1] if lines else 'refused by the Simulator\'s declaration'


def bench_value(scenario, kind, name):
    """The value a scenario sets for a constant, or None when it leaves the default (a
    trial_distribution/<group>/<key> may also come from the scenario's `simulator:` section)."""
    value = (scenario.get(kind) or {}).get(name)
    parts = name.split('/')
    if value is None and kind == 'simulator_params' and len(parts) == 3 \
            and parts[0] == 'trial_distribution':
        value = ((scenario.get('simulator') or {}).get(parts[1]) or {}).get(parts[2])
    return None if value is None else float(value)


def resolve(entries, scenario, defaults, check=check_simulator_setting):
    """Each entry's nominal (the scenario's value, else the sweep file's, else the declared
    default; `nominal_from` says which) and its check against the declarations: a known name,
    and low, high and the nominal taken by the Simulator's declaration (`check(name, value)`:
    None or its message) or within the delays' range. Raises SweepError naming the entry."""
    for index, entry in enumerate(entries, 1):
        where = 'constant %d (%s)' % (index, entry['key'])
        if entry['kind'] == 'engine_delays' and entry['name'] not in engine_core.DELAY_OPTIONS:
            raise SweepError('%s: unknown engine delay %r (known: %s)' % (
                where, entry['name'], ', '.join(sorted(engine_core.DELAY_OPTIONS))))
        set_value = bench_value(scenario, entry['kind'], entry['name'])
        if set_value is not None and entry['nominal'] is not None \
                and not same_value(set_value, entry['nominal']):
            raise SweepError('%s: the scenario sets %s, the sweep file says nominal %s'
                             % (where, number_text(set_value), number_text(entry['nominal'])))
        default = defaults[entry['kind']].get(entry['name'])
        for origin, value in (('scenario', set_value), ('sweep file', entry['nominal']),
                              ('default', default)):
            if value is not None:
                entry['nominal'], entry['nominal_from'] = value, origin
                break
        _check_values(where, entry, check)
        if entry['nominal'] is None:
            raise SweepError('%s: no declared default; give its nominal' % where)
        if not entry['low'] <= entry['nominal'] <= entry['high']:
            raise SweepError('%s: the nominal %s (%s) is outside [%s, %s]' % (
                where, number_text(entry['nominal']), entry['nominal_from'],
                number_text(entry['low']), number_text(entry['high'])))
    return entries


def _check_values(where, entry, check):
    """low, high and a nominal the sweep file gives (the scenario's was checked with it, a
    default by its declaration) against the declarations."""
    values = [('low', entry['low']), ('high', entry['high'])]
    if entry.get('nominal_from') == 'sweep file':
        values.append(('nominal', entry['nominal']))
    for label, value in values:
        if entry['kind'] == 'engine_delays':
            if not DELAY_RANGE[0] <= value <= DELAY_RANGE[1]:
                raise SweepError('%s: %s %s s is outside the delays\' [0, 1] s' % (
                    where, label, number_text(value)))
            continue
        message = check(entry['name'], value)
        if message:
            raise SweepError('%s: %s %s: %s' % (where, label, number_text(value), message))


def same_value(a, b):
    """Whether two values of a constant are the same setting."""
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def select(entries, only):
    """The entries named by --only (by key or bare name; all when `only` is empty)."""
    if not only:
        return entries
    known = {e['key']: e for e in entries}
    known.update({e['name']: e for e in entries})
    for name in only:
        if name not in known:
            raise SweepError('--only %s: no such constant in the sweep file (known: %s)'
                             % (name, ', '.join(e['key'] for e in entries)))
    chosen = {known[name]['key'] for name in only}
    return [e for e in entries if e['key'] in chosen]


# --- the benches --------------------------------------------------------------------------------

def nominal_scenario(scenario, entries):
    """The nominal bench: the scenario, with the nominals the sweep file gives and the scenario
    does not set."""
    out = copy.deepcopy(scenario)
    for entry in entries:
        if entry['nominal_from'] == 'sweep file':
            out[entry['kind']] = dict(out.get(entry['kind']) or {}, **{entry['name']:
                                                                        entry['nominal']})
    return out


def conditions(entries, nominal, out_dir):
    """The benches of the sweep: the nominal one, then each constant at its low and high end
    (`scenario` None: the end is the nominal value, whose campaign it uses)."""
    found = [{'id': 'nominal', 'entry': None, 'end': None, 'value': None,
              'dir': os.path.join(out_dir, 'nominal'), 'scenario': nominal}]
    for entry in entries:
        for end in ENDS:
            value = entry[end]
            ident = bench_id(entry, end)
            scenario = None
            if not same_value(value, entry['nominal']):
                scenario = copy.deepcopy(nominal)
                scenario[entry['kind']] = dict(scenario.get(entry['kind']) or {},
                                               **{entry['name']: value})
                for kind, settings in (entry.get('with') or {}).items():
                    scenario[kind] = dict(scenario.get(kind) or {}, **settings)
            found.append({'id': ident, 'entry': entry, 'end': end, 'value': value,
                          'dir': os.path.join(out_dir, ident) if scenario else found[0]['dir'],
                          'scenario': scenario})
    return found


def bench_id(entry, end):
    """The name of a constant's end among the benches (its folder when it has a campaign)."""
    return '%s-%s' % (entry['key'].replace('/', '.'), end)


def label(condition):
    """`nominal`, or `NAME = VALUE (end)`."""
    if condition['entry'] is None:
        return 'nominal'
    text = '%s = %s (%s)' % (condition['entry']['key'], number_text(condition['value']),
                             condition['end'])
    if condition['scenario'] is not None:
        for kind, settings in sorted((condition['entry'].get('with') or {}).items()):
            text += ''.join(', with %s.%s = %s' % (kind, name, value)
                            for name, value in sorted(settings.items()))
    return text


def scenario_text(condition, base_path):
    """The scenario file of a bench, as the sub-campaign reads it (headed by the tool that made
    it: the condition's 'tool', campaign_sensitivity by default)."""
    head = '# %s: %s, %s\n' % (condition.get('tool', TOOL), os.path.basename(base_path),
                               label(condition))
    return head + yaml.safe_dump(condition['scenario'], default_flow_style=False, sort_keys=True)
