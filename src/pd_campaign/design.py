"""The campaign's design: which trials run, with which seeds, and how shards split them.

Every trial is identified by (case, rpm, index). Its seed depends on (seed space, base seed, rpm,
index) but NOT on the case, so that the three cases at one speed drill the same specimens with the
same virtual patients (a paired design: differences between cases are not specimen luck).

Seed spaces: every choice made by looking at simulated outcomes (a timeout, a rate, a
threshold) is made on `calibration` seeds; every published number comes from `evaluation` seeds.
The two spaces are disjoint by construction: bit 62 of a trial seed is 1 in the evaluation space
and 0 in the calibration space, whatever the base seed, so no base seed of one space can ever
draw a specimen of the other (SEED_SPACE_BIT, seed_space_of)."""
import hashlib

CASES = ('stationary', 'uncompensated', 'compensated')
# Faults the core engine injects (core::FaultKind, `trial_engine --list-faults`), in its order.
FAULTS = ('none', 'force_silent', 'force_nan', 'force_inf', 'force_spike', 'force_stuck',
          'force_drift', 'tracker_silent', 'tracker_jump', 'tracker_stale', 'breathing_amplitude',
          'breathing_rate_up', 'breathing_rate_down', 'command_lost', 'command_delayed',
          'force_saturated', 'force_axis_nan', 'force_neg_inf', 'tracker_occlusion', 'stop_lost',
          'planner_killed', 'monitor_killed', 'controller_aborted')


SEED_SPACES = ('calibration', 'evaluation')
# The bit that tells the spaces apart: set in every evaluation seed, clear in every calibration
# seed (trial seeds are 63-bit, so they stay below 2^63 and fit the engine's uint64 and ROS's).
SEED_SPACE_BIT = 1 << 62


def trial_seed(base_seed, rpm, index, space='evaluation'):
    """Stable 63-bit seed of the given seed space, independent of Python's hash randomisation."""
    if space not in SEED_SPACES:
        raise ValueError('seed space %r is not one of: %s' % (space, ', '.join(SEED_SPACES)))
    digest = hashlib.sha256(('%s/%d/%d/%d' % (space, base_seed, int(rpm), index)).encode()).digest()
    seed = int.from_bytes(digest[:8], 'big') >> 2  # 62 bits
    return seed | SEED_SPACE_BIT if space == 'evaluation' else seed


def seed_space_of(seed):
    """The seed space a trial seed belongs to."""
    return 'evaluation' if int(seed) & SEED_SPACE_BIT else 'calibration'


def build_design(cases, rpms, trials, base_seed, faults=None, space='evaluation'):
    """All trials in canonical order: by rpm, then index, then case, then fault. `trials` is the
    count per case and speed, or a list of one count per rpm (a trial's seed does not depend on
    it). With `faults` (a fault campaign), every case runs once per fault on the same seed, so
    that each fault is paired with the fault-free trial of the same specimen and patient.
    `space`: the seed space the seeds are drawn from (calibration or evaluation)."""
    counts = trials if isinstance(trials, list) else [trials] * len(rpms)
    if len(counts) != len(rpms):
        raise ValueError('%d trial counts for %d spindle speeds' % (len(counts), len(rpms)))
    design = []
    for rpm, count in zip(rpms, counts):
        for index in range(count):
            seed = trial_seed(base_seed, rpm, index, space)
            for case in cases:
                if not faults:
                    design.append({
                        'trial_id': '%s-%d-%03d' % (case, int(rpm), index),
                        'case': case,
                        'rpm': float(rpm),
                        'index': index,
                        'seed': seed,
                        'seed_space': space,
                    })
                    continue
                for fault in faults:
                    design.append({
                        'trial_id': '%s-%s-%d-%03d' % (case, fault, int(rpm), index),
                        'case': case,
                        'rpm': float(rpm),
                        'index': index,
                        'seed': seed,
                        'seed_space': space,
                        'fault': fault,
                    })
    return design


def shard(design, k, n):
    """The k-th (1-based) of n deterministic slices: every n-th trial of the canonical order."""
    if not (1 <= k <= n):
        raise ValueError('shard %d/%d: K must be in 1..N' % (k, n))
    return [trial for i, trial in enumerate(design) if i % n == k - 1]


def parse_shard(text):
    try:
        k_text, n_text = text.split('/')
        k, n = int(k_text), int(n_text)
    except ValueError:
        raise ValueError("--shard '%s' is not of the form K/N" % text)
    if n < 1 or not 1 <= k <= n:
        raise ValueError("--shard '%s': need 1 <= K <= N" % text)
    return k, n
