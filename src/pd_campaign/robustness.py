"""Robustness curves: each compensator's success and tracking against the size of a model error.

    rosrun pedicle_drilling campaign_robustness [--sweep FILE] [--out DIR] [--trials N]
        [--seed S] [--seed-space SPACE] [--jobs J] [--only ERROR ...]

For each compensator class and each kind of model error of the sweep file
(config/robustness.yaml), one core-engine campaign per error size: the scenario with the
compensator and the error's Simulator parameter at that size, the one case and speed of the sweep
file, in OUT/<compensator>/<error>_<size>/. Every campaign draws the same seeds (a trial's seed
depends on the base seed, the seed space, the speed and the index only), so the curves are
paired trial by trial. The campaigns are run and kept as campaign_sensitivity runs and keeps its
benches (sensitivity.run_all: Table II identified once into OUT/identification, a finished
campaign of the same scenario, design and build kept); each takes the identical trials a
finished campaign under OUT ran (--reuse-trials OUT: the nominal point, the same for every
error, runs once per compensator). Written to OUT, each through a temporary file:
robustness.csv, robustness.md (a table per error and the range of sizes over which each
compensator's success rate stays at or above 95 %) and robustness_<error>.png.
"""
import copy
import csv
import math
import os
import re
import subprocess
import sys
import types

import yaml

from . import aggregate, arguments, sensitivity, tools, trials_csv
from .atomic import atomic_savefig, atomic_write
from .design import CASES
from .identification import IdentificationError
from .scenario import BONE_MOTIONS, PACKAGE_ROOT, Scenario, UsageError

CONFIG_VERSION = 1
CONFIG_KEYS = ('version', 'scenario', 'case', 'rpm', 'trials', 'compensators', 'errors')
ERROR_KEYS = ('name', 'parameter', 'unit', 'label', 'points', 'offset', 'needs_bone_motion')
REQUIRED_ERROR_KEYS = ('name', 'parameter', 'unit', 'label', 'points')
DEFAULTS = {'scenario': 'config/scenario_realistic.yaml', 'case': 'compensated', 'rpm': 12000.0,
            'trials': 100}
DEFAULT_SWEEP = os.path.join(PACKAGE_ROOT, 'config', 'robustness.yaml')
# The range's rule: success count / trials >= 95 %, in integers (19/20 is in it, exactly).
TARGET_NUMERATOR, TARGET_DENOMINATOR = 95, 100
NAME = re.compile(r'^[A-Za-z0-9_-]+$')  # an error's name: a part of file and folder names
TOOL = 'campaign_robustness'


class ConfigError(sensitivity.SweepError):
    """A sweep file, or an entry of it, that cannot be run; the message names the key."""


# --- the sweep file ----------------------------------------------------------------------------

def load_config(path):
    """The sweep file, checked in form (not yet against the bench and the declarations):
    {scenario (a path), case, rpm, trials, compensators, errors}. Raises ConfigError naming the
    key."""
    where = '--sweep %s' % path
    try:
        with open(path) as handle:
            data = yaml.safe_load(handle)
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as error:
        raise ConfigError('%s: cannot read: %s' % (where, ' '.join(str(error).split())))
    if not isinstance(data, dict):
        raise ConfigError('%s: not a mapping with the keys %s' % (where, ', '.join(CONFIG_KEYS)))
    unknown = sorted(set(data) - set(CONFIG_KEYS))
    if unknown:
        raise ConfigError('%s: unknown key %r (known: %s)' % (where, unknown[0],
                                                              ', '.join(CONFIG_KEYS)))
    if data.get('version', CONFIG_VERSION) != CONFIG_VERSION:
        raise ConfigError('%s: version %r is not supported (this tool reads version %d)'
                          % (where, data['version'], CONFIG_VERSION))
    config = dict(DEFAULTS, **{k: v for k, v in data.items() if k != 'version'})
    config['path'] = path
    config['scenario'] = _scenario_path(where, config['scenario'])
    if config['case'] not in CASES:
        raise ConfigError('%s: case %r is not one of %s' % (where, config['case'],
                                                            ', '.join(CASES)))
    rpm = config['rpm']
    if not sensitivity.is_finite_number(rpm) or not 1000.0 <= rpm <= 60000.0:
        raise ConfigError('%s: rpm %r is not a speed in [1000, 60000]' % (where, rpm))
    config['rpm'] = float(rpm)
    trials = config['trials']
    if isinstance(trials, bool) or not isinstance(trials, int) or not 1 <= trials <= 10000:
        raise ConfigError('%s: trials %r is not a count in [1, 10000]' % (where, trials))
    config['compensators'] = _compensators(where, config.get('compensators'))
    errors = config.get('errors')
    if not isinstance(errors, list) or not errors:
        raise ConfigError('%s: errors must be a non-empty list' % where)
    config['errors'] = [_error(where, index, raw) for index, raw in enumerate(errors, 1)]
    names = [e['name'] for e in config['errors']]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError('%s: errors: the name %r is given twice' % (where, twice[0]))
    return config


def _scenario_path(where, value):
    """The scenario's path: absolute, or relative to the package (config/...)."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError('%s: scenario must be a path' % where)
    path = value if os.path.isabs(value) else os.path.join(PACKAGE_ROOT, value)
    if not os.path.isfile(path):
        raise ConfigError('%s: scenario %s: no such file (a relative path is taken from the '
                          'package, %s)' % (where, value, PACKAGE_ROOT))
    return path


def _compensators(where, value):
    if not isinstance(value, list) or not value:
        raise ConfigError('%s: compensators must be a non-empty list of compensator classes'
                          % where)
    for name in value:
        if not isinstance(name, str) or not name.strip():
            raise ConfigError('%s: compensators: %r is not a class name' % (where, name))
    twice = sorted({n for n in value if value.count(n) > 1})
    if twice:
        raise ConfigError('%s: compensators: %s is listed twice' % (where, twice[0]))
    return list(value)


def _error(where, index, raw):
    """One entry of `errors`, checked in form."""
    where = sensitivity.entry_form('%s: errors, entry %d' % (where, index), raw, ERROR_KEYS,
                                   REQUIRED_ERROR_KEYS, ConfigError)
    if not isinstance(raw['name'], str) or not NAME.match(raw['name']):
        raise ConfigError('%s: name must be letters, digits, _ or - (it names files)' % where)
    if not isinstance(raw['parameter'], str) or not raw['parameter'].strip():
        raise ConfigError('%s: parameter must name a Simulator parameter' % where)
    if not isinstance(raw['unit'], str):
        raise ConfigError('%s: unit must be a text (\'\' for none)' % where)
    if not isinstance(raw['label'], str) or not raw['label'].strip():
        raise ConfigError('%s: label must be a non-empty text' % where)
    points = raw['points']
    if not isinstance(points, list) or not points:
        raise ConfigError('%s: points is empty (give the error sizes, a list of numbers)'
                          % where)
    for point in points:
        if not sensitivity.is_finite_number(point):
            raise ConfigError('%s: points: %r is not a finite number' % (where, point))
    if len({'%g' % p for p in points}) != len(points):  # '%g': the size in a folder's name
        raise ConfigError('%s: points: a size is given twice' % where)
    if not isinstance(raw.get('offset', False), bool):
        raise ConfigError('%s: offset must be true or false' % where)
    needs = raw.get('needs_bone_motion')
    if needs is not None and needs not in BONE_MOTIONS:
        raise ConfigError('%s: needs_bone_motion %r is not one of %s'
                          % (where, needs, ', '.join(BONE_MOTIONS)))
    return {'name': raw['name'], 'parameter': raw['parameter'].strip(), 'unit': raw['unit'],
            'label': raw['label'].strip(), 'points': sorted(float(p) for p in points),
            'offset': raw.get('offset', False), 'needs_bone_motion': needs}


def select(errors, only):
    """The errors named by --only (all when `only` is empty)."""
    known = [e['name'] for e in errors]
    for name in only:
        if name not in known:
            raise ConfigError('--only %s: no such error in the sweep file (known: %s)'
                              % (name, ', '.join(known)))
    return [e for e in errors if not only or e['name'] in only]


# --- the sweep file against the bench and the declarations ------------------------------------

def check_compensator(name, scenario):
    """None if trial_engine loads the compensator class with the scenario's compensator_params
    (the campaign's own check), else its message."""
    params = arguments.class_params(None, Scenario(scenario).compensator_params,
                                    '--compensator-param')
    result = subprocess.run(tools.tool('trial_engine') + ['--check-compensator', name] +
                            ['%s=%s' % kv for kv in sorted(params.items())],
                            capture_output=True, text=True)
    if result.returncode == 0:
        return None
    lines = result.stderr.strip().splitlines()
    return lines[-1] if lines else 'the class does not load'


def _setting(error, point):
    """The parameter's value at a point."""
    return float('%.12g' % (error['nominal'] + point)) if error['offset'] else point


def resolve(config, errors, scenario, defaults, check=sensitivity.check_simulator_setting,
            compensator_check=check_compensator):
    """Each error's nominal (the scenario's value of its parameter, else the declared default in
    `defaults`), its settings (the parameter's value at each point) and its checks: the bone
    motion it needs, the nominal point among its points, every setting taken by the Simulator's
    declaration (`check(name, value)`: None or its message, as campaign_sensitivity checks its
    ends); and every compensator class loaded (`compensator_check(name, scenario)`). Raises
    ConfigError naming the key."""
    for name in config['compensators']:
        message = compensator_check(name, scenario)
        if message:
            raise ConfigError('--sweep %s: compensators: %s: %s' % (config['path'], name,
                                                                  message))
    bone_motion = Scenario(scenario).bone_motion
    for error in errors:
        where = '--sweep %s: errors, %s (%s)' % (config['path'], error['name'],
                                                 error['parameter'])
        if error['needs_bone_motion'] not in (None, bone_motion):
            raise ConfigError('%s: needs_bone_motion %s, the scenario has bone_motion %s'
                              % (where, error['needs_bone_motion'], bone_motion))
        nominal = sensitivity.bench_value(scenario, 'simulator_params', error['parameter'])
        error['nominal_from'] = 'the scenario\'s' if nominal is not None else 'the default'
        nominal = nominal if nominal is not None else defaults.get(error['parameter'])
        if nominal is None:
            message = check(error['parameter'], error['points'][0])
            raise ConfigError('%s: %s' % (where, message or 'no declared default (not a '
                                          'number parameter of the Simulator)'))
        error['nominal'] = nominal
        centre = 0.0 if error['offset'] else nominal
        if not any(sensitivity.same_value(p, centre) for p in error['points']):
            raise ConfigError('%s: points must include the nominal point %g (%s %s = %g)' % (
                where, centre, error['nominal_from'], error['parameter'], nominal))
        error['settings'] = [_setting(error, p) for p in error['points']]
        for point, value in zip(error['points'], error['settings']):
            message = check(error['parameter'], value)
            if message:
                raise ConfigError('%s: points: %g (%s = %g): %s' % (
                    where, point, error['parameter'], value, message))
    return errors


# --- the campaigns ------------------------------------------------------------------------------

def compensator_folder(name):
    """The folder of a compensator's campaigns: its class name, / and : as '.'."""
    return name.replace('/', '.').replace(':', '.')


def _derived(scenario, config, design, compensator, error, setting, nominal):
    """The scenario of one point: the bench with the compensator, the case, the speed and the
    design, and the parameter at the point (left at the bench's at the nominal point, so that
    its trials are the same for every error and reused)."""
    out = copy.deepcopy(scenario)
    out.update(compensator=compensator, cases=[config['case']], rpms=[config['rpm']],
               trials=design['trials'], seed=design['seed'], seed_space=design['seed_space'])
    if not nominal:
        out['simulator_params'] = dict(out.get('simulator_params') or {},
                                       **{error['parameter']: setting})
    return out


def benches(config, errors, scenario, design, out_dir):
    """The campaigns, one per compensator, error and point, as sensitivity.run_all takes them
    (id, dir, scenario, and entry, end and value for its label), in the order they run: the first
    error's nominal points first, the other errors' nominal points last (their trials are the
    first's, taken with --reuse-trials)."""
    found = []
    for k, compensator in enumerate(config['compensators']):
        for e, error in enumerate(errors):
            for point, setting in zip(error['points'], error['settings']):
                nominal = sensitivity.same_value(setting, error['nominal'])
                ident = os.path.join(compensator_folder(compensator),
                                     '%s_%g' % (error['name'], point))
                found.append({
                    'id': ident, 'dir': os.path.join(out_dir, ident),
                    'scenario': _derived(scenario, config, design, compensator, error, setting,
                                         nominal),
                    'entry': {'key': '%s: %s' % (compensator, error['parameter']), 'with': {}},
                    'end': '%s %g%s' % (error['name'], point, ', nominal' if nominal else ''),
                    'value': setting, 'compensator': compensator, 'error': error, 'tool': TOOL,
                    'point': point, 'nominal': nominal, 'order': (e, k, point)})
    first = errors[0]['name']
    return sorted(found, key=lambda c: 1 if not c['nominal'] else
                  (0 if c['error']['name'] == first else 2))


# --- the results ----------------------------------------------------------------------------------

def cell(rows, case, rpm):
    """A point's numbers from its campaign's trial rows (trials_csv.read_trials_csv) of the case and
    speed, trials without a fault: the trials that did not error, their successes with the Wilson
    95 % interval, the H1 stops, the breakthroughs, the median tracking RMS and the errored
    trials (aggregate.summarise and aggregate.h1_by_volunteer, as the campaign's report counts
    them)."""
    rows = [r for r in rows if r['case'] == case and r['rpm'] == rpm]
    group = next(iter(aggregate.summarise(rows)), None)
    if group is None:
        return {'trials': 0, 'successes': 0, 'wilson95': [0.0, 1.0], 'h1_stops': 0,
                'breakthroughs': 0, 'median_tracking_rms_mm': None, 'errors': 0}
    return {'trials': group['trials'], 'successes': group['successes'],
            'wilson95': list(group['wilson95']),
            'h1_stops': sum(g['h1_stops'] for g in aggregate.h1_by_volunteer(rows)),
            'breakthroughs': group['trials'] - group['no_penetration'],
            'median_tracking_rms_mm': group['median_tracking_rms_mm'],
            'errors': group['errors']}


def read_results(points, case, rpm):
    """One result row per campaign (compensator, error, point): its cell(); in the sweep file's
    order of the errors and the compensators, by size."""
    out = []
    for c in sorted(points, key=lambda c: c['order']):
        rows = trials_csv.read_trials_csv(os.path.join(c['dir'], 'trials.csv'))
        error = c['error']
        out.append(dict(cell(rows, case, rpm), compensator=c['compensator'],
                        error=error['name'], parameter=error['parameter'], value=c['point'],
                        setting=c['value'], unit=error['unit'], nominal=c['nominal']))
    return out


def reaches_target(c):
    """Whether a point's success count / trials is at least 95 %."""
    return c['trials'] > 0 and \
        c['successes'] * TARGET_DENOMINATOR >= TARGET_NUMERATOR * c['trials']


def range_95(cells, nominal_index):
    """(first, last): the indices of the contiguous run of points around the nominal one (cells
    sorted by error size) whose success count / trials is at least 95 %; None when the nominal
    point's is below."""
    if not reaches_target(cells[nominal_index]):
        return None
    first = last = nominal_index
    while first > 0 and reaches_target(cells[first - 1]):
        first -= 1
    while last < len(cells) - 1 and reaches_target(cells[last + 1]):
        last += 1
    return first, last


def _size(value, unit):
    return '%g%s' % (value, ' ' + unit if unit else '')


def range_text(curve, unit):
    """The one line on a curve's 95 % range: `curve` is the result rows of one compensator and
    error, sorted by size, one of them the nominal point."""
    nominal = next(i for i, r in enumerate(curve) if r['nominal'])
    found = range_95(curve, nominal)
    if found is None:
        return 'below 95 %% at the nominal point itself (%s: %d/%d)' % (
            _size(curve[nominal]['value'], unit), curve[nominal]['successes'],
            curve[nominal]['trials'])
    first, last = found
    below = [_size(curve[i]['value'], unit) for i in (first - 1, last + 1)
             if 0 <= i < len(curve)]
    if not below:
        return 'at or above 95 %% at every size run, %s to %s (it may go further)' % (
            _size(curve[first]['value'], unit), _size(curve[last]['value'], unit))
    if first == last:
        text = 'at or above 95 %% at the nominal point (%s) only' % _size(curve[first]['value'],
                                                                         unit)
    else:
        text = 'at or above 95 %% from %s%s to %s%s' % (
            _size(curve[first]['value'], unit), ' (the smallest size run)' if first == 0 else '',
            _size(curve[last]['value'], unit),
            ' (the largest size run)' if last == len(curve) - 1 else '')
    return text + '; below at %s' % ' and '.join(below)


def curves(results, error):
    """[(compensator, its rows sorted by size)] of one error, in the results' order (the sweep
    file's)."""
    out = {}
    for row in results:
        if row['error'] == error:
            out.setdefault(row['compensator'], []).append(row)
    return [(k, sorted(v, key=lambda r: r['value'])) for k, v in out.items()]


# --- the outputs ----------------------------------------------------------------------------------

CSV_COLUMNS = ['compensator', 'error', 'parameter', 'value', 'setting', 'unit', 'nominal',
               'trials', 'successes', 'wilson_low', 'wilson_high', 'h1_stops', 'breakthroughs',
               'median_tracking_rms_mm', 'errors']


def csv_rows(results):
    """robustness.csv's rows: one per compensator, error and point."""
    out = []
    for r in results:
        rms = r['median_tracking_rms_mm']
        out.append(dict({k: r[k] for k in ('compensator', 'error', 'parameter', 'unit', 'trials',
                                          'successes', 'h1_stops', 'breakthroughs', 'errors')},
                        value='%g' % r['value'], setting='%g' % r['setting'],
                        nominal='true' if r['nominal'] else 'false',
                        wilson_low='%.6g' % r['wilson95'][0],
                        wilson_high='%.6g' % r['wilson95'][1],
                        median_tracking_rms_mm='' if rms is None else '%.6g' % rms))
    return out


def _unit(unit):
    return ' [%s]' % unit if unit else ''


def error_markdown(error, results):
    """The section of one error: its figure, its table and each compensator's 95 % range."""
    lines = ['## %s: %s' % (error['name'], error['label']), '',
             '`%s` = %g at the nominal point (%s)%s.' % (
                 error['parameter'], error['nominal'], error['nominal_from'],
                 '; a size is added to it' if error['offset'] else ''), '',
             '![%s](robustness_%s.png)' % (error['name'], error['name']), '',
             '| compensator | size%s | `%s` | success | Wilson 95 %% | H1 stops | breakthroughs '
             '| median tracking RMS [mm] |' % (_unit(error['unit']), error['parameter']),
             '|---|---|---|---|---|---|---|---|']
    found = curves(results, error['name'])
    for compensator, curve in found:
        for r in curve:
            rms = r['median_tracking_rms_mm']
            lines.append('| `%s` | %g%s | %g | %d/%d | %.0f-%.0f %% | %d | %d | %s |' % (
                compensator, r['value'], ' (nominal)' if r['nominal'] else '',
                r['setting'], r['successes'], r['trials'], 100 * r['wilson95'][0],
                100 * r['wilson95'][1], r['h1_stops'], r['breakthroughs'],
                '-' if rms is None else '%.2f' % rms))
    lines += ['', 'Success rate at or above 95 % (successes / trials >= 0.95), the contiguous '
              'range of sizes around the nominal point:', '']
    lines += ['- `%s`: %s.' % (compensator, range_text(curve, error['unit']))
              for compensator, curve in found]
    return '\n'.join(lines)


def design_markdown(setup):
    """The head of robustness.md."""
    return '\n'.join([
        '# Robustness curves', '',
        'Scenario `%s`, sweep `%s`: the %s case at %.0f rpm, %d trials per point, base seed %d, '
        '%s seeds. For each compensator and each model error, one campaign per error size; '
        'every campaign draws the same seeds, so the points and the compensators are paired '
        'trial by trial. Success k/n (trials that errored left out) with its Wilson 95 %% '
        'interval; H1 stops: trials whose first stop was the safety monitor\'s position error; '
        'breakthroughs: trials that perforated the inner cortex; the tracking RMS is the '
        'median over the trials of the tip-bone AP tracking RMS. The campaigns are in '
        '`<compensator>/<error>_<size>/`.' % (
            sensitivity.shown(setup['scenario']), sensitivity.shown(setup['sweep']),
            setup['case'], setup['rpm'], setup['trials'], setup['seed'], setup['seed_space'])])


def figure(error, results, path):
    """robustness_<error>.png: the success rate with its Wilson 95 % interval against the error's
    size, one line per compensator (shifted a little apart), and the median tracking RMS below."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    found = curves(results, error['name'])
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 6.4))
    span = (max(error['points']) - min(error['points'])) or 1.0
    for k, (compensator, curve) in enumerate(found):
        shift = (k - (len(found) - 1) / 2.0) * 0.01 * span
        x = [r['value'] + shift for r in curve]
        rate = [100.0 * r['successes'] / r['trials'] if r['trials'] else math.nan for r in curve]
        low = [max(0.0, y - 100.0 * r['wilson95'][0]) if r['trials'] else 0.0
               for y, r in zip(rate, curve)]
        high = [max(0.0, 100.0 * r['wilson95'][1] - y) if r['trials'] else 0.0
                for y, r in zip(rate, curve)]
        name = compensator.split('/')[-1]
        top.errorbar(x, rate, yerr=[low, high], marker='o', capsize=3, label=name)
        rms = [math.nan if r['median_tracking_rms_mm'] is None else r['median_tracking_rms_mm']
               for r in curve]
        bottom.plot([r['value'] for r in curve], rms, marker='o', label=name)
    nominal = 0.0 if error['offset'] else error['nominal']
    for ax in (top, bottom):
        ax.axvline(nominal, color='grey', linewidth=0.8, linestyle='--')
        ax.grid(True, alpha=0.3)
    top.axhline(95.0, color='black', linewidth=0.8, linestyle=':')
    top.set_ylim(-2, 102)
    top.set_ylabel('success [%] (Wilson 95 %)')
    top.legend(fontsize=8)
    top.set_title('%s: %s, nominal %g%s' % (error['name'], error['parameter'], error['nominal'],
                                             ', plus the size' if error['offset'] else ''),
                  fontsize=9)
    bottom.set_ylabel('median tracking RMS [mm]')
    bottom.set_xlabel(error['label'] + _unit(error['unit']), fontsize=8)
    fig.tight_layout()
    try:
        atomic_savefig(fig, path, dpi=100)
    finally:
        plt.close(fig)


def write_tables(setup, errors, results, statuses):
    """robustness.csv and robustness.md in the output folder, each through a temporary file;
    the 95 % ranges' lines as text."""
    out = setup['out']
    with atomic_write(os.path.join(out, 'robustness.csv'), newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        writer.writerows(csv_rows(results))
    sections = [error_markdown(e, results) for e in errors]
    failed = sorted(k for k, v in statuses.items() if v)
    if failed:
        sections.append('Campaigns that did not finish every trial (their numbers cover the '
                        'trials they have): %s.' % ', '.join('`%s` (exit %d)' % (k, statuses[k])
                                                             for k in failed))
    with atomic_write(os.path.join(out, 'robustness.md')) as handle:
        handle.write('\n\n'.join([design_markdown(setup)] + sections) + '\n')
    return '\n'.join('%s, %s: %s' % (compensator, e['name'], range_text(curve, e['unit']))
                     for e in errors for compensator, curve in curves(results, e['name']))


def write_outputs(setup, errors, results, statuses):
    """Every output: the tables and one figure per error."""
    ranges = write_tables(setup, errors, results, statuses)
    for error in errors:
        figure(error, results, os.path.join(setup['out'], 'robustness_%s.png' % error['name']))
    return ranges


# --- the command line ---------------------------------------------------------------------------

def parse_args(argv):
    """The command line."""
    parser = tools.argument_parser(prog=TOOL, description=__doc__.split('\n')[0])
    parser.add_argument('--sweep', default=DEFAULT_SWEEP,
                        help='the bench, the compensators and the errors with their sizes '
                        '(default: config/robustness.yaml)')
    parser.add_argument('--out', default='robustness_out',
                        help='the output folder, one subfolder per campaign (default: '
                        'robustness_out)')
    parser.add_argument('--trials', type=int, help='trials per point (default: the sweep '
                        'file\'s)')
    parser.add_argument('--seed', type=int, help='base seed (default: the scenario\'s)')
    parser.add_argument('--seed-space', help='calibration | evaluation (default: the '
                        'scenario\'s, else evaluation)')
    parser.add_argument('--jobs', type=int, default=2,
                        help='campaigns run at once, one trial_engine process each (a trial '
                        'depends on its seed only: the results do not depend on it)')
    parser.add_argument('--only', action='append', default=[], metavar='ERROR',
                        help='run only this error (its name in the sweep file; repeatable)')
    return parser.parse_args(argv)


def prepare(args):
    """Everything checked before any campaign runs: the sweep file, the campaign options and the
    scenario, the errors against the declarations; (setup, the campaigns' options, the design a
    kept campaign must have, the campaigns)."""
    config = load_config(args.sweep)
    errors = select(config['errors'], args.only)
    options = types.SimpleNamespace(
        scenario=config['scenario'], rpm='%r' % config['rpm'],
        trials=str(args.trials if args.trials is not None else config['trials']),
        seed=args.seed, seed_space=args.seed_space, reuse_trials=None, jobs=args.jobs)
    argv, scenario, expected = sensitivity.campaign_argv(options)
    argv += ['--case', config['case']]
    expected['cases'] = [config['case']]
    defaults = sensitivity.declared_defaults()['simulator_params']
    resolve(config, errors, scenario, defaults)
    out = os.path.abspath(args.out)
    setup = {'scenario': config['scenario'], 'sweep': args.sweep, 'out': out,
             'case': config['case'], 'rpm': config['rpm'], 'trials': expected['trials'],
             'seed': expected['seed'], 'seed_space': expected['seed_space']}
    argv += ['--reuse-trials', out]
    return setup, errors, argv, expected, benches(config, errors, scenario, setup, out)


def main(argv=None):
    """`rosrun pedicle_drilling campaign_robustness`: exit 0, 1 when a campaign left trials
    unfinished (the outputs cover the others) or the identification failed, 2 for a refused
    sweep or scenario, 130 on Ctrl-C."""
    args = parse_args(argv)
    try:
        setup, errors, campaign, expected, points = prepare(args)
        os.makedirs(setup['out'], exist_ok=True)
        sys.stderr.write('%s: %d compensator(s) x %d error(s), %d campaign(s) of %d trials into '
                         '%s\n' % (TOOL, len({c['compensator'] for c in points}), len(errors),
                                   len(points), setup['trials'], setup['out']))
        sys.stderr.flush()
        statuses = sensitivity.run_all(points, campaign, expected, setup['scenario'],
                                       sys.stderr, args.jobs, setup['out'])
    except (sensitivity.SweepError, UsageError) as error:
        sys.stderr.write('%s: %s\n' % (TOOL, error))
        return 2
    except IdentificationError as error:
        sys.stderr.write('%s: %s\n' % (TOOL, error))
        return 1
    except (OSError, RuntimeError, ValueError, subprocess.CalledProcessError) as error:
        sys.stderr.write('%s: cannot ask the built tools (make build?): %s\n' % (TOOL, error))
        return 2
    except KeyboardInterrupt:
        sys.stderr.write('%s: interrupted; the finished campaigns are kept (run the same command '
                         'again to resume)\n' % TOOL)
        return 130
    try:
        results = read_results(points, setup['case'], setup['rpm'])
    except (OSError, ValueError) as error:
        sys.stderr.write('%s: a campaign left no readable trials.csv: %s\n' % (TOOL, error))
        return 1
    ranges = write_outputs(setup, errors, results, statuses)
    sys.stdout.write('%s\nwritten: %s/robustness.md, robustness.csv, %s\n' % (
        ranges, setup['out'], ', '.join('robustness_%s.png' % e['name'] for e in errors)))
    return 1 if any(statuses.values()) else 0


if __name__ == '__main__':
    sys.exit(main())
