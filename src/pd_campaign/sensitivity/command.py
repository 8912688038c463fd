"""`rosrun pedicle_drilling campaign_sensitivity`: its command line, the checks before any
campaign runs, and the sweep from the benches to the outputs."""
import os
import subprocess
import sys

from .. import arguments, tools
from ..identification import IdentificationError
from ..scenario import DEFAULT_SCENARIO, Scenario, UsageError
from .outputs import write_outputs
from .runner import read_results, run_all
from .sweep import (DEFAULT_SWEEP, SweepError, conditions, declared_defaults, load_sweep,
                    nominal_scenario, resolve, select)
from .verdicts import conclusions, sensitivity_table

# The first line of the package's documentation: campaign_sensitivity --help's description.
DESCRIPTION = 'Sensitivity of the campaign\'s conclusions to the bench\'s uncertain constants.'

# --- the command line --------------------------------------------------------------------------

def parse_args(argv):
    """The command line."""
    parser = tools.argument_parser(prog='campaign_sensitivity', description=DESCRIPTION)
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
    if Scenario(scenario).faults or Scenario(scenario).protocol != 'recognition':
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
