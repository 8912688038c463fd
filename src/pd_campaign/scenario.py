"""The campaign's scenario file (`--scenario`, doc/experiments.md "Scenario files"): its keys
declared once (SCENARIO_KEYS: type, range, default), read and validated once (load_scenario,
whose errors name the key), and read through Scenario, which gives each key its value or its
one default."""
import collections
import copy
import os

import yaml

from . import engine_core, tools
from .design import CASES, FAULTS, SEED_SPACES

# The package's config/ and urdf/: its source folder (devel space) or its share folder (install
# space), found through rospack.
PACKAGE_ROOT = tools.package_dir()
DEFAULT_SCENARIO = os.path.join(PACKAGE_ROOT, 'config', 'scenario_paper.yaml')
DEFAULT_MODEL = os.path.join(PACKAGE_ROOT, 'config', 'patient_default.yaml')
SIMULATOR_CONFIG = os.path.join(PACKAGE_ROOT, 'config', 'simulator.yaml')
SCENARIO_VERSION = 1
DEFAULT_RECOGNIZER = 'pedicle_drilling/PaperRecognizer'
DEFAULT_COMPENSATOR = 'pedicle_drilling/PaperCompensator'

# A scenario key: its type (or types), its range (None: no range) and the value a scenario
# without it has.
Key = collections.namedtuple('Key', ('kind', 'low', 'high', 'default'))

# Scenario keys. Documented in doc/experiments.md ("Scenario files").
SCENARIO_KEYS = {
    'cases': Key(list, None, None, list(CASES)),
    'rpms': Key(list, 1000.0, 60000.0, [12000, 16000, 20000]),
    'trials': Key((int, list), 1, 10000, 20),  # per case and speed: one count, or one per rpm
    'seed': Key(int, 0, 2 ** 62, 1),
    # calibration | evaluation (design.SEED_SPACES): the disjoint seed space the trials are
    # drawn from; constants are chosen on calibration seeds, numbers published on evaluation
    # seeds (doc/experiments.md, "Seed spaces").
    'seed_space': Key(str, None, None, 'evaluation'),
    'feed_rate_mm_s': Key(float, 0.05, 5.0, 0.5),
    'max_duration_s': Key(float, 5.0, 600.0, 60.0),
    'identification_window_s': Key(float, 5.0, 300.0, 30.0),
    'identification': Key(str, None, None, 'volunteers'),
    'model': Key(str, None, None, 'linear'),
    'bone_motion': Key(str, None, None, 'virtual_patient'),
    'compensation_profile': Key(str, None, None, 'paper'),
    # the plan's depth limit (default true: the bench's planning step makes a plan and the
    # planner enforces it); false: the paper's system as published, which had no plan (the
    # planner's depth_limit/require_plan false). Both engines.
    'depth_limit': Key(bool, None, None, True),
    # recognition (the recognizer stops the drill) or peak_forces (paper Sec. V-D: it observes,
    # the drill goes through the inner layer; F_out / F_in of Fig. 16). Core engine only.
    'protocol': Key(str, None, None, 'recognition'),
    'simulator': Key(dict, None, None, {}),
    # {name: value}: any of the Simulator's declared parameters (param_docs), e.g. the force
    # sensor's chain (force_sensor_rate_hz, force_antialias_cutoff_hz). Both engines (the ROS
    # pipeline's Simulator reads them at every reset).
    'simulator_params': Key(dict, None, None, {}),
    # {name: value}: any of the CompensationPlanner's declared trial-sequence parameters
    # (param_docs), e.g. stop_hold_s, outer_cortical_max_mm. Core engine only.
    'planner_params': Key(dict, None, None, {}),
    # {force_to_recognizer_s, stop_to_planner_s, command_to_arm_s}: the core engine's transport
    # delays (core::EngineDelays, [0, 1] s; defaults 0, 1 ms, 1 ms). Core engine only.
    'engine_delays': Key(dict, None, None, {}),
    'faults': Key(list, None, None, None),  # none: no fault injected
    'fault_params': Key(dict, None, None, {}),
    # a recognizer class (pluginlib name); --recognizer wins
    'recognizer': Key(str, None, None, DEFAULT_RECOGNIZER),
    # a compensator class (pluginlib name); --compensator wins
    'compensator': Key(str, None, None, DEFAULT_COMPENSATOR),
    'recognizer_params': Key(dict, None, None, {}),  # {name: value} for the recognizer class
    'compensator_params': Key(dict, None, None, {}),  # {name: value} for the compensator class
    'version': Key(int, 1, 1, SCENARIO_VERSION),  # optional (a file without it is version 1)
}
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
PROTOCOLS = ('recognition', 'peak_forces')
# compensation_profile: the planner's segment profile (its ~segment_profile): the paper's 125 ms
# rest-to-rest trapezoids, or the exact reference (beyond the paper).
COMPENSATION_PROFILES = {'paper': 'rest_to_rest', 'exact': 'exact'}
# bone_motion: what the SPMS plays in the moving cases.
BONE_MOTIONS = ('model', 'virtual_patient')
# The keys whose value is one of a few words: key -> (the words, how an error lists them).
CHOICES = {
    'identification': (('volunteers', 'online'), 'volunteers or online'),
    'bone_motion': (BONE_MOTIONS, 'one of ' + ', '.join(BONE_MOTIONS)),
    'compensation_profile': (tuple(COMPENSATION_PROFILES),
                             'one of ' + ', '.join(COMPENSATION_PROFILES)),
    'protocol': (PROTOCOLS, 'one of ' + ', '.join(PROTOCOLS)),
    'model': (('linear', 'hysteresis'), 'linear or hysteresis'),
    'seed_space': (SEED_SPACES, 'one of ' + ', '.join(SEED_SPACES)),
}


class UsageError(Exception):
    pass


class Scenario:
    """A validated scenario (load_scenario's mapping) read by key: `scenario.model` is the
    file's value, else the key's one default (SCENARIO_KEYS); `given` is the file's mapping."""

    def __init__(self, given):
        self.given = given

    def __getattr__(self, key):
        if key == 'given' or key not in SCENARIO_KEYS:
            raise AttributeError('no scenario key %r' % key)
        if key in self.given:
            return self.given[key]
        return copy.deepcopy(SCENARIO_KEYS[key].default)


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


def _read(path):
    """The scenario file's mapping, its version checked."""
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
    return data


def _check_type(path, key, value):
    """The value of a known key in its type (an int for a float key made a float)."""
    kind = SCENARIO_KEYS[key].kind
    if kind is float and isinstance(value, int):
        value = float(value)
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise UsageError('--scenario %s: %r must be a %s' % (
            path, key, ' or '.join(k.__name__ for k in (kind if isinstance(kind, tuple)
                                                       else (kind,)))))
    return value


def _check_trials(path, key, value):
    low, high = SCENARIO_KEYS[key].low, SCENARIO_KEYS[key].high
    for count in (value if isinstance(value, list) else [value]):
        if not isinstance(count, int) or isinstance(count, bool) or not low <= count <= high:
            raise UsageError('--scenario %s: trials %r must be integers in [%s, %s]'
                             % (path, count, low, high))


def _check_rpms(path, key, value):
    low, high = SCENARIO_KEYS[key].low, SCENARIO_KEYS[key].high
    for rpm in value:
        if not isinstance(rpm, (int, float)) or not low <= rpm <= high:
            raise UsageError('--scenario %s: rpm %r out of range [%s, %s]'
                             % (path, rpm, low, high))


def _check_faults(path, key, value):
    if not value:
        raise UsageError('--scenario %s: faults is empty' % path)
    for fault in value:
        if fault not in FAULTS:
            raise UsageError('--scenario %s: faults: unknown fault %r (known: %s)'
                             % (path, fault, ', '.join(FAULTS)))
    twice = sorted({f for f in value if value.count(f) > 1})
    if twice:
        raise UsageError('--scenario %s: faults: %s listed twice' % (path, ', '.join(twice)))


def _check_fault_params(path, key, value):
    for name, number in value.items():
        if name not in FAULT_PARAMS:
            raise UsageError('--scenario %s: unknown key fault_params.%s (known: %s)'
                             % (path, name, ', '.join(sorted(FAULT_PARAMS))))
        if isinstance(number, bool) or not isinstance(number, (int, float)):
            raise UsageError('--scenario %s: fault_params.%s must be a number' % (path, name))


def _check_planner_params(path, key, value):
    for name in value:
        if name in PLANNER_PARAMS_SET_ELSEWHERE:
            raise UsageError('--scenario %s: planner_params.%s is set by the scenario key %s'
                             % (path, name, PLANNER_PARAMS_SET_ELSEWHERE[name]))


def _check_engine_delays(path, key, value):
    for name, number in value.items():
        if name not in engine_core.DELAY_OPTIONS:
            raise UsageError('--scenario %s: unknown key engine_delays.%s (known: %s)'
                             % (path, name, ', '.join(sorted(engine_core.DELAY_OPTIONS))))
        if (isinstance(number, bool) or not isinstance(number, (int, float))
                or not 0.0 <= number <= 1.0):
            raise UsageError('--scenario %s: engine_delays.%s must be a number of seconds in '
                             '[0, 1]' % (path, name))


def _check_cases(path, key, value):
    for case in value:
        if case not in CASES:
            raise UsageError('--scenario %s: unknown case %r' % (path, case))


# The checks of a key's value beyond its type and range: check(path, key, value).
VALUE_CHECKS = {
    'rpms': _check_rpms,
    'simulator': lambda path, key, value: check_simulator_section(path, value),
    'faults': _check_faults,
    'fault_params': _check_fault_params,
    'planner_params': _check_planner_params,
    'engine_delays': _check_engine_delays,
    'cases': _check_cases,
}


def check_value(path, key, value):
    """Raises UsageError naming `key` when its value is not one it may have."""
    if key == 'trials':
        _check_trials(path, key, value)
        return
    kind, low, high, _ = SCENARIO_KEYS[key]
    if kind in (int, float) and not low <= value <= high:
        raise UsageError('--scenario %s: %r = %s out of range [%s, %s]'
                         % (path, key, value, low, high))
    if key in VALUE_CHECKS:
        VALUE_CHECKS[key](path, key, value)
    if key in CHOICES and value not in CHOICES[key][0]:
        raise UsageError('--scenario %s: %s %r is not %s' % (path, key, value, CHOICES[key][1]))


def load_scenario(path):
    """Reads and validates a scenario YAML: the file's mapping (the keys it gives, each in its
    type); errors name the key. Scenario(mapping) reads it with the defaults."""
    data = _read(path)
    for key, value in data.items():
        if key not in SCENARIO_KEYS:
            raise UsageError('--scenario %s: unknown key %r (known: %s)'
                             % (path, key, ', '.join(sorted(SCENARIO_KEYS))))
        value = _check_type(path, key, value)
        data[key] = value
        check_value(path, key, value)
    return data
