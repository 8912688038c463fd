"""The command line of `rosrun pedicle_drilling campaign`: its options, checked against each
other and against the scenario (parse_args), and the recognizer's and compensator's classes and
parameters, checked by trial_engine before anything is written (prepare)."""
import math
import os
import subprocess
import types

from . import engine_core, resume, tools
from .design import CASES, SEED_SPACES, parse_shard
from .identification import check_identification
from .scenario import (DEFAULT_COMPENSATOR, DEFAULT_RECOGNIZER, DEFAULT_SCENARIO, ROS_DELAYS,
                       SCENARIO_KEYS, Scenario, UsageError, load_scenario)

ENGINES = ('core', 'ros')


def parser():
    """The campaign's argument parser."""
    out = tools.argument_parser(
        prog='campaign', description='Reproduce the paper\'s drilling experiments on the '
        'simulator: Table III, Fig. 15-18, with Wilson 95 %% intervals.')
    _design_options(out)
    _run_options(out)
    return out


def _design_options(parser):
    """The options that choose the trials and the classes that run them."""
    parser.add_argument('--case', default=None,
                        help='stationary | uncompensated | compensated | all, or a '
                        'comma-separated list (default: scenario)')
    parser.add_argument('--rpm', default=None, help='comma-separated spindle speeds')
    parser.add_argument('--trials', default=None,
                        help='trials per case and speed: N, or one count per --rpm (N1,N2,...)')
    parser.add_argument('--seed', type=int, default=None)
    parser.add_argument('--seed-space', default=None,
                        help='calibration | evaluation (default: the scenario\'s, else '
                        'evaluation): the disjoint seed space of the trials. Choose constants '
                        'on calibration seeds, publish numbers from evaluation seeds')
    parser.add_argument('--scenario', default=DEFAULT_SCENARIO)
    parser.add_argument('--recognizer', default=None,
                        help='drilling-state recognizer class (default: the scenario\'s, else '
                        'pedicle_drilling/PaperRecognizer; pedicle_drilling/'
                        'ForceDifferenceRecognizer is the literature baseline)')
    parser.add_argument('--compensator', default=None,
                        help='motion compensator class (default: the scenario\'s, else '
                        'pedicle_drilling/PaperCompensator; pedicle_drilling/'
                        'TrackedMarkerCompensator is the tracker-feedback baseline)')
    parser.add_argument('--recognizer-param', action='append', default=None, metavar='NAME=VALUE',
                        help='a parameter of the recognizer class (repeatable; replaces the '
                        'scenario\'s recognizer_params)')
    parser.add_argument('--compensator-param', action='append', default=None,
                        metavar='NAME=VALUE',
                        help='a parameter of the compensator class (repeatable; replaces the '
                        'scenario\'s compensator_params), e.g. extrapolate=true')
    parser.add_argument('--engine', default='core',
                        help='core (default): trial_engine, the ROS-free closed-loop engine, '
                        'deterministic; ros: the full nodelet pipeline on ROS masters')
    parser.add_argument('--jobs', type=int, default=2,
                        help='parallel workers (trial_engine processes or ROS masters)')
    parser.add_argument('--out', default='campaign_out')
    parser.add_argument('--shard', default=None, help='K/N: run the K-th of N slices')


def _run_options(parser):
    """The options of how the trials run and what is kept of them."""
    parser.add_argument('--bags', action='store_true', help='keep a rosbag per trial')
    parser.add_argument('--samples', action='store_true',
                        help='keep every force-sensor sample of each trial in OUT/samples/'
                        '<trial_id>.npy (core engine; the dataset of doc/dataset.md)')
    parser.add_argument('--base-port', type=int, default=11400)
    parser.add_argument('--real-time-factor', type=float, default=None,
                        help='sim seconds per wall second in each --engine ros worker; 0: as '
                        'fast as the lockstep lets it (the participants are waited for, so '
                        'the trial does not depend on it). Default 0, or 5 with --bags (a '
                        'recorder in another process must keep up)')
    parser.add_argument('--profile', action='store_true',
                        help='--engine core: where the trials\' wall time goes, by component '
                        '(OUT/profile.md and profile.json)')
    parser.add_argument('--identification', default=None, metavar='DIR',
                        help='use the Table II identification in DIR (written by table2.py '
                        '--out DIR, or a campaign\'s OUT/identification) instead of running it '
                        '(campaign_sensitivity identifies once for all its campaigns). The '
                        'identification takes no scenario setting, so it is the same for every '
                        'scenario; it must come from this build')
    parser.add_argument('--no-figures', action='store_true',
                        help='write trials.csv, summary.json and report.md without the figures '
                        '(campaign_sensitivity\'s campaigns: it reads their trials only)')
    parser.add_argument('--pin-workers', default='auto', choices=('auto', 'on', 'off'),
                        help='--engine ros: run each worker (its master, launch and nodelet '
                        'manager) on one CPU of this process\'s CPU set. auto (default): when '
                        'there are no more workers than CPUs; on: round robin; off: never. '
                        'The lockstep hands every synchronised step between the manager\'s '
                        'threads, and a hand-off to a thread on another CPU costs a '
                        'cross-CPU wake-up: pinned, the same trials take about a quarter less '
                        'wall time (doc/benchmarks.md)')
    parser.add_argument('--reuse-trials', default=None, metavar='ROOT',
                        help='--engine core: take the trials that a finished campaign in ROOT '
                        '(or one or two folders below it) ran with the same build, package '
                        'files and engine options, row and trace, instead of running them '
                        'again (a trial\'s record depends on these and its seed only; '
                        'doc/experiments.md, "Reusing trials"). make run gives its results '
                        'folder')
    parser.add_argument('--resume', action='store_true',
                        help='continue the campaign stopped in --out (Ctrl-C, a kill, a full '
                        'disk): keep the trials it finished, run the others; the same '
                        'trials.csv as an uninterrupted run. Refused, naming what differs, '
                        'when that campaign was started with other arguments, scenario or '
                        'build (OUT/%s). Without it, a campaign starts over in a folder of an '
                        'earlier one' % resume.ARGS_FILE)
    parser.add_argument('--lockstep-every-step', action='store_true',
                        help='--engine ros: the simulator waits for the participants at every '
                        'step (~lockstep_every_step), not only where one of them needs it; the '
                        'same trials, slower (make run compares the two)')


def _check_core_engine(args, scenario):
    """What the core engine does not support, refused by name before anything runs."""
    if scenario.identification != 'volunteers':
        raise UsageError('scenario key identification: %r is not supported by --engine core '
                         '(use --engine ros)' % scenario.identification)
    if args.bags:
        raise UsageError('--bags records the ROS pipeline: use it with --engine ros')
    if args.lockstep_every_step:
        raise UsageError('--lockstep-every-step is the ROS pipeline\'s: use it with '
                         '--engine ros')
    if args.resume and args.profile:
        raise UsageError('--resume keeps trials timed by an earlier run: not with --profile')
    if args.reuse_trials is not None and (args.samples or args.profile):
        raise UsageError('--reuse-trials takes trials without their samples or profile: '
                         'not with --samples or --profile')


def _check_ros_engine(args, scenario):
    """What the ROS pipeline does not run, refused by name before anything runs."""
    if args.reuse_trials is not None:
        raise UsageError('--reuse-trials takes core-engine trials: use it with --engine core')
    if args.samples:
        raise UsageError('--samples is written by --engine core only')
    if args.profile:
        raise UsageError('--profile times the core engine: use it with --engine core')
    if set(scenario.engine_delays) - set(ROS_DELAYS):
        raise UsageError('scenario key engine_delays: on --engine ros only %s (the Simulator\'s '
                         'transport under the lockstep); %s run by --engine core only' % (
                             ', '.join(sorted(ROS_DELAYS)), ', '.join(sorted(
                                 set(scenario.engine_delays) - set(ROS_DELAYS)))))
    if scenario.planner_params:
        raise UsageError('scenario key planner_params: run by --engine core only (the ROS '
                         'pipeline\'s CompensationPlanner reads its parameters at its start)')
    if scenario.protocol != 'recognition':
        raise UsageError('scenario key protocol: %r is run by --engine core only (the ROS '
                         'pipeline\'s recognizer always stops the drill)' % scenario.protocol)
    if scenario.faults or scenario.fault_params:
        raise UsageError('scenario keys faults/fault_params: faults are injected by --engine core '
                         'only (the ROS pipeline has one rostest per fault, doc/nodes.md)')
    if str(scenario.simulator_params.get('population/enabled', '')).lower() in ('true', '1'):
        raise UsageError('simulator_params population/enabled: the population bench is run by '
                         '--engine core only (each trial\'s model is identified from its own '
                         'patient\'s recording; the ROS pipeline identifies the volunteers)')


def _cases(args, scenario):
    if args.case is None:
        return list(scenario.cases)
    if args.case == 'all':
        return list(CASES)
    if all(c in CASES for c in args.case.split(',')):
        return [c for c in CASES if c in args.case.split(',')]  # canonical order
    raise UsageError('--case %r is not one of: %s, all (or a comma-separated list)'
                     % (args.case, ', '.join(CASES)))


def _rpms(args, scenario):
    if args.rpm is None:
        return [float(r) for r in scenario.rpms]
    try:
        rpms = [float(r) for r in args.rpm.split(',')]
    except ValueError:
        raise UsageError('--rpm %r is not a comma-separated list of numbers' % args.rpm)
    if any(not 1000.0 <= r <= 60000.0 for r in rpms):
        raise UsageError('--rpm values must be in [1000, 60000]')
    return rpms


def _trials(args, scenario, rpms):
    """One count for every speed, or a list of one count per speed."""
    if args.trials is not None:
        try:
            trials = [int(n) for n in args.trials.split(',')]
        except ValueError:
            raise UsageError('--trials %r is not a count or a comma-separated list of counts'
                             % args.trials)
    else:
        trials = scenario.trials
        trials = trials if isinstance(trials, list) else [trials]
    low, high = SCENARIO_KEYS['trials'].low, SCENARIO_KEYS['trials'].high
    if any(not low <= n <= high for n in trials):
        raise UsageError('--trials must be in %d..%d' % (low, high))
    if len(trials) == 1:
        return trials[0]
    if len(trials) != len(rpms):
        raise UsageError('--trials has %d counts for %d spindle speeds (give one count, or one '
                         'per speed)' % (len(trials), len(rpms)))
    return trials


def _seed(args, scenario):
    """The base seed; args.seed_space set to the seed space."""
    seed = args.seed if args.seed is not None else scenario.seed
    if not 0 <= seed <= SCENARIO_KEYS['seed'].high:
        raise UsageError('--seed %d is out of range [0, 2^62]' % seed)
    space = args.seed_space or scenario.seed_space
    if space not in SEED_SPACES:
        raise UsageError('--seed-space %r is not one of: %s' % (space, ', '.join(SEED_SPACES)))
    args.seed_space = space
    return seed


def _check_folders(args, scenario):
    """--identification and --reuse-trials: existing folders, made absolute."""
    if args.identification is not None:
        if scenario.identification != 'volunteers':
            raise UsageError('--identification gives the volunteers\' Table II models; the '
                             'scenario identifies online (identification: %s)'
                             % scenario.identification)
        args.identification = os.path.abspath(args.identification)
        missing = check_identification(args.identification)
        if missing:
            raise UsageError('--identification %s is not a Table II identification (table2.py '
                             '--out DIR): %s missing' % (args.identification, missing))
    if args.reuse_trials is not None:
        if not os.path.isdir(args.reuse_trials):
            raise UsageError('--reuse-trials %s is not a folder' % args.reuse_trials)
        args.reuse_trials = os.path.abspath(args.reuse_trials)


def parse_args(argv):
    """(args, scenario (load_scenario's mapping), cases, rpms, trials, seed, shard (None: the
    whole design)); raises UsageError naming the option or the scenario key."""
    args = parser().parse_args(argv)
    if args.real_time_factor is None:
        args.real_time_factor = 5.0 if args.bags else 0.0
    if not (math.isfinite(args.real_time_factor) and 0.0 <= args.real_time_factor <= 1000.0):
        raise UsageError('--real-time-factor must be in [0, 1000], got %g' % args.real_time_factor)
    if args.engine not in ENGINES:
        raise UsageError('--engine %r is not one of: %s' % (args.engine, ', '.join(ENGINES)))
    given = load_scenario(args.scenario)
    scenario = Scenario(given)
    if args.engine == 'core':
        _check_core_engine(args, scenario)
    else:
        _check_ros_engine(args, scenario)
    cases = _cases(args, scenario)
    rpms = _rpms(args, scenario)
    trials = _trials(args, scenario, rpms)
    if args.jobs < 1 or args.jobs > 64:
        raise UsageError('--jobs must be in 1..64')
    seed = _seed(args, scenario)
    _check_folders(args, scenario)
    shard_spec = None
    if args.shard:
        try:
            shard_spec = parse_shard(args.shard)
        except ValueError as error:
            raise UsageError(str(error))
    return args, given, cases, rpms, trials, seed, shard_spec


def class_params(given, from_scenario, option):
    """{name: value as text} of a class: the command line's NAME=VALUE items, else the scenario's
    mapping. Raises UsageError naming a malformed item."""
    if given:
        out = {}
        for item in given:
            name, sep, value = item.partition('=')
            if not sep or not name:
                raise UsageError('%s %r is not NAME=VALUE' % (option, item))
            out[name] = value
        return out
    out = {}
    for name, value in (from_scenario or {}).items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        if not isinstance(value, (str, int, float)):
            raise UsageError('scenario %s: %s must be a number, a bool or a string'
                             % (option.lstrip('-').replace('-', '_') + 's', name))
        out[str(name)] = str(value)
    return out


def check_with_trial_engine(args, scenario, recognizer, compensator, params):
    """Raises UsageError with trial_engine's message when it refuses a class or its parameters
    (both engines load them through the same loader), the simulator section (the Simulator's own
    declaration, on either engine: the ROS pipeline's Simulator reads the same names and ranges
    at every reset) or the planner parameters: before anything is written. `scenario`: a
    Scenario."""
    checks = []
    for kind, name, default in (('recognizer', recognizer, DEFAULT_RECOGNIZER),
                                ('compensator', compensator, DEFAULT_COMPENSATOR)):
        if name != default or params[kind]:
            checks.append((['--check-' + kind, name] +
                           ['%s=%s' % kv for kv in sorted(params[kind].items())],
                           '--%s %s does not load' % (kind, name)))
    if scenario.simulator or scenario.simulator_params:
        checks.append((['--check-simulator'] + engine_core.simulator_params(
            scenario.simulator, scenario.simulator_params),
            'the simulator section was refused'))
    if args.engine == 'core' and scenario.planner_params:
        checks.append((['--check-planner'] + engine_core.settings_list(scenario.planner_params),
                       'the planner_params were refused'))
    for options, otherwise in checks:
        check = subprocess.run(engine_core.tool('trial_engine') + options, capture_output=True,
                               text=True)
        if check.returncode != 0:
            raise UsageError((check.stderr.strip().splitlines() or [otherwise])[-1])


def prepare(argv):
    """The campaign's settings (parse_args', its classes and their parameters), checked before
    anything is written; raises UsageError. `scenario` is the file's mapping, `settings` the
    Scenario that reads it."""
    args, given, cases, rpms, trials, seed, shard_spec = parse_args(argv)
    scenario = Scenario(given)
    recognizer = args.recognizer or scenario.recognizer or DEFAULT_RECOGNIZER
    compensator = args.compensator or scenario.compensator or DEFAULT_COMPENSATOR
    params = {'recognizer': class_params(args.recognizer_param, scenario.recognizer_params,
                                         '--recognizer-param'),
              'compensator': class_params(args.compensator_param, scenario.compensator_params,
                                          '--compensator-param')}
    check_with_trial_engine(args, scenario, recognizer, compensator, params)
    return types.SimpleNamespace(args=args, scenario=given, settings=scenario, cases=cases,
                                 rpms=rpms, trials=trials, seed=seed, shard_spec=shard_spec,
                                 faults=scenario.faults, recognizer=recognizer,
                                 compensator=compensator, params=params)
