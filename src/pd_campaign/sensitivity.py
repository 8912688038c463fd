"""Sensitivity of the campaign's conclusions to the bench's uncertain constants.

    rosrun pedicle_drilling campaign_sensitivity [--scenario FILE] [--sweep FILE] [--rpm R,...]
        [--trials N] [--seed S] [--seed-space SPACE] [--jobs J] [--out DIR] [--only NAME ...]

One constant at a time goes to each end of its documented range (config/sensitivity.yaml), every
other constant stays at the nominal bench (the scenario). Each bench is one campaign, run by the
campaign itself (scripts/campaign) into a subdirectory of --out: `nominal` and
`<kind>.<name>-low` / `-high`, all on the same seeds (a trial's seed depends on the base seed,
the seed space, the speed and the index only, design.py), so every end is paired with the
nominal bench trial by trial. An end equal to the nominal value uses the nominal campaign. A
subdirectory that already holds the finished campaign of the same scenario and design, run by
the same build (tools.build_id: the trial_engine executable, the package's libraries and this
Python package's sources; its build.json), is kept (the sweep resumes). Written to --out, each through a temporary file: sensitivity.md (per case
and speed, one row per constant, sorted by the largest swing: success at low, nominal and high
with Wilson 95 % intervals, McNemar's exact p of each end against the nominal, the failure kinds
that moved; then the verdict of each conclusion at the nominal bench and at every swept end),
sensitivity.csv, sensitivity.json and sensitivity.png (a tornado plot per case and speed).
"""
import collections
import copy
import csv
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time

import yaml

from . import arguments, campaign_process, engine_core, report, stats, tools
from .atomic import atomic_savefig, atomic_write
from .design import CASES
from .progress import clock
from .scenario import DEFAULT_SCENARIO, PACKAGE_ROOT, UsageError

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


class IdentificationError(RuntimeError):
    """The sweep's one Table II identification (table2.py) failed."""


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
        raise SweepError('%s: low %s is not below high %s' % (where, _g(low), _g(high)))
    if nominal is not None and not low <= nominal <= high:
        raise SweepError('%s: nominal %s is outside [%s, %s]' % (where, _g(nominal), _g(low),
                                                                 _g(high)))
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


def _g(value):
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
                             % (where, _g(set_value), _g(entry['nominal'])))
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
                where, _g(entry['nominal']), entry['nominal_from'], _g(entry['low']),
                _g(entry['high'])))
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
                    where, label, _g(value)))
            continue
        message = check(entry['name'], value)
        if message:
            raise SweepError('%s: %s %s: %s' % (where, label, _g(value), message))


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
    text = '%s = %s (%s)' % (condition['entry']['key'], _g(condition['value']), condition['end'])
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


# --- running the sub-campaigns -------------------------------------------------------------------

def is_complete(directory, text, expected):
    """Whether `directory` holds the finished campaign of this scenario text and design: the same
    scenario.yaml, a design.json whose meta has the `expected` values, every trial of the design
    in trials.csv, and its summary.json."""
    try:
        with open(os.path.join(directory, 'scenario.yaml')) as handle:
            if handle.read() != text:
                return False
        with open(os.path.join(directory, 'design.json')) as handle:
            meta = json.load(handle)['meta']
        if any(meta.get(key) != value for key, value in expected.items()):
            return False
        rows = report.read_trials_csv(os.path.join(directory, 'trials.csv'))
        return os.path.isfile(os.path.join(directory, 'summary.json')) \
            and len(rows) == meta['design_size']
    except (OSError, ValueError, KeyError, TypeError):
        return False


# The sweep's running campaigns (run_campaign_process), so that a stop of the sweep reaches them.
_RUNNING = set()
_RUNNING_LOCK = threading.Lock()
STOP_GRACE_S = 10.0  # a campaign's own Ctrl-C handling, before the sweep sends it SIGINT


def run_campaign_process(argv, log_path):
    """Runs the campaign with `argv`, its output to `log_path`; its exit status. A campaign
    stopped by SIGINT (Ctrl-C reaches the whole process group; stop_running() sends it to the
    campaigns when only the sweep got it) stops its own workers and keeps its finished trials
    (exit 130). The campaign is forked from a server that imported its modules once
    (campaign_process)."""
    with open(log_path, 'w'):  # not atomic: the sub-campaign's live log, written by it
        pass
    process = campaign_process.CampaignProcess(argv, log_path)
    with _RUNNING_LOCK:
        _RUNNING.add(process)
    try:
        return process.wait()
    finally:
        with _RUNNING_LOCK:
            _RUNNING.discard(process)


def stop_running(futures):
    """Stops the sweep's running campaigns: each gets STOP_GRACE_S to end by itself (a Ctrl-C on
    the terminal reached it too), then SIGINT; waits for `futures` (their threads) to end."""
    import concurrent.futures
    _, still = concurrent.futures.wait(futures, timeout=STOP_GRACE_S)
    if still:
        with _RUNNING_LOCK:
            running = list(_RUNNING)
        for process in running:
            try:
                process.send_signal(signal.SIGINT)
            except ProcessLookupError:
                pass
        concurrent.futures.wait(still)


BUILD_FILE = 'build.json'


def built_by(directory):
    """The build_id() a finished campaign in `directory` was run by (None: unknown)."""
    try:
        with open(os.path.join(directory, BUILD_FILE)) as handle:
            return json.load(handle).get('build_id')
    except (OSError, ValueError, AttributeError):
        return None


def is_kept(condition, expected, base_path, build):
    """A bench whose directory holds its finished campaign already, run by the same build
    (`build`, tools.build_id(); None: never kept)."""
    directory = condition['dir']
    return build is not None and built_by(directory) == build and \
        is_complete(directory, scenario_text(condition, base_path), expected)


def run_condition(condition, argv, expected, base_path, build=None):
    """('kept' | 'ran', exit status) of one bench: kept when is_kept(), else run into its
    directory."""
    if is_kept(condition, expected, base_path, build):
        return 'kept', 0
    directory = condition['dir']
    text = scenario_text(condition, base_path)
    os.makedirs(directory, exist_ok=True)
    stamp = os.path.join(directory, BUILD_FILE)
    if os.path.exists(stamp):
        os.remove(stamp)  # the campaign about to run is not the one it described
    path = os.path.join(directory, 'scenario.yaml')
    with atomic_write(path) as handle:
        handle.write(text)
    status = run_campaign_process(argv + ['--scenario', path, '--out', directory],
                                  os.path.join(directory, 'campaign.log'))
    if status == 0 and build is not None:
        with atomic_write(stamp) as handle:
            json.dump({'build_id': build}, handle)
    return 'ran', status


def _log_tail(directory, lines=5):
    try:
        with open(os.path.join(directory, 'campaign.log')) as handle:
            return ''.join(handle.readlines()[-lines:])
    except OSError:
        return ''


IDENTIFICATION_DIR = 'identification'


def identify(out, jobs):
    """Table II once for the whole sweep, into OUT/identification (the campaigns read it with
    --identification: it takes no scenario setting, so every bench's campaign would identify the
    same models). Raises IdentificationError with table2.py's message when it fails."""
    directory = os.path.join(out, IDENTIFICATION_DIR)
    result = subprocess.run(tools.tool('table2.py') + ['--out', directory, '--jobs', str(jobs),
                                                       '--no-figure'],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise IdentificationError('the Table II identification failed:\n%s'
                                  % (result.stderr or result.stdout))
    return directory


def run_all(benches, argv, expected, base_path, stream, jobs=1, out=None):
    """Runs every bench that needs a campaign, up to `jobs` campaigns at once (each one
    trial_engine process: a trial depends on its seed only, so the campaigns' trials do not
    depend on it), one line on `stream` per finished one; {id: status} (0 for a kept one). The
    Table II identification runs once, into `out` (None: each campaign identifies itself). Stops
    starting campaigns at the first that refuses its scenario (2), lets the running ones finish,
    then raises SweepError."""
    import concurrent.futures
    todo = [c for c in benches if c['scenario'] is not None]
    statuses, start, ran = {}, time.time(), 0
    build = tools.build_id()
    pending = [c for c in todo if not is_kept(c, expected, base_path, build)]
    if pending and out is not None:
        argv = argv + ['--identification', identify(out, jobs), '--no-figures']
    refused = None

    def one(condition):
        began = time.time()
        how, status = run_condition(condition, argv, expected, base_path, build)
        return condition, how, status, time.time() - began

    waiting = collections.deque(todo)
    running = set()
    done_count = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        try:
            while waiting or running:
                # At most `jobs` campaigns at a time; none starts after a refusal.
                while waiting and len(running) < max(1, jobs) and refused is None:
                    running.add(pool.submit(one, waiting.popleft()))
                if not running:
                    break
                finished, running = concurrent.futures.wait(
                    running, return_when=concurrent.futures.FIRST_COMPLETED)
                for future in finished:
                    condition, how, status, took = future.result()
                    done_count += 1
                    statuses[condition['id']] = status
                    ran += how == 'ran'
                    elapsed = time.time() - start
                    eta = elapsed / ran * (len(todo) - done_count) if ran else 0
                    what = ('finished in %s (exit %d)' % (clock(took), status)
                            if how == 'ran' else 'complete already, kept')
                    stream.write('%s: [%d/%d] %s: %s; elapsed %s, ETA %s\n' % (
                        condition.get('tool', TOOL), done_count, len(todo), label(condition),
                        what, clock(elapsed), clock(eta)))
                    stream.flush()
                    if status == 130:
                        raise KeyboardInterrupt()
                    if status == 2 and refused is None:
                        refused = condition  # the running ones finish; no new one starts
        except BaseException:
            # Ctrl-C, or anything else: the running campaigns keep their finished trials and
            # stop; none starts after.
            stop_running(running)
            raise
    if refused is not None:
        raise SweepError('the campaign refused %s (%s):\n%s' % (
            label(refused), refused['dir'], _log_tail(refused['dir'])))
    return statuses


def read_results(benches):
    """{bench id: its fault-free trial rows}; an end equal to the nominal value gets the
    nominal's rows."""
    out = {}
    for condition in benches:
        rows = report.read_trials_csv(os.path.join(condition['dir'], 'trials.csv'))
        out[condition['id']] = [r for r in rows if (r.get('fault') or 'none') == 'none']
    return out


# --- the table ---------------------------------------------------------------------------------

def _group(rows, case, rpm):
    return [r for r in rows if r['case'] == case and r['rpm'] == rpm]


def success_cell(rows):
    """Successes of the trials that did not error, their count, the Wilson 95 % interval, the
    errored trials and the failure kinds (pd_campaign.outcome) by count."""
    valid = [r for r in rows if not r.get('error')]
    successes = sum(1 for r in valid if r['success'])
    kinds = {}
    for row in valid:
        kind = row.get('failure_kind') or ('success' if row['success'] else 'unknown')
        kinds[kind] = kinds.get(kind, 0) + 1
    return {'successes': successes, 'trials': len(valid), 'errors': len(rows) - len(valid),
            'wilson95': list(stats.wilson_interval(successes, len(valid))),
            'failure_kinds': dict(sorted(kinds.items()))}


def rate(cell):
    """Success rate of a cell, None without trials."""
    return cell['successes'] / cell['trials'] if cell['trials'] else None


def paired_test(end_rows, nominal_rows):
    """McNemar's exact test of an end against the nominal bench on the same seeds."""
    pairs, _, only_end, only_nominal, _ = stats.paired_counts(end_rows, nominal_rows,
                                                             key=lambda r: r['seed'])
    return {'pairs': pairs, 'only_end': only_end, 'only_nominal': only_nominal,
            'mcnemar_p': stats.mcnemar_exact(only_end, only_nominal)}


def moved_kinds(end_cell, nominal_cell):
    """{failure kind: [count at the nominal, count at the end]} of the kinds whose count moved
    (success left out: the success columns give it)."""
    a, b = nominal_cell['failure_kinds'], end_cell['failure_kinds']
    return {kind: [a.get(kind, 0), b.get(kind, 0)] for kind in sorted(set(a) | set(b))
            if kind != 'success' and a.get(kind, 0) != b.get(kind, 0)}


def constant_row(entry, nominal_rows, end_rows):
    """One constant in one case and speed: the three cells, each end's test against the nominal
    and its moved failure kinds, and the swing (largest minus smallest of the three rates)."""
    row = {'key': entry['key'], 'name': entry['name'], 'kind': entry['kind'],
           'unit': entry['unit'], 'source': entry['source'], 'low': entry['low'],
           'nominal': entry['nominal'], 'high': entry['high'],
           'nominal_cell': success_cell(nominal_rows)}
    for end in ENDS:
        row[end + '_cell'] = success_cell(end_rows[end])
        row[end + '_test'] = paired_test(end_rows[end], nominal_rows)
        row[end + '_moved'] = moved_kinds(row[end + '_cell'], row['nominal_cell'])
        row[end + '_is_nominal'] = same_value(entry[end], entry['nominal'])
    rates = [rate(row[k + '_cell']) for k in ('low', 'nominal', 'high')]
    rates = [r for r in rates if r is not None]
    row['swing'] = max(rates) - min(rates) if rates else 0.0
    return row


def sensitivity_table(entries, results, cases, rpms):
    """[{case, rpm, rows}] per case and speed; rows sorted by the largest swing first."""
    groups = []
    for rpm in rpms:
        for case in cases:
            rows = []
            for entry in entries:
                ends = {end: _group(results[bench_id(entry, end)], case, rpm) for end in ENDS}
                rows.append(constant_row(entry, _group(results['nominal'], case, rpm), ends))
            rows.sort(key=lambda r: (-r['swing'], r['key']))
            groups.append({'case': case, 'rpm': rpm, 'rows': rows})
    return groups


# --- the conclusions ---------------------------------------------------------------------------

def _verdict(holds, detail):
    return {'holds': holds, 'detail': detail}


def _paired_verdict(rows, rpms, case_a, case_b, holds):
    """At every speed, `holds(only_a, only_b, p)` on the trials of the two cases paired by seed."""
    verdict, details = True, []
    for rpm in rpms:
        a, b = _group(rows, case_a, rpm), _group(rows, case_b, rpm)
        if not a or not b:
            return _verdict(None, 'no %s or %s trials at %.0f rpm' % (case_a, case_b, rpm))
        pairs, both, only_a, only_b, _ = stats.paired_counts(a, b, key=lambda r: r['seed'])
        if pairs == 0:
            errors = [r.get('error') for r in a + b if r.get('error')]
            return _verdict(None, '%.0f rpm: no %s and %s pair without an error%s' % (
                rpm, case_a, case_b, (' (%d errored: %s)' % (len(errors), errors[0]))
                if errors else ''))
        p = stats.mcnemar_exact(only_a, only_b)
        verdict = verdict and holds(only_a, only_b, p)
        details.append('%.0f rpm: %s %d/%d, %s %d/%d, McNemar p = %.2g' % (
            rpm, case_a, both + only_a, pairs, case_b, both + only_b, pairs, p))
    return _verdict(verdict, '; '.join(details))


def compensated_equals_stationary(rows, rpms):
    """At every speed, no significant difference between the compensated and the stationary
    trials of the same seeds (McNemar's exact p >= ALPHA)."""
    return _paired_verdict(rows, rpms, 'compensated', 'stationary',
                           lambda only_a, only_b, p: p >= ALPHA)


def compensated_beats_uncompensated(rows, rpms):
    """At every speed, more compensated than uncompensated successes on the same seeds, and
    significantly so (McNemar's exact p < ALPHA)."""
    return _paired_verdict(rows, rpms, 'compensated', 'uncompensated',
                           lambda only_a, only_b, p: only_a > only_b and p < ALPHA)


def _speed_tests(rows, rpms):
    """[(rpm, successes, trials, p)] of the SPEED_CASE at each speed other than BEST_RPM, with
    Fisher's exact p against BEST_RPM (speeds draw different specimens: independent samples),
    and BEST_RPM's (successes, trials); None when fewer than two speeds or no BEST_RPM."""
    if BEST_RPM not in rpms or len(rpms) < 2:
        return None

    def cell(rpm):
        valid = [r for r in _group(rows, SPEED_CASE, rpm) if not r.get('error')]
        return sum(1 for r in valid if r['success']), len(valid)
    best = cell(BEST_RPM)
    others = [(rpm,) + cell(rpm) for rpm in rpms if rpm != BEST_RPM]
    return best, [(rpm, k, n, stats.fisher_exact(best[0], best[1], k, n))
                  for rpm, k, n in others]


def _speed_detail(best, others):
    return '%s %d/%d at %.0f rpm; ' % (SPEED_CASE, best[0], best[1], BEST_RPM) + '; '.join(
        '%d/%d at %.0f rpm (Fisher p = %.2g)' % (k, n, rpm, p) for rpm, k, n, p in others)


def _higher(k_a, n_a, k_b, n_b):
    return n_a > 0 and (n_b == 0 or k_a * n_b > k_b * n_a)


def best_speed_not_beaten(rows, rpms):
    """'12000 rpm is the best speed': no other speed has a higher success rate of the
    compensated case with Fisher's exact p < ALPHA. None without several speeds."""
    tests = _speed_tests(rows, rpms)
    if tests is None:
        return _verdict(None, 'needs several speeds, %.0f rpm among them' % BEST_RPM)
    best, others = tests
    beaten = [t for t in others if _higher(t[1], t[2], best[0], best[1]) and t[3] < ALPHA]
    return _verdict(not beaten, _speed_detail(best, others))


def best_speed_significantly(rows, rpms):
    """The paper's drop with speed (Fig. 15): 12000 rpm has a higher compensated success rate
    than every other speed, each with Fisher's exact p < ALPHA. None without several speeds."""
    tests = _speed_tests(rows, rpms)
    if tests is None:
        return _verdict(None, 'needs several speeds, %.0f rpm among them' % BEST_RPM)
    best, others = tests
    better = all(_higher(best[0], best[1], t[1], t[2]) and t[3] < ALPHA for t in others)
    return _verdict(better, _speed_detail(best, others))


CONCLUSIONS = (
    ('compensated_equals_stationary', 'Compensated equals stationary',
     'no significant difference (McNemar\'s exact p >= %g) between compensated and stationary on '
     'the same seeds, at every speed' % ALPHA, compensated_equals_stationary),
    ('compensated_beats_uncompensated', 'Compensated beats uncompensated',
     'more compensated than uncompensated successes on the same seeds, McNemar\'s exact p < %g, '
     'at every speed' % ALPHA, compensated_beats_uncompensated),
    ('best_speed', '12000 rpm is the best speed',
     'no other speed has a higher compensated success rate with Fisher\'s exact p < %g' % ALPHA,
     best_speed_not_beaten),
    ('best_speed_significantly', '12000 rpm is significantly the best speed (Fig. 15\'s drop)',
     'the compensated success rate at 12000 rpm is higher than at every other speed, each with '
     'Fisher\'s exact p < %g' % ALPHA, best_speed_significantly),
)


def conclusions(results, benches, rpms):
    """Per conclusion: its verdict at the nominal bench and at every swept end (an end at the
    nominal value is the nominal bench), and the ends where it fails."""
    out = []
    for ident, title, rule, test in CONCLUSIONS:
        nominal = test(results['nominal'], rpms)
        ends = []
        for condition in benches:
            if condition['scenario'] is None or condition['entry'] is None:
                continue  # the nominal bench itself
            verdict = test(results[condition['id']], rpms)
            ends.append(dict(verdict, id=condition['id'], key=condition['entry']['key'],
                             end=condition['end'], value=condition['value']))
        out.append({'id': ident, 'title': title, 'rule': rule, 'nominal': nominal, 'ends': ends,
                    'fails_at': [e for e in ends if e['holds'] is False],
                    'holds_over_range': overall(nominal, ends)})
    return out


def overall(nominal, ends):
    """True when a conclusion holds at the nominal bench and at every end, False when it fails
    at any, None when it cannot be evaluated (at the nominal bench or at an end)."""
    verdicts = [nominal['holds']] + [e['holds'] for e in ends]
    if False in verdicts:
        return False
    return None if None in verdicts else True


# --- the outputs ---------------------------------------------------------------------------------

def _cell_text(cell):
    if not cell['trials']:
        return '-'
    low, high = cell['wilson95']
    return '%d/%d (%.0f-%.0f %%)' % (cell['successes'], cell['trials'], 100 * low, 100 * high)


def _moved_text(row):
    parts = []
    for end in ENDS:
        moved = row[end + '_moved']
        if moved:
            parts.append('%s: %s' % (end, ', '.join('%s %d→%d' % (k, a, b)
                                                    for k, (a, b) in moved.items())))
    return '; '.join(parts) or '-'


def _values_text(row):
    def value(end):
        return _g(row[end]) + (' (nominal)' if row[end + '_is_nominal'] else '')
    unit = ' %s' % row['unit'] if row['unit'] else ''
    return '%s / %s / %s%s' % (value('low'), _g(row['nominal']), value('high'), unit)


def group_markdown(group):
    """The table of one case and speed."""
    nominal = group['rows'][0]['nominal_cell'] if group['rows'] else None
    lines = ['### %s, %.0f rpm' % (group['case'], group['rpm']), '',
             'Nominal bench: %s.' % (_cell_text(nominal) if nominal else '-'), '',
             '| constant | low / nominal / high | success at low | at nominal | at high '
             '| McNemar p, low vs nominal | high vs nominal | swing [points] '
             '| failure kinds that moved (nominal→end) |',
             '|---|---|---|---|---|---|---|---|---|']
    for row in group['rows']:
        p = ['-' if row[end + '_is_nominal'] else '%.2g' % row[end + '_test']['mcnemar_p']
             for end in ENDS]
        lines.append('| `%s` | %s | %s | %s | %s | %s | %s | %.0f | %s |' % (
            row['key'], _values_text(row), _cell_text(row['low_cell']),
            _cell_text(row['nominal_cell']), _cell_text(row['high_cell']), p[0], p[1],
            100 * row['swing'], _moved_text(row)))
    return '\n'.join(lines)


def _holds_text(holds):
    return {True: 'holds', False: 'fails', None: 'not evaluated'}[holds]


def conclusions_markdown(found):
    """The section "Conclusions over the range"."""
    lines = ['## Conclusions over the range', '']
    for c in found:
        lines += ['### %s' % c['title'], '', 'Rule: %s.' % c['rule'], '',
                  '- At the nominal bench: **%s** (%s).' % (_holds_text(c['nominal']['holds']),
                                                            c['nominal']['detail'])]
        unevaluated = [e for e in c['ends'] if e['holds'] is None]
        if c['fails_at']:
            lines.append('- Over the range: **fails at %d of %d swept ends**:' % (
                len(c['fails_at']), len(c['ends'])))
            lines += ['    - `%s` = %s (%s): %s' % (e['key'], _g(e['value']), e['end'],
                                                    e['detail']) for e in c['fails_at']]
        elif c['nominal']['holds'] is None or len(unevaluated) == len(c['ends']):
            lines.append('- Over the range: **not evaluated** (%s).' % (
                (unevaluated[0] if unevaluated else c['nominal'])['detail']))
            unevaluated = []
        elif unevaluated:
            lines.append('- Over the range: **holds at every one of the %d evaluated ends** '
                         '(of %d):' % (len(c['ends']) - len(unevaluated), len(c['ends'])))
        else:
            lines.append('- Over the range: **holds at every one of the %d swept ends**.'
                         % len(c['ends']))
        lines += ['    - not evaluated: `%s` = %s (%s): %s' % (e['key'], _g(e['value']),
                                                               e['end'], e['detail'])
                  for e in unevaluated]
        lines.append('')
    return '\n'.join(lines)


def _shown(path):
    """A path as the report names it: relative to the package for its own files."""
    absolute = os.path.abspath(path)
    inside = absolute.startswith(PACKAGE_ROOT + os.sep)
    return os.path.relpath(absolute, PACKAGE_ROOT) if inside else path


def design_markdown(setup):
    """The head of sensitivity.md: the design and the constants swept."""
    lines = ['# Sensitivity of the conclusions', '',
             'Scenario `%s`, sweep `%s`: %s trials per case and speed at %s rpm, base seed %d, '
             '%s seeds. One constant at a time at each end of its range, every other at the '
             'nominal bench; every bench is a campaign on the same seeds, so each end is paired '
             'with the nominal bench trial by trial. Success k/n with Wilson 95 %% intervals; '
             'McNemar\'s exact p of each end against the nominal bench on the same seeds; the '
             'swing is the largest minus the smallest of the three success rates, and the rows '
             'are sorted by it. An end marked (nominal) is the nominal value: its numbers are '
             'the nominal campaign\'s. Tests are two-sided at %g, without a correction for the '
             'number of tests.' % (
                 _shown(setup['scenario_path']), _shown(setup['sweep_path']), setup['trials'],
                 ', '.join('%.0f' % r for r in setup['rpms']), setup['seed'],
                 setup['seed_space'], ALPHA), '',
             '| constant | low | nominal | high | unit | source |', '|---|---|---|---|---|---|']
    for e in setup['entries']:
        lines.append('| `%s` | %s | %s (%s) | %s | %s | %s |' % (
            e['key'], _g(e['low']), _g(e['nominal']), e['nominal_from'], _g(e['high']),
            e['unit'] or '-', e['source']))
    return '\n'.join(lines)


def benches_markdown(benches, statuses):
    """Where each bench's campaign is, and how its campaign ended."""
    lines = ['## The campaigns', '', '| bench | directory | campaign |', '|---|---|---|']
    for c in benches:
        if c['scenario'] is None:
            how = 'the nominal\'s (the end is the nominal value)'
        else:
            status = statuses.get(c['id'])
            how = 'exit %d' % status if status else 'complete'
        lines.append('| %s | `%s` | %s |' % (label(c), os.path.basename(c['dir']), how))
    return '\n'.join(lines)


CSV_COLUMNS = ['case', 'rpm', 'constant', 'unit', 'low', 'nominal', 'high', 'swing',
               'successes_low', 'trials_low', 'wilson_low_lo', 'wilson_low_hi',
               'successes_nominal', 'trials_nominal', 'wilson_nominal_lo', 'wilson_nominal_hi',
               'successes_high', 'trials_high', 'wilson_high_lo', 'wilson_high_hi',
               'mcnemar_p_low', 'only_low', 'only_nominal_vs_low',
               'mcnemar_p_high', 'only_high', 'only_nominal_vs_high',
               'errors_low', 'errors_nominal', 'errors_high', 'moved_low', 'moved_high',
               'source']


def csv_rows(groups):
    """sensitivity.csv's rows: one per case, speed and constant."""
    out = []
    for group in groups:
        for row in group['rows']:
            line = {'case': group['case'], 'rpm': '%.0f' % group['rpm'],
                    'constant': row['key'], 'unit': row['unit'], 'low': _g(row['low']),
                    'nominal': _g(row['nominal']), 'high': _g(row['high']),
                    'swing': '%.6g' % row['swing'], 'source': row['source']}
            for end in ('low', 'nominal', 'high'):
                cell = row[end + '_cell']
                line.update({'successes_' + end: cell['successes'], 'trials_' + end:
                             cell['trials'], 'errors_' + end: cell['errors'],
                             'wilson_%s_lo' % end: '%.6g' % cell['wilson95'][0],
                             'wilson_%s_hi' % end: '%.6g' % cell['wilson95'][1]})
            for end in ENDS:
                test = row[end + '_test']
                line.update({'mcnemar_p_' + end: '%.6g' % test['mcnemar_p'],
                             'only_' + end: test['only_end'],
                             'only_nominal_vs_' + end: test['only_nominal'],
                             'moved_' + end: json.dumps(row[end + '_moved'], sort_keys=True)})
            out.append(line)
    return out


def _short(key):
    return key.split('.', 1)[1].split('/')[-1]


def _tornado_axis(ax, group):
    rows = group['rows']
    nominal = rate(rows[0]['nominal_cell']) if rows else None
    for i, row in enumerate(rows):
        y = len(rows) - 1 - i
        for end, colour, offset in (('low', 'tab:blue', 0.18), ('high', 'tab:orange', -0.18)):
            value = rate(row[end + '_cell'])
            if value is None or nominal is None:
                continue
            ax.barh(y + offset, 100 * (value - nominal), left=100 * nominal, height=0.34,
                    color=colour)
            ax.plot([100 * value], [y + offset], marker='|', color=colour, markersize=9,
                    markeredgewidth=2, zorder=3)
    if nominal is not None:
        ax.axvline(100 * nominal, color='black', linewidth=0.9, zorder=2)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(['%s [%s-%s%s]' % (_short(r['key']), _g(r['low']), _g(r['high']),
                                          ' ' + r['unit'] if r['unit'] else '')
                        for r in reversed(rows)], fontsize=7)
    ax.set_xlim(-2, 102)
    ax.set_xlabel('success [%]', fontsize=8)
    nominal_cell = rows[0]['nominal_cell'] if rows else {'successes': 0, 'trials': 0}
    ax.set_title('%s, %.0f rpm (nominal %d/%d)' % (group['case'], group['rpm'],
                                                    nominal_cell['successes'],
                                                    nominal_cell['trials']), fontsize=9)


def tornado(groups, path):
    """sensitivity.png: per case (columns) and speed (rows) a tornado plot, one bar from the
    nominal success rate to each end's, the constants with the largest swing on top."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    rpms = sorted({g['rpm'] for g in groups})
    cases = [c for c in CASES if any(g['case'] == c for g in groups)]
    count = max([len(g['rows']) for g in groups] + [1])
    fig, axes = plt.subplots(len(rpms), len(cases), squeeze=False,
                             figsize=(6.2 * len(cases), (0.32 * count + 1.4) * len(rpms)))
    for group in groups:
        _tornado_axis(axes[rpms.index(group['rpm'])][cases.index(group['case'])], group)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    fig.legend(handles=[Patch(color='tab:blue', label='low end'),
                        Patch(color='tab:orange', label='high end'),
                        Line2D([], [], color='black', linewidth=0.9, label='nominal bench')],
               loc='upper center', ncol=3, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / fig.get_size_inches()[1]))
    try:
        atomic_savefig(fig, path, dpi=100)
    finally:
        plt.close(fig)


def write_outputs(setup, benches, statuses, groups, found):
    """sensitivity.md, sensitivity.csv, sensitivity.json and sensitivity.png in the output
    folder, each through a temporary file; the conclusions' section as text."""
    out = setup['out']
    section = conclusions_markdown(found)
    text = '\n\n'.join([design_markdown(setup), '## Success per case and speed',
                        '![tornado plots](sensitivity.png)']
                       + [group_markdown(g) for g in groups]
                       + [section, benches_markdown(benches, statuses)]) + '\n'
    with atomic_write(os.path.join(out, 'sensitivity.md')) as handle:
        handle.write(text)
    with atomic_write(os.path.join(out, 'sensitivity.csv'), newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        writer.writerows(csv_rows(groups))
    design = {k: setup[k] for k in ('scenario_path', 'sweep_path', 'rpms', 'trials', 'seed',
                                    'seed_space', 'entries')}
    with atomic_write(os.path.join(out, 'sensitivity.json')) as handle:
        json.dump({'design': design, 'groups': groups, 'conclusions': found}, handle, indent=1,
                  sort_keys=True)
        handle.write('\n')
    tornado(groups, os.path.join(out, 'sensitivity.png'))
    return section


# --- the command line --------------------------------------------------------------------------

def parse_args(argv):
    """The command line."""
    parser = tools.argument_parser(prog='campaign_sensitivity', description=__doc__.split(
        '\n')[0])
    parser.add_argument('--scenario', default=DEFAULT_SCENARIO,
                        help='the nominal bench (default: config/scenario_paper.yaml)')
    parser.add_argument('--sweep', default=DEFAULT_SWEEP,
                        help='the constants and their ranges (default: config/sensitivity.yaml)')
    parser.add_argument('--rpm', help='comma-separated spindle speeds (default: the scenario\'s)')
    parser.add_argument('--trials', help='trials per case and speed (default: the scenario\'s)')
    parser.add_argument('--seed', type=int, help='base seed (default: the scenario\'s)')
    parser.add_argument('--seed-space', help='calibration | evaluation (default: the '
                        'scenario\'s, else evaluation)')
    parser.add_argument('--jobs', type=int, default=2,
                        help='campaigns run at once, one trial_engine process each (a trial '
                        'depends on its seed only: the results do not depend on it)')
    parser.add_argument('--out', default='sensitivity_out')
    parser.add_argument('--reuse-trials', default=None, metavar='ROOT',
                        help='each campaign takes the trials a finished campaign under ROOT ran '
                        'with the same build and engine options (campaign --reuse-trials): '
                        'the nominal bench\'s trials from the main campaign, for instance')
    parser.add_argument('--only', action='append', default=[], metavar='NAME',
                        help='sweep only this constant (its name with or without the kind; '
                        'repeatable)')
    return parser.parse_args(argv)


def campaign_argv(args):
    """The options every sub-campaign gets (the scenario and the folder apart), resolved by the
    campaign's own parser, and the design values a finished sub-campaign's meta must have."""
    if not 1 <= args.jobs <= 64:
        raise SweepError('--jobs must be in 1..64, got %d' % args.jobs)
    # No --case: the scenario's cases (all three unless it names fewer).
    argv = ['--engine', 'core', '--jobs', '1']
    for option in ('rpm', 'trials', 'seed', 'seed_space'):
        value = getattr(args, option)
        if value is not None:
            argv += ['--' + option.replace('_', '-'), str(value)]
    try:
        parsed, scenario, cases, rpms, trials, seed, _ = arguments.parse_args(
            argv + ['--scenario', args.scenario])
    except SystemExit as error:  # argparse's own refusal (e.g. --seed x), already printed
        raise SweepError('bad campaign option (exit %s)' % error.code)
    if scenario.get('faults') or scenario.get('protocol', 'recognition') != 'recognition':
        raise SweepError('--scenario %s: a fault campaign or the peak_forces protocol has no '
                         'success to compare' % args.scenario)
    argv = ['--engine', 'core', '--jobs', '1',
            '--rpm', ','.join('%r' % r for r in rpms),
            '--trials', ','.join(str(t) for t in trials) if isinstance(trials, list)
            else str(trials), '--seed', str(seed), '--seed-space', parsed.seed_space]
    if args.reuse_trials is not None:
        if not os.path.isdir(args.reuse_trials):
            raise SweepError('--reuse-trials %s is not a folder' % args.reuse_trials)
        argv += ['--reuse-trials', os.path.abspath(args.reuse_trials)]
    expected = {'cases': list(cases), 'rpms': rpms, 'trials': trials, 'seed': seed,
                'seed_space': parsed.seed_space, 'engine': 'core'}
    return argv, scenario, expected


def prepare(args):
    """Everything checked before any campaign runs: the campaign options, the scenario, the
    sweep file against the declarations; the benches to run."""
    argv, scenario, expected = campaign_argv(args)
    entries = select(load_sweep(args.sweep), args.only)
    resolve(entries, scenario, declared_defaults())
    out = os.path.abspath(args.out)
    nominal = nominal_scenario(scenario, entries)
    setup = {'scenario_path': args.scenario, 'sweep_path': args.sweep, 'out': out,
             'entries': entries, 'rpms': expected['rpms'], 'trials': expected['trials'],
             'seed': expected['seed'], 'seed_space': expected['seed_space'],
             'cases': expected['cases']}
    return setup, argv, expected, conditions(entries, nominal, out)


def main(argv=None):
    """`rosrun pedicle_drilling campaign_sensitivity`: exit 0, 1 when a campaign left trials
    unfinished (the report covers the others) or the identification failed, 2 for a refused
    sweep or scenario, 130 on Ctrl-C."""
    args = parse_args(argv)
    try:
        setup, campaign, expected, benches = prepare(args)
        os.makedirs(setup['out'], exist_ok=True)
        runs = sum(1 for c in benches if c['scenario'] is not None)
        sys.stdout.write('campaign_sensitivity: %d constant(s), %d campaign(s) (ends at the '
                         'nominal value, which use the nominal campaign: %d) into %s\n' % (
                             len(setup['entries']), runs, len(benches) - runs, setup['out']))
        sys.stdout.flush()
        statuses = run_all(benches, campaign, expected, args.scenario, sys.stdout, args.jobs,
                           setup['out'])
    except (SweepError, UsageError) as error:
        sys.stderr.write('campaign_sensitivity: %s\n' % error)
        return 2
    except IdentificationError as error:
        sys.stderr.write('campaign_sensitivity: %s\n' % error)
        return 1
    except (OSError, RuntimeError, ValueError, subprocess.CalledProcessError) as error:
        sys.stderr.write('campaign_sensitivity: cannot ask the built tools (make build?): %s\n'
                         % error)
        return 2
    except KeyboardInterrupt:
        sys.stderr.write('campaign_sensitivity: interrupted; the finished campaigns are kept '
                         '(run the same command again to resume)\n')
        return 130
    try:
        results = read_results(benches)
    except (OSError, ValueError) as error:
        sys.stderr.write('campaign_sensitivity: a campaign left no readable trials.csv: %s\n'
                         % error)
        return 1
    groups = sensitivity_table(setup['entries'], results, setup['cases'], setup['rpms'])
    found = conclusions(results, benches, setup['rpms'])
    section = write_outputs(setup, benches, statuses, groups, found)
    sys.stdout.write('\n' + section + '\nwritten: %s/sensitivity.md, sensitivity.csv, '
                     'sensitivity.json, sensitivity.png\n' % setup['out'])
    return 1 if any(statuses.values()) else 0


if __name__ == '__main__':
    sys.exit(main())
