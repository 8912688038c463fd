"""Where a core-engine campaign's time goes: `campaign --profile` has every
trial_engine worker time its trials by component (core::ComponentProfile) and merges the workers'
files into OUT/profile.json and the table OUT/profile.md. make bench prints its shares."""
import json
import os

from .atomic import atomic_write

# The simulation's components, then the pipeline's; 'bullet_world' is part of 'arm_step'.
COMPONENTS = [
    ('arm_step', "the arm's dynamics step (BulletArm::step)"),
    ('bullet_world', "  of which Bullet's world step (the articulated-body algorithm)"),
    ('arm_controllers', "the arm's controllers: trajectories, feed drive, set-points"),
    ('platform', 'the SPMS: inverse and forward kinematics, slider drives'),
    ('sensor', 'the F/T sensor chain and the tare'),
    ('drilling', 'the drilling force law and the elastic contact'),
    ('patient', 'the ventilator and the breath sensor'),
    ('monitor', 'the safety monitor'),
    ('recognizer', 'the drilling-state recognizer'),
]


def merge(paths):
    """Sums trial_engine --profile files: {'trials', 'sim_s', 'wall_s': {component: s}}."""
    total = {'trials': 0, 'sim_s': 0.0, 'wall_s': {}}
    for path in paths:
        with open(path) as handle:
            part = json.load(handle)
        total['trials'] += int(part['trials'])
        total['sim_s'] += float(part['sim_s'])
        for name, seconds in part['wall_s'].items():
            total['wall_s'][name] = total['wall_s'].get(name, 0.0) + float(seconds)
    return total


def rows(profile):
    """(component, description, wall s, share of the engine's steps, ms per simulated s), the
    rest of the pipeline (planner, compensator, transport, records) last."""
    wall = profile['wall_s']
    steps = wall.get('engine_step', 0.0)
    sim_s = profile['sim_s']

    def row(name, text, seconds):
        return (name, text, seconds, seconds / steps if steps > 0 else float('nan'),
                1e3 * seconds / sim_s if sim_s > 0 else float('nan'))
    out = [row(name, text, wall.get(name, 0.0)) for name, text in COMPONENTS]
    listed = sum(wall.get(name, 0.0) for name, _ in COMPONENTS if name != 'bullet_world')
    out.append(row('pipeline_rest', 'the rest of each step: planner, compensator, transport, '
                   'records', max(0.0, steps - listed)))
    out.append(row('engine_step', 'every engine step (the rows above but bullet_world, which is '
                   'part of arm_step)', steps))
    return out


def markdown(profile, campaign_wall_s=None, workers=None):
    """The profile as a Markdown table, with the campaign's time outside the engine's steps."""
    lines = ['# Where the trials\' time goes (campaign --profile)', '',
             '%d trials, %.1f s of simulated time; wall time of the core engine\'s steps by '
             'component, summed over the workers.' % (profile['trials'], profile['sim_s']), '',
             '| component | wall s | share of the steps | ms per simulated s |',
             '|---|---|---|---|']
    for name, text, seconds, share, per_sim in rows(profile):
        lines.append('| %s: %s | %.2f | %.1f %% | %.3f |' % (name, text, seconds, 100 * share,
                                                              per_sim))
    steps = profile['wall_s'].get('engine_step', 0.0)
    if campaign_wall_s is not None and workers:
        lines += ['', 'From the workers\' start to the written report: %.1f s of wall time with '
                  '%d worker(s), %.1f s of worker time; the engine\'s steps were %.1f s of it '
                  '(%.0f %%). The rest: process start, each trial\'s set-up and record, the '
                  'campaign\'s reading of the records, its analysis and the report.'
                  % (campaign_wall_s, workers, campaign_wall_s * workers, steps,
                     100 * steps / (campaign_wall_s * workers))]
    return '\n'.join(lines) + '\n'


def write(paths, out_dir, campaign_wall_s, workers):
    """Merges the workers' files into out_dir/profile.json and profile.md (atomically)."""
    profile = merge(paths)
    with atomic_write(os.path.join(out_dir, 'profile.json')) as handle:
        json.dump(profile, handle, indent=1)
    with atomic_write(os.path.join(out_dir, 'profile.md')) as handle:
        handle.write(markdown(profile, campaign_wall_s, workers))
    return profile
