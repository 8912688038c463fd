"""`rosrun pedicle_drilling campaign` and `rosrun pedicle_drilling campaign_merge`."""
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import types

import yaml

from . import engine_core, profile, report, resume, reuse, tools
from .atomic import atomic_path, atomic_write, remove_temporaries
from .design import CASES, FAULTS, SEED_SPACES, build_design, parse_shard, shard

# The package's config/ and urdf/: its source folder (devel space) or its share folder (install
# space), found through rospack.
PACKAGE_ROOT = tools.package_dir()
DEFAULT_SCENARIO = os.path.join(PACKAGE_ROOT, 'config', 'scenario_paper.yaml')
DEFAULT_MODEL = os.path.join(PACKAGE_ROOT, 'config', 'patient_default.yaml')
# Table II files a campaign copies from its identification; shards share them.
TABLE2_FILES = ('table2.md', 'table2.csv')
TABLE2_VOLUNTEERS = (1, 2, 3, 4, 5)  # table2.py's IDS: the five virtual volunteers' models
SIMULATOR_CONFIG = os.path.join(PACKAGE_ROOT, 'config', 'simulator.yaml')

# Scenario keys: name -> (type, min, max). Documented in doc/experiments.md ("Scenario files").
SCENARIO_KEYS = {
    'cases': (list, None, None),
    'rpms': (list, 1000.0, 60000.0),
    'trials': ((int, list), 1, 10000),  # per case and speed: one count, or one per rpm
    'seed': (int, 0, 2 ** 62),
    # calibration | evaluation (design.SEED_SPACES): the disjoint seed space the trials are
    # drawn from; constants are chosen on calibration seeds, numbers published on evaluation
    # seeds (doc/experiments.md, "Seed spaces"). Default evaluation.
    'seed_space': (str, None, None),
    'feed_rate_mm_s': (float, 0.05, 5.0),
    'max_duration_s': (float, 5.0, 600.0),
    'identification_window_s': (float, 5.0, 300.0),
    'identification': (str, None, None),
    'model': (str, None, None),
    'bone_motion': (str, None, None),
    'compensation_profile': (str, None, None),
    # the plan's depth limit (default true: the bench's planning step makes a plan and the
    # planner enforces it); false: the paper's system as published, which had no plan (the
    # planner's depth_limit/require_plan false). Both engines.
    'depth_limit': (bool, None, None),
    # recognition (the recognizer stops the drill) or peak_forces (paper Sec. V-D: it observes,
    # the drill goes through the inner layer; F_out / F_in of Fig. 16). Core engine only.
    'protocol': (str, None, None),
    'simulator': (dict, None, None),
    # {name: value}: any of the Simulator's declared parameters (param_docs), e.g. the force
    # sensor's chain (force_sensor_rate_hz, force_antialias_cutoff_hz). Both engines (the ROS
    # pipeline's Simulator reads them at every reset).
    'simulator_params': (dict, None, None),
    # {name: value}: any of the CompensationPlanner's declared trial-sequence parameters
    # (param_docs), e.g. stop_hold_s, outer_cortical_max_mm. Core engine only.
    'planner_params': (dict, None, None),
    # {force_to_recognizer_s, stop_to_planner_s, command_to_arm_s}: the core engine's transport
    # delays (core::EngineDelays, [0, 1] s; defaults 0, 1 ms, 1 ms). Core engine only.
    'engine_delays': (dict, None, None),
    'faults': (list, None, None),
    'fault_params': (dict, None, None),
    'recognizer': (str, None, None),  # a recognizer class (pluginlib name); --recognizer wins
    'compensator': (str, None, None),  # a compensator class (pluginlib name); --compensator wins
    'recognizer_params': (dict, None, None),  # {name: value} for the recognizer class
    'compensator_params': (dict, None, None),  # {name: value} for the compensator class
    'version': (int, 1, 1),  # SCENARIO_VERSION; optional (a file without it is version 1)
}
SCENARIO_VERSION = 1
DEFAULT_RECOGNIZER = 'pedicle_drilling/PaperRecognizer'
DEFAULT_COMPENSATOR = 'pedicle_drilling/PaperCompensator'
# scenario key engine_delays on --engine ros: the Simulator's transport under the lockstep.
ROS_DELAYS = {'command_to_arm_s': 'command_delay_s', 'command_jitter_s': 'command_jitter_s',
              'tracker_to_pipeline_s': 'tracker_delay_s'}
# planner_params that other scenario keys set for every trial (refused, naming the key).
PLANNER_PARAMS_SET_ELSEWHERE = {'feed_rate_mm_s': 'feed_rate_mm_s', 'spindle_rpm': 'rpms',
                                'max_duration_s': 'max_duration_s',
                                'segment_profile': 'compensation_profile',
                                'depth_limit/require_plan': 'depth_limit',
                                'feed_joint': '(the workcell URDF)'}
# fault_params: the sizes of the injected faults (core::FaultParams) -> trial_engine option.
FAULT_PARAMS = {
    'spike_n': '--fault-spike-n',
    'drift_n_per_s': '--fault-drift-n-per-s',
    'tracker_jump_m': '--fault-tracker-jump-m',
    'amplitude_factor': '--fault-amplitude-factor',
    'rate_change_bpm': '--fault-rate-change-bpm',
    'command_delay_s': '--fault-command-delay-s',
    'command_fault_count': '--fault-command-count',
    'saturation_n': '--fault-saturation-n',
    'saturation_noise_sd_n': '--fault-saturation-noise-sd-n',
    'nan_axis': '--fault-nan-axis',
    'occlusion_samples': '--fault-occlusion-samples',
    'occlusion_period_samples': '--fault-occlusion-period-samples',
}
INTEGER_FAULT_PARAMS = ('command_fault_count', 'nan_axis', 'occlusion_samples',
                        'occlusion_period_samples')
ENGINES = ('core', 'ros')
PROTOCOLS = ('recognition', 'peak_forces')
# compensation_profile: the planner's segment profile (its ~segment_profile): the paper's 125 ms
# rest-to-rest trapezoids, or the exact reference (beyond the paper).
COMPENSATION_PROFILES = {'paper': 'rest_to_rest', 'exact': 'exact'}
# bone_motion: what the SPMS plays in the moving cases.
BONE_MOTIONS = ('model', 'virtual_patient')
# Options that change a campaign's outputs besides its design and scenario: --resume refuses a
# folder whose campaign had others (resume.check). The others may differ: --jobs, --base-port,
# --pin-workers and --reuse-trials change no trial; --identification is the folder's own once
# it is complete, and the Table II models are compared by content (the engine key); --profile is
# refused with --resume.
RESUME_OPTIONS = ('bags', 'samples', 'real_time_factor', 'lockstep_every_step', 'no_figures')


class UsageError(Exception):
    pass


def simulator_keys():
    """The simulator's trial-distribution keys, {group: set of keys}, as config/simulator.yaml
    documents them (the simulator itself checks the ranges at every reset)."""
    with open(SIMULATOR_CONFIG) as handle:
        section = yaml.safe_load(handle)['trial_distribution']
    return {group: set(values) for group, values in section.items()}


def check_simulator_section(path, section):
    """The scenario's `simulator:` section: {group: {key: number}} with the keys of
    config/simulator.yaml's trial_distribution; errors name the key."""
    known = simulator_keys()
    for group, values in section.items():
        if group not in known:
            raise UsageError('--scenario %s: unknown key simulator.%s (known: %s)'
                             % (path, group, ', '.join(sorted(known))))
        if not isinstance(values, dict):
            raise UsageError('--scenario %s: simulator.%s must be a mapping' % (path, group))
        for key, value in values.items():
            if key not in known[group]:
                raise UsageError('--scenario %s: unknown key simulator.%s.%s (known: %s)'
                                 % (path, group, key, ', '.join(sorted(known[group]))))
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise UsageError('--scenario %s: simulator.%s.%s must be a number'
                                 % (path, group, key))
            values[key] = float(value)


def load_scenario(path):
    """Reads and validates a scenario YAML; errors name the key."""
    try:
        with open(path) as handle:
            data = yaml.safe_load(handle) or {}
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as error:
        # One line: YAML's message spans several (the problem, then its place).
        raise UsageError('--scenario %s: cannot read: %s' % (path, ' '.join(str(error).split())))
    if not isinstance(data, dict):
        raise UsageError('--scenario %s: not a mapping' % path)
    if not data:
        raise UsageError('--scenario %s: holds no setting (empty, only comments, or cut short?)'
                         % path)
    if 'version' in data and (data['version'] != SCENARIO_VERSION
                              or isinstance(data['version'], bool)):
        raise UsageError('--scenario %s: version %r is not supported (this campaign reads '
                         'version %d)' % (path, data['version'], SCENARIO_VERSION))
    for key, value in data.items():
        if key not in SCENARIO_KEYS:
            raise UsageError('--scenario %s: unknown key %r (known: %s)'
                             % (path, key, ', '.join(sorted(SCENARIO_KEYS))))
        kind, low, high = SCENARIO_KEYS[key]
        if kind is float and isinstance(value, int):
            value = float(value)
            data[key] = value
        if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
            raise UsageError('--scenario %s: %r must be a %s' % (
                path, key, ' or '.join(k.__name__ for k in (kind if isinstance(kind, tuple)
                                                           else (kind,)))))
        if key == 'trials':
            for count in (value if isinstance(value, list) else [value]):
                if not isinstance(count, int) or isinstance(count, bool) \
                        or not low <= count <= high:
                    raise UsageError('--scenario %s: trials %r must be integers in [%s, %s]'
                                     % (path, count, low, high))
            continue
        if kind in (int, float) and not low <= value <= high:
            raise UsageError('--scenario %s: %r = %s out of range [%s, %s]'
                             % (path, key, value, low, high))
        if key == 'rpms':
            for rpm in value:
                if not isinstance(rpm, (int, float)) or not low <= rpm <= high:
                    raise UsageError('--scenario %s: rpm %r out of range [%s, %s]'
                                     % (path, rpm, low, high))
        if key == 'simulator':
            check_simulator_section(path, value)
        if key == 'identification' and value not in ('volunteers', 'online'):
            raise UsageError('--scenario %s: identification %r is not volunteers or online'
                             % (path, value))
        if key == 'bone_motion' and value not in BONE_MOTIONS:
            raise UsageError('--scenario %s: bone_motion %r is not one of %s'
                             % (path, value, ', '.join(BONE_MOTIONS)))
        if key == 'compensation_profile' and value not in COMPENSATION_PROFILES:
            raise UsageError('--scenario %s: compensation_profile %r is not one of %s'
                             % (path, value, ', '.join(COMPENSATION_PROFILES)))
        if key == 'protocol' and value not in PROTOCOLS:
            raise UsageError('--scenario %s: protocol %r is not one of %s'
                             % (path, value, ', '.join(PROTOCOLS)))
        if key == 'model' and value not in ('linear', 'hysteresis'):
            raise UsageError('--scenario %s: model %r is not linear or hysteresis' % (path, value))
        if key == 'seed_space' and value not in SEED_SPACES:
            raise UsageError('--scenario %s: seed_space %r is not one of %s'
                             % (path, value, ', '.join(SEED_SPACES)))
        if key == 'faults':
            if not value:
                raise UsageError('--scenario %s: faults is empty' % path)
            for fault in value:
                if fault not in FAULTS:
                    raise UsageError('--scenario %s: faults: unknown fault %r (known: %s)'
                                     % (path, fault, ', '.join(FAULTS)))
            twice = sorted({f for f in value if value.count(f) > 1})
            if twice:
                raise UsageError('--scenario %s: faults: %s listed twice'
                                 % (path, ', '.join(twice)))
        if key == 'fault_params':
            for name, number in value.items():
                if name not in FAULT_PARAMS:
                    raise UsageError('--scenario %s: unknown key fault_params.%s (known: %s)'
                                     % (path, name, ', '.join(sorted(FAULT_PARAMS))))
                if isinstance(number, bool) or not isinstance(number, (int, float)):
                    raise UsageError('--scenario %s: fault_params.%s must be a number'
                                     % (path, name))
        if key == 'planner_params':
            for name in value:
                if name in PLANNER_PARAMS_SET_ELSEWHERE:
                    raise UsageError('--scenario %s: planner_params.%s is set by the scenario '
                                     'key %s' % (path, name, PLANNER_PARAMS_SET_ELSEWHERE[name]))
        if key == 'engine_delays':
            for name, number in value.items():
                if name not in engine_core.DELAY_OPTIONS:
                    raise UsageError('--scenario %s: unknown key engine_delays.%s (known: %s)'
                                     % (path, name, ', '.join(sorted(engine_core.DELAY_OPTIONS))))
                if (isinstance(number, bool) or not isinstance(number, (int, float))
                        or not 0.0 <= number <= 1.0):
                    raise UsageError('--scenario %s: engine_delays.%s must be a number of '
                                     'seconds in [0, 1]' % (path, name))
        if key == 'cases':
            for case in value:
                if case not in CASES:
                    raise UsageError('--scenario %s: unknown case %r' % (path, case))
    return data


def parse_args(argv):
    parser = tools.argument_parser(
        prog='campaign', description='Reproduce the paper\'s drilling experiments on the '
        'simulator: Table III, Fig. 15-18, with Wilson 95 %% intervals.')
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
    args = parser.parse_args(argv)
    if args.real_time_factor is None:
        args.real_time_factor = 5.0 if args.bags else 0.0
    if not (math.isfinite(args.real_time_factor) and 0.0 <= args.real_time_factor <= 1000.0):
        raise UsageError('--real-time-factor must be in [0, 1000], got %g' % args.real_time_factor)
    if args.engine not in ENGINES:
        raise UsageError('--engine %r is not one of: %s' % (args.engine, ', '.join(ENGINES)))
    scenario = load_scenario(args.scenario)
    if args.engine == 'core':
        # What the core engine does not support is refused by name, before anything runs.
        if scenario.get('identification', 'volunteers') != 'volunteers':
            raise UsageError('scenario key identification: %r is not supported by --engine core '
                             '(use --engine ros)' % scenario.get('identification'))
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
    elif args.reuse_trials is not None:
        raise UsageError('--reuse-trials takes core-engine trials: use it with --engine core')
    elif args.samples:
        raise UsageError('--samples is written by --engine core only')
    elif args.profile:
        raise UsageError('--profile times the core engine: use it with --engine core')
    elif set(scenario.get('engine_delays') or {}) - set(ROS_DELAYS):
        raise UsageError('scenario key engine_delays: on --engine ros only %s (the Simulator\'s '
                         'transport under the lockstep); %s run by --engine core only' % (
                             ', '.join(sorted(ROS_DELAYS)), ', '.join(sorted(
                                 set(scenario['engine_delays']) - set(ROS_DELAYS)))))
    elif scenario.get('planner_params'):
        raise UsageError('scenario key planner_params: run by --engine core only (the ROS '
                         'pipeline\'s CompensationPlanner reads its parameters at its start)')
    elif scenario.get('protocol', 'recognition') != 'recognition':
        raise UsageError('scenario key protocol: %r is run by --engine core only (the ROS '
                         'pipeline\'s recognizer always stops the drill)' % scenario['protocol'])
    elif scenario.get('faults') or scenario.get('fault_params'):
        raise UsageError('scenario keys faults/fault_params: faults are injected by --engine core '
                         'only (the ROS pipeline has one rostest per fault, doc/nodes.md)')
    elif str((scenario.get('simulator_params') or {}).get('population/enabled', '')).lower() in (
            'true', '1'):
        raise UsageError('simulator_params population/enabled: the population bench is run by '
                         '--engine core only (each trial\'s model is identified from its own '
                         'patient\'s recording; the ROS pipeline identifies the volunteers)')
    if args.case is None:
        cases = list(scenario.get('cases', CASES))
    elif args.case == 'all':
        cases = list(CASES)
    elif all(c in CASES for c in args.case.split(',')):
        cases = [c for c in CASES if c in args.case.split(',')]  # canonical order
    else:
        raise UsageError('--case %r is not one of: %s, all (or a comma-separated list)'
                         % (args.case, ', '.join(CASES)))
    if args.rpm is None:
        rpms = [float(r) for r in scenario.get('rpms', [12000, 16000, 20000])]
    else:
        try:
            rpms = [float(r) for r in args.rpm.split(',')]
        except ValueError:
            raise UsageError('--rpm %r is not a comma-separated list of numbers' % args.rpm)
        if any(not 1000.0 <= r <= 60000.0 for r in rpms):
            raise UsageError('--rpm values must be in [1000, 60000]')
    if args.trials is not None:
        try:
            trials = [int(n) for n in args.trials.split(',')]
        except ValueError:
            raise UsageError('--trials %r is not a count or a comma-separated list of counts'
                             % args.trials)
    else:
        trials = scenario.get('trials', 20)
        trials = trials if isinstance(trials, list) else [trials]
    low, high = SCENARIO_KEYS['trials'][1:]
    if any(not low <= n <= high for n in trials):
        raise UsageError('--trials must be in %d..%d' % (low, high))
    if len(trials) == 1:
        trials = trials[0]
    elif len(trials) != len(rpms):
        raise UsageError('--trials has %d counts for %d spindle speeds (give one count, or one '
                         'per speed)' % (len(trials), len(rpms)))
    if args.jobs < 1 or args.jobs > 64:
        raise UsageError('--jobs must be in 1..64')
    seed = args.seed if args.seed is not None else scenario.get('seed', 1)
    if not 0 <= seed <= SCENARIO_KEYS['seed'][2]:
        raise UsageError('--seed %d is out of range [0, 2^62]' % seed)
    space = args.seed_space or scenario.get('seed_space', 'evaluation')
    if space not in SEED_SPACES:
        raise UsageError('--seed-space %r is not one of: %s' % (space, ', '.join(SEED_SPACES)))
    args.seed_space = space
    if args.identification is not None:
        if scenario.get('identification', 'volunteers') != 'volunteers':
            raise UsageError('--identification gives the volunteers\' Table II models; the '
                             'scenario identifies online (identification: %s)'
                             % scenario.get('identification'))
        args.identification = os.path.abspath(args.identification)
        missing = check_identification(args.identification)
        if missing:
            raise UsageError('--identification %s is not a Table II identification (table2.py '
                             '--out DIR): %s missing' % (args.identification, missing))
    if args.reuse_trials is not None:
        if not os.path.isdir(args.reuse_trials):
            raise UsageError('--reuse-trials %s is not a folder' % args.reuse_trials)
        args.reuse_trials = os.path.abspath(args.reuse_trials)
    shard_spec = None
    if args.shard:
        try:
            shard_spec = parse_shard(args.shard)
        except ValueError as error:
            raise UsageError(str(error))
    return args, scenario, cases, rpms, trials, seed, shard_spec


def worker_cpus(jobs, mode, allowed):
    """The CPU each of `jobs` ROS workers is pinned to (None: not pinned), from the CPU set
    `allowed` (os.sched_getaffinity: a Slurm allocation's CPUs, not the machine's) and
    --pin-workers `mode`: auto pins one worker per CPU when there are no more workers than
    CPUs, on pins round robin, off never. A trial does not depend on it (the lockstep)."""
    cpus = sorted(allowed)
    if mode == 'off' or not cpus or (mode == 'auto' and jobs > len(cpus)):
        return [None] * jobs
    return [cpus[k % len(cpus)] for k in range(jobs)]


def identification_files():
    """The files of a Table II identification a campaign uses: TABLE2_FILES and each
    volunteer's linear and hysteresis model."""
    return list(TABLE2_FILES) + [os.path.join('models', 'volunteer_%d_%s.yaml' % (v, kind))
                                 for v in TABLE2_VOLUNTEERS for kind in ('linear', 'hysteresis')]


def check_identification(directory):
    """The first file a Table II identification directory lacks (None: complete)."""
    return next((name for name in identification_files()
                 if not os.path.isfile(os.path.join(directory, name))), None)


class Progress:
    """Progress with ETA on stderr: a bar redrawn in place on a terminal; on anything else (a
    file, a pipe, Slurm's log) whole lines, one per tenth of the trials or per 30 s, whichever
    comes first, and the last."""

    LINE_EVERY_S = 30.0

    def __init__(self, total, stream=None, interactive=None):
        self.total = total
        self.done = 0
        self.failed = 0
        self.start = time.time()
        self.stream = sys.stderr if stream is None else stream
        self.interactive = (self.stream.isatty() if interactive is None else interactive)
        self.last_line = self.start
        self.last_tenth = 0

    def update(self, row):
        self.done += 1
        if row.get('error'):
            self.failed += 1
        now = time.time()
        elapsed = now - self.start
        eta = elapsed / self.done * (self.total - self.done) if self.done else 0
        if self.interactive:
            width = 30
            filled = int(width * self.done / max(1, self.total))
            self.stream.write('\r[%s%s] %d/%d trials (%d errors)  elapsed %s  ETA %s   ' % (
                '#' * filled, '.' * (width - filled), self.done, self.total, self.failed,
                _clock(elapsed), _clock(eta)))
        else:
            tenth = 10 * self.done // max(1, self.total)
            if (tenth == self.last_tenth and self.done < self.total and
                    now - self.last_line < self.LINE_EVERY_S):
                return
            self.last_tenth = tenth
            self.last_line = now
            self.stream.write('campaign: %d/%d trials (%d errors), elapsed %s, ETA %s\n' % (
                self.done, self.total, self.failed, _clock(elapsed), _clock(eta)))
        self.stream.flush()


def _clock(seconds):
    seconds = int(seconds)
    return '%d:%02d' % (seconds // 60, seconds % 60)


def write_outputs(rows, meta, out_dir, notes='', figures=True):
    """trials.csv, summary.json, report.md and (`figures`) the figures from the finished
    rows."""
    report.write_trials_csv(rows, os.path.join(out_dir, 'trials.csv'))
    # Everything below from the rows as trials.csv keeps them (6 significant digits), so that a
    # merge of shards, which can only read trials.csv, gives the very same summary and report.
    rows = report.read_trials_csv(os.path.join(out_dir, 'trials.csv'))
    summary = report.summarise(rows)
    faults = report.fault_summary(rows)
    rows = [r for r in rows if r['fault'] == 'none']  # the paper's figures: fault-free trials
    report.write_summary_json(summary, meta, os.path.join(out_dir, 'summary.json'), faults)
    drawn = draw_figures(summary, rows, meta, out_dir) if figures else []
    table2 = os.path.join(out_dir, 'table2.md')
    if os.path.exists(table2):
        with open(table2) as handle:
            notes = notes + '\n\n## Table II (identification on the five virtual volunteers)\n\n' \
                + handle.read()
    report.write_report_md(summary, meta, drawn, os.path.join(out_dir, 'report.md'), notes,
                           faults, rows)
    return summary


def draw_figures(summary, rows, meta, out_dir):
    """The report's figures, [(title, file name)] (matplotlib imported only here: a campaign
    without figures does not load it)."""
    from . import plots
    figures = []
    # Under the peak_forces protocol no trial is a success: Table III, Fig. 15 and Fig. 18 (the
    # residual of the recognizer's stops) have nothing to show.
    recognition = meta.get('protocol', 'recognition') == 'recognition'
    for title, name in (
            ('Table III', plots.table3(summary, out_dir) if recognition else None),
            ('Fig. 15', plots.fig15(summary, out_dir) if recognition else None),
            ('Fig. 16', plots.fig16(rows, out_dir)),
            ('Fig. 17', plots.fig17(rows, out_dir, os.path.join(out_dir, 'traces'))),
            ('Fig. 18', plots.fig18(rows, out_dir) if recognition else None),
            ('Table II', plots.table2(os.path.join(out_dir, 'table2.csv'), out_dir))):
        if name:
            figures.append((title, name))
    return figures


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


def _check_with_trial_engine(args, scenario, recognizer, compensator, params):
    """Raises UsageError with trial_engine's message when it refuses a class or its parameters
    (both engines load them through the same loader), the simulator section (the Simulator's own
    declaration, on either engine: the ROS pipeline's Simulator reads the same names and ranges
    at every reset) or the planner parameters: before anything is written."""
    checks = []
    for kind, name, default in (('recognizer', recognizer, DEFAULT_RECOGNIZER),
                                ('compensator', compensator, DEFAULT_COMPENSATOR)):
        if name != default or params[kind]:
            checks.append((['--check-' + kind, name] +
                           ['%s=%s' % kv for kv in sorted(params[kind].items())],
                           '--%s %s does not load' % (kind, name)))
    if scenario.get('simulator') or scenario.get('simulator_params'):
        checks.append((['--check-simulator'] + engine_core.simulator_params(
            scenario.get('simulator'), scenario.get('simulator_params')),
            'the simulator section was refused'))
    if args.engine == 'core' and scenario.get('planner_params'):
        checks.append((['--check-planner'] + engine_core.settings_list(scenario['planner_params']),
                       'the planner_params were refused'))
    for options, otherwise in checks:
        check = subprocess.run(engine_core.tool('trial_engine') + options, capture_output=True,
                               text=True)
        if check.returncode != 0:
            raise UsageError((check.stderr.strip().splitlines() or [otherwise])[-1])


def _prepare(argv):
    """The campaign's settings (parse_args', its classes and their parameters), checked before
    anything is written; raises UsageError."""
    args, scenario, cases, rpms, trials, seed, shard_spec = parse_args(argv)
    recognizer = args.recognizer or scenario.get('recognizer') or DEFAULT_RECOGNIZER
    compensator = args.compensator or scenario.get('compensator') or DEFAULT_COMPENSATOR
    params = {'recognizer': class_params(args.recognizer_param,
                                         scenario.get('recognizer_params'), '--recognizer-param'),
              'compensator': class_params(args.compensator_param,
                                          scenario.get('compensator_params'),
                                          '--compensator-param')}
    _check_with_trial_engine(args, scenario, recognizer, compensator, params)
    return types.SimpleNamespace(args=args, scenario=scenario, cases=cases, rpms=rpms,
                                 trials=trials, seed=seed, shard_spec=shard_spec,
                                 faults=scenario.get('faults'), recognizer=recognizer,
                                 compensator=compensator, params=params)


def _meta(setup, design):
    """The report's meta data: the design only, so that merged shards report the same."""
    scenario = setup.scenario
    meta = {'cases': setup.cases, 'rpms': setup.rpms, 'trials': setup.trials, 'seed': setup.seed,
            'seed_space': setup.args.seed_space,
            'design_size': len(design), 'simulator': scenario.get('simulator') or {},
            'model': scenario.get('model', 'linear'),
            'bone_motion': scenario.get('bone_motion', 'virtual_patient'),
            'compensation_profile': scenario.get('compensation_profile', 'paper'),
            'depth_limit': scenario.get('depth_limit', True),
            'protocol': scenario.get('protocol', 'recognition'),
            'simulator_params': scenario.get('simulator_params') or {},
            'planner_params': scenario.get('planner_params') or {},
            'engine_delays': scenario.get('engine_delays') or {},
            'recognizer': setup.recognizer,
            'compensator': setup.compensator,
            'engine': setup.args.engine}
    for kind in ('recognizer', 'compensator'):
        if setup.params[kind]:
            meta[kind + '_params'] = setup.params[kind]
    if setup.faults:
        meta['faults'] = list(setup.faults)
        meta['fault_params'] = {k: float(v) for k, v in
                                sorted((scenario.get('fault_params') or {}).items())}
    return meta


def _identify(args, scenario, out_dir, own=False):
    """The folder of the Table II models the trials use ('' without: identification online);
    None when the identification failed (said on stderr). `own`: a resumed campaign keeps its
    folder's identification when it is complete (its trials used it)."""
    if scenario.get('identification', 'volunteers') != 'volunteers':
        return ''
    # Table II: identify the five virtual volunteers from their own 30 s recordings; the
    # simulator's patients are these volunteers, and the trials use these models.
    ident_dir = os.path.join(out_dir, 'identification')
    own = own and check_identification(ident_dir) is None
    if own:
        pass  # nothing written: a resume refused after this (another build) changed nothing
    elif args.identification:
        # Identified already (the same for every scenario: it reads no setting of it),
        # copied into OUT/identification/ (the campaign's output keeps the models it used).
        os.makedirs(os.path.join(ident_dir, 'models'), exist_ok=True)
        for name in identification_files():
            with atomic_path(os.path.join(ident_dir, name)) as tmp:
                shutil.copyfile(os.path.join(args.identification, name), tmp)
    else:
        sys.stderr.write('campaign: identifying the five virtual volunteers (Table II)\n')
        result = subprocess.run(tools.tool('table2.py') + [
            '--out', ident_dir, '--jobs', str(args.jobs), '--no-figure'],
            capture_output=True, text=True)
        if result.returncode != 0:
            sys.stderr.write('campaign: Table II identification failed:\n%s\n'
                             % (result.stderr or result.stdout))
            return None
    for name in TABLE2_FILES:
        if own and os.path.isfile(os.path.join(out_dir, name)):
            continue
        with atomic_path(os.path.join(out_dir, name)) as tmp:
            shutil.copyfile(os.path.join(ident_dir, name), tmp)
    return os.path.join(ident_dir, 'models')


def _core_command(setup, models_dir):
    """command(samples_dir=None, profile_path=None): the trial_engine command of the campaign's
    core-engine workers."""
    scenario, params = setup.scenario, setup.params
    pose = engine_core.drilling_pose(PACKAGE_ROOT)

    def command(samples_dir=None, profile_path=None):
        return engine_core.trial_engine_command(
            '-', pose, models_dir,
            scenario.get('model', 'linear'), scenario.get('bone_motion', 'virtual_patient'),
            float(scenario.get('feed_rate_mm_s', 0.5)),
            float(scenario.get('max_duration_s', 60.0)), DEFAULT_MODEL,
            COMPENSATION_PROFILES[scenario.get('compensation_profile', 'paper')],
            [(FAULT_PARAMS[k], int(v) if k in INTEGER_FAULT_PARAMS else float(v))
             for k, v in sorted((scenario.get('fault_params') or {}).items())],
            setup.recognizer, setup.compensator, params['recognizer'], params['compensator'],
            scenario.get('simulator'), scenario.get('protocol', 'recognition'),
            scenario.get('simulator_params'), planner_settings(scenario),
            scenario.get('engine_delays'), samples_dir, profile_path)
    return command


def planner_settings(scenario):
    """The core engine's planner settings: the scenario's planner_params, and
    depth_limit/require_plan false for a scenario without the depth limit (key depth_limit)."""
    settings = dict(scenario.get('planner_params') or {})
    if not scenario.get('depth_limit', True):
        settings['depth_limit/require_plan'] = False
    return settings


def _ros_worker(setup, out_dir, k, part, models_dir, cpu):
    """The k-th --engine ros worker, started on its trials `part`."""
    args, scenario, params = setup.args, setup.scenario, setup.params
    trial_file = os.path.join(out_dir, 'worker-%d-trials.json' % k)
    with atomic_write(trial_file) as handle:
        json.dump(part, handle)
    command = ['/usr/bin/python3', '-m', 'pd_campaign.worker',
               '--port', str(args.base_port + k + (os.getpid() % 50) * 64),
               '--trials', trial_file, '--out', out_dir,
               '--feed-rate', str(scenario.get('feed_rate_mm_s', 0.5)),
               '--max-duration', str(scenario.get('max_duration_s', 60.0)),
               '--identification-window-s',
               str(scenario.get('identification_window_s', 30.0)),
               '--default-model', DEFAULT_MODEL,
               '--real-time-factor', str(args.real_time_factor),
               '--models-dir', models_dir,
               '--model', scenario.get('model', 'linear'),
               '--bone-motion', scenario.get('bone_motion', 'virtual_patient'),
               '--segment-profile',
               COMPENSATION_PROFILES[scenario.get('compensation_profile', 'paper')],
               '--simulator-overrides', json.dumps(scenario.get('simulator') or {}),
               '--recognizer', setup.recognizer,
               '--compensator', setup.compensator,
               '--depth-limit', 'true' if scenario.get('depth_limit', True) else 'false']
    # The classes' parameters as the core engine takes them (NAME=VALUE text); the worker
    # puts them in the nodelets' parameter files (worker.plugin_config).
    for kind in ('recognizer', 'compensator'):
        for name, value in sorted(params[kind].items()):
            command += ['--%s-param' % kind, '%s=%s' % (name, value)]
    for name, value in sorted((scenario.get('engine_delays') or {}).items()):
        command += ['--simulator-param', '%s=%r' % (ROS_DELAYS[name], float(value))]
    for name, value in sorted((scenario.get('simulator_params') or {}).items()):
        command += ['--simulator-param', '%s=%s' % (name, json.dumps(value))]
    if args.lockstep_every_step:
        command += ['--simulator-param', 'lockstep_every_step=true']
    if args.bags:
        command.append('--bags')
    if cpu is not None:
        command += ['--cpu', str(cpu)]
    # The worker imports pd_campaign as this process did: catkin's devel space has it.
    return subprocess.Popen(command, stdout=subprocess.PIPE, text=True, start_new_session=True)


def _start_workers(setup, out_dir, slices, design, core_command, models_dir, profiles):
    """One worker per slice of the pending trials: a trial_engine process (its trials through
    stdin, the next to the process that finished one: engine_core.TrialFeed; a trial depends on
    its seed only, not on the process that runs it) or an --engine ros worker. The ones started
    are stopped when one cannot be."""
    args = setup.args
    samples_dir = os.path.join(out_dir, 'samples') if args.samples else None
    if samples_dir:
        os.makedirs(samples_dir, exist_ok=True)
    position = {trial['trial_id']: k for k, trial in enumerate(design)}
    cpus = worker_cpus(len(slices), args.pin_workers, os.sched_getaffinity(0))
    workers = []
    try:
        for k, part in enumerate(slices):
            if args.engine == 'core':
                workers.append(engine_core.start(core_command(samples_dir, profiles[k])))
                continue
            # Each trial's stamps from its place in the design, not from when its worker got to
            # it: the same trial on any run, job count or shard (worker.time_zero).
            part = [dict(trial, design_position=position[trial['trial_id']]) for trial in part]
            workers.append(_ros_worker(setup, out_dir, k, part, models_dir, cpus[k]))
    except BaseException:
        _stop(workers)
        raise
    return workers


def _stop(workers, number=signal.SIGTERM):
    for worker in workers:
        try:
            os.killpg(worker.pid, number)
        except ProcessLookupError:
            pass


class _Collector:
    """The campaign's finished rows: `first` (kept by --resume or taken by --reuse-trials, in
    design order) in the live trials.csv from its start, then each worker's trials as they
    arrive, appended to it. A reader that fails stops its worker (a trial_engine would otherwise
    wait for its next trial for ever; the campaign then ends with exit 1, naming it); an output
    that cannot be written (a trace, trials.csv: a full disk) stops every worker, the others'
    outputs would fail as well."""

    def __init__(self, total, first, out_dir, engine, feed):
        self.out_dir, self.engine, self.feed = out_dir, engine, feed
        self.lock = threading.Lock()
        self.appender = report.TrialsAppender(os.path.join(out_dir, 'trials.csv'), first)
        self.rows = list(first)
        self.progress = Progress(total)
        for row in first:
            self.progress.update(row)
        self.errors = []
        self.write_error = None
        self.workers = []

    def _collect(self, worker):
        try:
            if self.feed:
                self.feed.start(worker)
            for line in worker.stdout:
                line = line.strip()
                if not line.startswith('{'):
                    continue
                if self.feed:
                    self.feed.next(worker)  # before the analysis: the engine is not kept waiting
                raw = (engine_core.row_from_line(line, os.path.join(self.out_dir, 'traces'))
                       if self.engine == 'core' else json.loads(line))
                row = report.normalise_row({k: ('' if v is None else v) for k, v in raw.items()})
                with self.lock:
                    self.appender.append(row)
                    self.rows.append(row)
                    self.progress.update(row)
        except OSError as error:
            with self.lock:
                self.write_error = self.write_error or error
            _stop(self.workers)
        except Exception as error:
            with self.lock:
                self.errors.append('%s: %s' % (type(error).__name__, error))
            _stop([worker])
        finally:
            if self.feed:
                self.feed.close(worker)

    def run(self, workers):
        """Reads the workers' trials until they end; True when Ctrl-C stopped them."""
        self.workers = workers
        readers = [threading.Thread(target=self._collect, args=(w,), daemon=True)
                   for w in workers]
        for reader in readers:
            reader.start()
        interrupted = False
        try:
            for worker in workers:
                worker.wait()
        except KeyboardInterrupt:
            interrupted = True
            sys.stderr.write('\ncampaign: interrupted; stopping workers, keeping finished '
                             'trials\n')
            _stop(workers)
            for worker in workers:
                try:
                    worker.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    _stop([worker], signal.SIGKILL)
        for reader in readers:
            reader.join(timeout=5)
        return interrupted

    def close(self):
        """The finished rows."""
        with self.lock:
            self.appender.close()
            return list(self.rows)


def _first_rows(args, selected, kept, engine_key, core_command, out_dir):
    """The rows a campaign has before it runs a trial, in design order: the `kept` ones
    (--resume) and the ones it takes from finished campaigns (--reuse-trials; their traces
    copied into `out_dir`)."""
    taken = {}
    wanted = [trial for trial in selected if trial['trial_id'] not in kept]
    if args.reuse_trials and engine_key:
        unreadable = []
        taken = reuse.find(args.reuse_trials, engine_key, wanted, exclude=out_dir,
                           unreadable=unreadable)
        for why in unreadable:
            sys.stderr.write('campaign: --reuse-trials: left out, unreadable: %s\n' % why)
    elif args.reuse_trials:
        sys.stderr.write('campaign: --reuse-trials: every trial runs: %s\n' % reuse.unkeyable(
            core_command(), tools.build_id()))
    rows = []
    for trial in selected:
        trial_id = trial['trial_id']
        if trial_id in kept:
            rows.append(kept[trial_id])
        elif trial_id in taken:
            rows.append(reuse.take(trial_id, *taken[trial_id], out_dir))
    return rows, len(taken)


def _run_trials(setup, out_dir, design, selected, meta, core_command, models_dir, engine_key,
                kept):
    """Runs the trials the campaign does not have yet; writes the outputs; its exit status."""
    args = setup.args
    first, taken = _first_rows(args, selected, kept, engine_key, core_command, out_dir)
    have = {row['trial_id'] for row in first}
    pending = [trial for trial in selected if trial['trial_id'] not in have]
    jobs = min(args.jobs, len(pending))
    slices = [pending[i::jobs] for i in range(jobs)]
    sys.stderr.write('campaign: %d trials (%s), %s%s%d worker(s), output %s\n' % (
        len(selected), 'shard ' + args.shard if args.shard else 'full design',
        '%d kept from the stopped campaign (--resume), ' % len(kept) if args.resume else '',
        '%d taken from finished campaigns (--reuse-trials), ' % taken
        if args.reuse_trials else '', jobs, out_dir))
    profiles = [os.path.join(out_dir, 'profile-worker-%d.json' % k) if args.profile else None
                for k in range(len(slices))]
    started = time.monotonic()
    collector = _Collector(len(selected), first, out_dir, args.engine,
                           engine_core.TrialFeed(pending) if args.engine == 'core' else None)
    workers = _start_workers(setup, out_dir, slices, design, core_command, models_dir, profiles)
    interrupted = collector.run(workers)
    if any(worker.returncode == 2 for worker in workers):
        collector.close()
        sys.stderr.write('campaign: a worker refused the scenario (see its message above)\n')
        return 2
    finished = collector.close()
    if collector.write_error is not None:
        raise collector.write_error
    for error in collector.errors:
        sys.stderr.write('campaign: reading a worker\'s trials failed (its worker was stopped): '
                         '%s\n' % error)
    sys.stderr.write('\n')
    write_outputs(finished, meta, out_dir, figures=not args.no_figures)
    if args.profile and all(os.path.exists(p) for p in profiles):
        profile.write(profiles, out_dir, time.monotonic() - started, len(workers))
        for path in profiles:
            os.remove(path)
    sys.stderr.write('campaign: %d/%d trials finished; report %s\n'
                     % (len(finished), len(selected), os.path.join(out_dir, 'report.md')))
    if interrupted:
        return 130
    complete = len(finished) == len(selected) and not collector.errors
    if complete and engine_key:
        reuse.mark(out_dir, engine_key)  # its trials may now be taken (--reuse-trials)
    return 0 if complete else 1


def _run(setup, out_dir):
    """The campaign in `out_dir`, whose lock it holds; its exit status. Raises resume.Refused
    before it writes anything when --resume cannot continue the folder's campaign."""
    args = setup.args
    design = build_design(setup.cases, setup.rpms, setup.trials, setup.seed, setup.faults,
                          args.seed_space)
    selected = shard(design, *setup.shard_spec) if setup.shard_spec else design
    meta = _meta(setup, design)
    identity = {'design': {'meta': meta, 'shard': args.shard or '1/1'},
                'scenario': setup.scenario,
                'options': {name: getattr(args, name) for name in RESUME_OPTIONS}}
    resuming = args.resume and resume.check(out_dir, identity, ('design', 'scenario', 'options'))
    if args.resume and not resuming:
        sys.stderr.write('campaign: --resume: %s holds no record of a campaign (%s): nothing is '
                         'kept, every trial runs\n' % (out_dir, resume.ARGS_FILE))
    if not resuming:
        resume.forget(out_dir)  # no longer the campaign it described
        reuse.unmark(out_dir)  # not a source of trials until this campaign has finished
    models_dir = _identify(args, setup.scenario, out_dir, own=resuming)
    if models_dir is None:
        return 1
    core_command = _core_command(setup, models_dir) if args.engine == 'core' else None
    engine_key = reuse.engine_key(core_command(), PACKAGE_ROOT) if core_command else None
    identity['engine_key'] = engine_key
    kept = {}
    if resuming:  # checked to the last: the folder has not changed so far
        resume.check(out_dir, identity, ('engine_key',))
        reuse.unmark(out_dir)
        for name in ('', 'traces', 'samples'):  # a write the stop cut (SIGKILL) left them
            if os.path.isdir(os.path.join(out_dir, name)):
                remove_temporaries(os.path.join(out_dir, name))
        kept = resume.kept(out_dir, selected, args.samples)
    with atomic_write(os.path.join(out_dir, 'design.json')) as handle:
        json.dump({'meta': meta, 'scenario': os.path.abspath(args.scenario),
                   'shard': args.shard or '1/1', 'trials': selected}, handle, indent=1)
    resume.record(out_dir, identity)
    return _run_trials(setup, out_dir, design, selected, meta, core_command, models_dir,
                       engine_key, kept)


def _os_error_text(error):
    """'FILE: reason' of an OSError (its text when it names no file)."""
    if error.filename and error.strerror:
        return '%s: %s' % (error.filename, error.strerror)
    return str(error) or type(error).__name__


def run_campaign(argv=None):
    try:
        setup = _prepare(argv)
    except UsageError as error:
        sys.stderr.write('campaign: %s\n' % error)
        return 2
    out_dir = os.path.abspath(setup.args.out)
    try:
        os.makedirs(os.path.join(out_dir, 'traces'), exist_ok=True)
        with resume.FolderLock(out_dir):
            return _run(setup, out_dir)
    except resume.Refused as error:
        sys.stderr.write('campaign: %s\n' % error)
        return 2
    except OSError as error:
        # A full disk, a quota, an I/O error: one line naming the file. Every output is written
        # whole or not at all, so what was written before it stays (trials.csv keeps the
        # finished trials, line by line: --resume runs the others).
        sys.stderr.write('campaign: stopped: %s (the files written before it are kept; '
                         '--resume continues)\n' % _os_error_text(error))
        return 1


def run_merge(argv=None):
    parser = tools.argument_parser(
        prog='campaign_merge', description='Merge shard outputs of one campaign design into one '
        'report, identical to a single run with the same design.')
    parser.add_argument('dirs', nargs='+')
    parser.add_argument('--out', required=True)
    args = parser.parse_args(argv)
    rows = {}
    metas = []
    out_dir = os.path.abspath(args.out)
    os.makedirs(os.path.join(out_dir, 'traces'), exist_ok=True)
    reuse.unmark(out_dir)  # a merge is no source of trials (--reuse-trials)
    for directory in args.dirs:
        try:
            with open(os.path.join(directory, 'design.json')) as handle:
                metas.append(json.load(handle)['meta'])
            shard_rows = report.read_trials_csv(os.path.join(directory, 'trials.csv'))
        except (OSError, ValueError, KeyError) as error:
            sys.stderr.write('campaign_merge: %s: %s\n' % (directory, error))
            return 2
        for row in shard_rows:
            if row['trial_id'] in rows:
                sys.stderr.write('campaign_merge: trial %s appears twice\n' % row['trial_id'])
                return 2
            rows[row['trial_id']] = row
        # Table II (the volunteers' identification) is the same in every shard of a design.
        for name in TABLE2_FILES:
            source = os.path.join(directory, name)
            if os.path.exists(source) and not os.path.exists(os.path.join(out_dir, name)):
                with atomic_path(os.path.join(out_dir, name)) as tmp:
                    shutil.copyfile(source, tmp)
        traces = os.path.join(directory, 'traces')
        if os.path.isdir(traces):
            for name in os.listdir(traces):
                with open(os.path.join(traces, name)) as src, \
                        atomic_write(os.path.join(out_dir, 'traces', name)) as dst:
                    dst.write(src.read())
    keys = ('cases', 'rpms', 'trials', 'seed', 'seed_space', 'simulator', 'faults', 'fault_params')
    if any(tuple(m.get(k) for k in keys) != tuple(metas[0].get(k) for k in keys)
           for m in metas):
        sys.stderr.write('campaign_merge: the directories come from different designs\n')
        return 2
    meta = dict(metas[0])
    write_outputs(list(rows.values()), meta, out_dir)
    expected = meta.get('design_size')
    sys.stderr.write('campaign_merge: %d trials%s -> %s\n' % (
        len(rows), '' if expected is None else ' of %d' % expected, out_dir))
    if expected is not None and len(rows) != expected:
        sys.stderr.write('campaign_merge: %d trial(s) of the design are missing (a shard not '
                         'finished or not given); the report covers the others\n'
                         % (expected - len(rows)))
        return 1
    return 0
