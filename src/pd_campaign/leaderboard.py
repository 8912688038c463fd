"""The recognizer leaderboard (doc/leaderboard.md).

    rosrun pedicle_drilling campaign_leaderboard --dataset DATASET_DIR --out DIR [--trials N]

1. **Tuning, offline, on the dataset** (pd_campaign.dataset): every entry of
   config/leaderboard.yaml with a `tune` grid is run over the training split's raw force traces
   by the `recognize` tool (the very recognizer object the closed loop runs, reset between
   trials), for every grid point; a stop whose sample is labelled inner cortical is correct. The
   best TOP_ON_TRAIN points on the training split are re-scored on the validation split and the
   best there is chosen (select()). The learned entry is fitted on the training split
   (pd_campaign.learned.train_learned). Nothing looks at the test split.
2. **Closed loop, on the test split's specimens**: each entry drills the same evaluation-seed
   trials (the dataset's base seed, evaluation space: the test split's specimens and patients,
   extended by further evaluation seeds when more trials are asked for) on both benches.
3. **The board**: per bench and case, each entry's correct stops (Wilson 95 %), no
   penetration, early stops, residual, overshoot, detection latency and McNemar's exact test
   paired with the reference entry, in DIR/leaderboard.md, .json and a figure; the same trials
   again with the plan's depth limit on, for the system's no-penetration column.
4. **Uncertainty and strata** (pd_campaign.board_stats): ranks bootstrapped over the specimens,
   strata and the hidden-condition board; every board stamped with the dataset's version and
   build and the board's own build. An entry submitted from outside: pd_campaign.submission.
"""

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import yaml

from . import (board_stats, campaign_process, compare, dataset_files, design, offline,
               stats, tools, trials_csv)
from .atomic import atomic_savefig, atomic_write
from .identification import IdentificationError, identify
from .learned import train_learned

PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DEFAULT_CONFIG = os.path.join(PACKAGE_ROOT, 'config', 'leaderboard.yaml')
TOP_ON_TRAIN = 3
class LeaderboardError(ValueError):
    """A bad configuration or dataset, named."""


def load_config(path):
    """The leaderboard's configuration, checked: entries with unique names and a recognizer."""
    try:
        with open(path) as handle:
            config = yaml.safe_load(handle)
    except (OSError, yaml.YAMLError) as e:
        raise LeaderboardError('%s: %s' % (path, e))
    if not isinstance(config, dict) or not isinstance(config.get('entries'), list):
        raise LeaderboardError('%s: no list "entries"' % path)
    names = set()
    for k, entry in enumerate(config['entries']):
        if not isinstance(entry, dict) or not entry.get('name') or not entry.get('recognizer'):
            raise LeaderboardError('%s: entries[%d] needs a name and a recognizer' % (path, k))
        if entry['name'] in names:
            raise LeaderboardError('%s: entry %r named twice' % (path, entry['name']))
        names.add(entry['name'])
        for key in ('params', 'tune'):
            if not isinstance(entry.get(key) or {}, dict):
                raise LeaderboardError('%s: entry %r: %s is not a map' % (path, entry['name'], key))
        if entry.get('train') not in (None, 'learned'):
            raise LeaderboardError('%s: entry %r: train: %r is not "learned"' % (
                path, entry['name'], entry.get('train')))
    if config.get('reference') not in names:
        raise LeaderboardError('%s: reference %r is not an entry' % (path, config.get('reference')))
    if not isinstance(config.get('benches'), dict) or not config['benches']:
        raise LeaderboardError('%s: no map "benches"' % path)
    return config


def outcome_of(stop_index, labels, residual_mm=None):
    """correct | shallow | early | late | none, from the stop's sample: its label, and the inner
    cortex left below the deepest cut then (`residual_mm`, per sample; None: not judged).
    Correct is the paper's success band: in the inner cortex with at most
    offline.MAX_RESIDUAL_MM of it left (offline.outcome_of judges the label); shallow: in
    it with more left (a failure in closed loop, as an early stop)."""
    if stop_index is not None and stop_index >= len(labels):
        raise LeaderboardError('stop index %d beyond the trace (%d samples)' % (
            stop_index, len(labels)))
    outcome = offline.outcome_of(None if stop_index is None else int(labels[stop_index]))
    if (outcome == 'correct' and residual_mm is not None
            and residual_mm[stop_index] > offline.MAX_RESIDUAL_MM):
        return 'shallow'
    return outcome


def offline_score(recognizer, settings, traces):
    """Runs `recognize` once over all traces with the settings (as --param: a value may hold a
    blank); {correct, early, late, none}."""
    return offline_scores(recognizer, [settings], traces, sets_file=False)[0]


def offline_scores(recognizer, settings_list, traces, sets_file=True):
    """offline_score() of each settings of `settings_list`, from one `recognize` process that
    reads the traces once and runs every settings' recognizer over them (--param-sets, whose
    items are separated by blanks; `sets_file` False: one settings, given as --param)."""
    lines = []
    for settings in settings_list:
        items = ['%s=%s' % (name, value) for name, value in sorted(settings.items())]
        if sets_file and any(len(item.split()) != 1 for item in items):
            raise LeaderboardError('recognize %s: a grid setting with a blank: %s' % (
                recognizer, items))
        lines.append(items)
    with tempfile.TemporaryDirectory(prefix='leaderboard-') as scratch:
        command = tools.tool('recognize') + ['--json', '--recognizer', recognizer]
        if sets_file:
            sets = os.path.join(scratch, 'param_sets.txt')
            with atomic_write(sets) as handle:
                handle.write(''.join(' '.join(items) + '\n' for items in lines))
            command += ['--param-sets', sets]
        else:
            assert len(lines) == 1
            command += [arg for item in lines[0] for arg in ('--param', item)]
        for trace in traces:
            command += ['--input', trace[0]]
        result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise LeaderboardError('recognize %s %s: %s' % (recognizer, settings_list,
                                                        result.stderr.strip()[-500:]))
    results = [json.loads(line) for line in result.stdout.splitlines() if line.startswith('{')]
    if len(results) != len(traces) * len(settings_list):
        raise LeaderboardError('recognize gave %d results for %d traces and %d settings' % (
            len(results), len(traces), len(settings_list)))
    scores = []
    for k in range(len(settings_list)):
        counts = {'correct': 0, 'shallow': 0, 'early': 0, 'late': 0, 'none': 0}
        mine = results[k * len(traces):(k + 1) * len(traces)]
        if sets_file and any(line.get('param_set') != k for line in mine):
            raise LeaderboardError('recognize gave the parameter sets out of order')
        for line, (_, labels, residual_mm) in zip(mine, traces):
            stop = line.get('stop')
            counts[outcome_of(stop['index'] if stop else None, labels, residual_mm)] += 1
        scores.append(counts)
    return scores


def scores_in_parallel(recognizer, settings_list, traces, pool, jobs):
    """offline_scores() of `settings_list` in `jobs` contiguous parts, one process each on
    `pool`; the scores in the list's order (a score depends on its settings only)."""
    size = -(-len(settings_list) // max(1, jobs))
    parts = [settings_list[i:i + size] for i in range(0, len(settings_list), size)]
    scores = []
    for part in pool.map(lambda part: offline_scores(recognizer, part, traces), parts):
        scores.extend(part)
    return scores


def _rank(counts):
    """Higher is better: correct stops (in the success band), then fewer late stops
    (breakthroughs), then fewer missing stops."""
    return (counts['correct'], -counts['late'], -counts['none'])


def select(points, train_scores, validation_scores):
    """The chosen grid point: among the TOP_ON_TRAIN best on the training split, the best on the
    validation split (ties: the better on train, then the earlier in the grid). `points` in grid
    order; `*_scores` aligned with it (validation_scores: None where not scored)."""
    order = sorted(range(len(points)), key=lambda i: (_rank(train_scores[i]), -i), reverse=True)
    top = order[:TOP_ON_TRAIN]
    best = max(top, key=lambda i: (_rank(validation_scores[i]), _rank(train_scores[i]), -i))
    return best, top


def grid_points(grid):
    names = sorted(grid)
    return [dict(zip(names, values)) for values in itertools.product(
        *[[str(v) for v in grid[n]] for n in names])]


def tune_entry(entry, train, validation, log=sys.stderr, jobs=1):
    """{params, train, validation, grid_size, top}: the entry's chosen settings and scores. The
    grid's points are scored in `jobs` parts at a time (one `recognize` process each, reading the
    traces once; a score depends on its point only, so the choice does not depend on `jobs`)."""
    import concurrent.futures
    fixed = {k: str(v) for k, v in (entry.get('params') or {}).items()}
    points = grid_points(entry.get('tune') or {}) or [{}]
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        train_scores = scores_in_parallel(
            entry['recognizer'], [dict(fixed, **point) for point in points], train, pool, jobs)
        for k, score in enumerate(train_scores):
            log.write('leaderboard: %s grid %d/%d on train: %s\n' % (
                entry['name'], k + 1, len(points), score))
        order = sorted(range(len(points)), key=lambda i: (_rank(train_scores[i]), -i),
                       reverse=True)
        validation_scores = [None] * len(points)
        top = order[:TOP_ON_TRAIN]
        for i, score in zip(top, scores_in_parallel(
                entry['recognizer'], [dict(fixed, **points[i]) for i in top], validation, pool,
                jobs)):
            validation_scores[i] = score
    best, top = select(points, train_scores, validation_scores)
    return {'params': dict(fixed, **points[best]), 'train': train_scores[best],
            'validation': validation_scores[best], 'grid_size': len(points),
            'top': [{'params': points[i], 'train': train_scores[i],
                     'validation': validation_scores[i]} for i in top]}


def train_entry(entry, dataset_dir, out_dir, train, validation):
    """The learned entry: fitted on train (its threshold chosen on validation), then scored."""
    model = os.path.join(out_dir, '%s_model.json' % entry['name'])
    train_learned(os.path.join(dataset_dir, 'train.npz'),
                  os.path.join(dataset_dir, 'validation.npz'), model)
    params = dict({k: str(v) for k, v in (entry.get('params') or {}).items()}, model=model)
    return {'params': params, 'train': offline_score(entry['recognizer'], params, train),
            'validation': offline_score(entry['recognizer'], params, validation),
            'grid_size': 0, 'top': []}


def run_campaign(entry, params, scenario, meta, args, out_dir, identification):
    """The entry's closed-loop campaign: trials.csv, summary.json and report.md, no figures
    (the leaderboard draws its own), on the leaderboard's one Table II identification; forked
    from a server that imported the campaign's modules once (campaign_process)."""
    argv = [
        '--scenario', scenario, '--seed', str(meta['base_seed']), '--seed-space', 'evaluation',
        '--case', ','.join(args.cases), '--rpm', ','.join(str(r) for r in args.rpms),
        '--trials', str(args.trials), '--jobs', str(args.jobs), '--out', out_dir,
        '--recognizer', entry['recognizer'], '--identification', identification, '--no-figures']
    for name, value in sorted(params.items()):
        argv += ['--recognizer-param', '%s=%s' % (name, value)]
    if campaign_process.run(argv) != 0:
        raise LeaderboardError('the campaign of %s on %s failed (%s)' % (
            entry['name'], scenario, out_dir))
    return trials_csv.read_trials_csv(os.path.join(out_dir, 'trials.csv'))


def scenario_with_depth_limit(scenario, out_dir):
    """A copy of the bench's scenario with the plan's depth limit on, written into out_dir."""
    with open(scenario) as handle:
        settings = yaml.safe_load(handle)
    settings['depth_limit'] = True
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, 'scenario_depth_limit.yaml')
    with atomic_write(path) as handle:
        yaml.safe_dump(settings, handle, sort_keys=False)
    return path


def limited_rows(rows_by_entry):
    """Per entry and (case, rpm), from the runs with the depth limit: trials, no penetration
    and the stops the limit made first."""
    out = {}
    for name, rows in rows_by_entry.items():
        for r in rows:
            if r.get('error'):
                continue
            cell = out.setdefault((name, r['case'], r['rpm']),
                                  {'n': 0, 'no_penetration': 0, 'limit_first': 0})
            cell['n'] += 1
            cell['no_penetration'] += 0 if r.get('breakthrough') else 1
            cell['limit_first'] += 1 if r.get('first_stop_kind') == 'safety_depth_limit' else 0
    return out


def _median(rows, key):
    return stats.median([r.get(key) for r in rows if not r.get('error')
                         and r.get(key) is not None])


def board_rows(rows_by_entry, reference, limited=None):
    """Per entry and (case, rpm): the field's metrics and the paired test with the reference;
    with `limited` (limited_rows), the same trials' no penetration with the depth limit."""
    limited = limited or {}
    out = []
    for name, rows in rows_by_entry.items():
        groups = compare.compare(rows, rows_by_entry[reference])
        for g in groups:
            in_group = [r for r in rows if r['case'] == g['case'] and r['rpm'] == g['rpm']
                        and not r.get('error')]
            kinds = g['failure_kinds_a']
            out.append({
                'entry': name, 'case': g['case'], 'rpm': g['rpm'], 'n': g['pairs'],
                'errors': g['errors_a'],
                'correct': g['successes_a'], 'wilson95': g['wilson95_a'],
                'no_penetration': g['no_penetration_a'],
                'early': sum(v for k, v in kinds.items() if k.startswith('stopped_')),
                'breakthrough': sum(v for k, v in kinds.items() if k.startswith('breakthrough')),
                'median_residual_mm': _median(in_group, 'residual_mm'),
                'median_overshoot_mm': _median(in_group, 'overshoot_mm'),
                'median_latency_ms': _median(in_group, 'detection_latency_ms'),
                'with_depth_limit': limited.get((name, g['case'], g['rpm'])),
                'vs_reference': None if name == reference else {
                    'only_entry': g['only_a'], 'only_reference': g['only_b'],
                    'mcnemar_p': g['mcnemar_p'], 'difference': g['difference'],
                    'difference_ci95': g['difference_ci95']},
            })
    return out


def _fmt(value, pattern='%.2f'):
    return '-' if value is None else pattern % value


def stamp(meta):
    """The board's stamp: the dataset's version and the build that made it (split.json's meta),
    and the build that made the board."""
    try:
        board_build = dataset_files.package_info()
    except (OSError, ValueError) as e:
        board_build = {'build_id': 'unknown (%s)' % e, 'build_digest': 'unknown'}
    return {'dataset_version': meta.get('dataset_version', 'unknown'),
            'dataset_build_id': meta.get('build_id', 'unknown'),
            'board_build_id': board_build['build_id'],
            'board_build_digest': board_build['build_digest']}


def extras(rows_by_entry, args, meta):
    """A bench's rank intervals, strata and hidden-condition board (pd_campaign.board_stats)."""
    hidden, reasons = board_stats.hidden_board(rows_by_entry, meta.get('hidden_conditions'))
    return {'ranks': board_stats.rank_table(rows_by_entry, args.cases),
            'strata': board_stats.strata_table(rows_by_entry, args.strata_edges),
            'hidden': hidden,
            'hidden_specimens': [{'rpm': k[0], 'seed': k[1], 'reason': v}
                                 for k, v in sorted(reasons.items())]}


def extras_markdown(bench, extra, args):
    reasons = {(s['rpm'], s['seed']): s['reason'] for s in extra['hidden_specimens']}
    return (['### Ranks on the %s bench, bootstrapped over specimens' % bench, '',
             'Each entry\'s rank by correct stops (1: the most; ties share the better rank) and '
             'its 95 %% percentile interval over %d resamples of the specimens (seed %d), the '
             'same resample for every entry and case.' % (board_stats.RESAMPLES,
                                                          board_stats.SEED), '']
            + board_stats.ranks_markdown(extra['ranks'], args.cases)
            + ['', '### Strata on the %s bench' % bench, '',
               'Correct stops per band, the cases pooled (Wilson 95 %); the bands\' edges are the '
               'tertiles of the training split\'s specimens (bone density: the outer cortex\'s '
               'true peak thrust over the dataset\'s reference at its speed).', '']
            + board_stats.strata_markdown(extra['strata'])
            + ['', '### Hidden-condition board on the %s bench' % bench, '',
               'The specimens whose breathing pattern or bone density the training and '
               'validation splits never held (the dataset\'s hidden conditions, doc/dataset.md), '
               'against the others.', '']
            + board_stats.hidden_markdown(extra['hidden'], reasons) + [''])


def markdown(boards, tuning, config, meta, args, marks=None):
    """leaderboard.md's text; `marks` the stamp (default: stamp(meta), this build's)."""
    marks = marks or stamp(meta)
    lines = ['# Recognizer leaderboard', '',
             'Dataset version `%s` (made by build `%s`); board made by build `%s` (digest `%s`).'
             % (marks['dataset_version'], marks['dataset_build_id'], marks['board_build_id'],
                marks['board_build_digest']), '',
             'Closed-loop trials on the test split\'s specimens (evaluation seeds of base seed %d, '
             '%d per case and speed), the same trials for every entry; every choice was made on '
             'the training and validation splits (offline, `recognize` over the dataset\'s raw '
             'force). Correct stop: the paper\'s success (stopped by the recognizer inside the '
             'inner cortex, 0 < residual <= 2 mm, no breakthrough). McNemar: exact, paired with '
             '`%s` on the same trials.' % (meta['base_seed'], args.trials, config['reference']),
             '']
    for bench, rows in boards.items():
        lines += ['## Bench: %s (`config/%s`)' % (bench, config['benches'][bench]), '',
                  '| entry | case | rpm | correct stops (95 %% CI) | no penetration | early | '
                  'breakthrough | residual mm | overshoot mm | latency ms | vs %s: only / only, '
                  'McNemar p | with the depth limit: no penetration (limit first) |'
                  % config['reference'],
                  '|---|---|---|---|---|---|---|---|---|---|---|---|']
        for r in rows:
            vs = r['vs_reference']
            limited = r.get('with_depth_limit')
            lines.append('| %s | %s | %d | %d/%d (%.0f-%.0f %%) | %d/%d | %d | %d | %s | %s | %s | '
                         '%s | %s |' % (
                             r['entry'], r['case'], r['rpm'], r['correct'], r['n'],
                             100 * r['wilson95'][0], 100 * r['wilson95'][1],
                             r['no_penetration'], r['n'], r['early'], r['breakthrough'],
                             _fmt(r['median_residual_mm']), _fmt(r['median_overshoot_mm']),
                             _fmt(r['median_latency_ms'], '%.0f'),
                             '-' if vs is None else '%d / %d, %.3g' % (
                                 vs['only_entry'], vs['only_reference'], vs['mcnemar_p']),
                             '-' if not limited else '%d/%d (%d)' % (
                                 limited['no_penetration'], limited['n'],
                                 limited['limit_first'])))
        lines.append('')
        if bench in args.extras:
            lines += extras_markdown(bench, args.extras[bench], args)
    lines += ['## Tuning (offline, training and validation splits)', '',
              'Offline stops per trial: correct (inner cortex, at most 2 mm of it left) / shallow '
              '(inner cortex, more left) / early / late (broken through) / none. The planner\'s '
              'plausibility bounds, off in the dataset\'s protocol, are not replayed offline: the '
              'closed loop has them.', '',
              '| entry | source | chosen parameters | grid | train | validation |',
              '|---|---|---|---|---|---|']
    for entry in config['entries']:
        t = tuning[entry['name']]

        def four(c):
            return '%d/%d/%d/%d/%d' % (c['correct'], c['shallow'], c['early'], c['late'],
                                       c['none'])
        params = ', '.join('%s=%s' % (k, (os.path.basename(v) if k == 'model' else v))
                           for k, v in sorted(t['params'].items())) or 'as published'
        lines.append('| %s | %s | %s | %s | %s | %s |' % (
            entry['name'], entry.get('source', ''), params,
            t['grid_size'] or ('trained' if entry.get('train') else '-'), four(t['train']),
            four(t['validation'])))
    lines.append('')
    return '\n'.join(lines)


def figure(boards, config, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = [e['name'] for e in config['entries']]
    fig, axes = plt.subplots(1, len(boards), figsize=(6.5 * len(boards), 4.2), squeeze=False)
    for ax, (bench, rows) in zip(axes[0], boards.items()):
        cases = [c for c in design.CASES if any(r['case'] == c for r in rows)]
        width = 0.8 / max(1, len(names))
        for k, name in enumerate(names):
            mine = {r['case']: r for r in rows if r['entry'] == name}
            x = np.arange(len(cases)) + (k - (len(names) - 1) / 2) * width
            rate = [mine[c]['correct'] / mine[c]['n'] if c in mine and mine[c]['n'] else 0
                    for c in cases]
            low = [rate[i] - mine[c]['wilson95'][0] if c in mine else 0
                   for i, c in enumerate(cases)]
            high = [mine[c]['wilson95'][1] - rate[i] if c in mine else 0
                    for i, c in enumerate(cases)]
            ax.bar(x, [100 * v for v in rate], width, label=name,
                   yerr=[[100 * v for v in low], [100 * v for v in high]], capsize=2)
        ax.set_xticks(np.arange(len(cases)))
        ax.set_xticklabels(cases)
        ax.set_ylim(0, 105)
        ax.set_ylabel('correct stops [%] (Wilson 95 %)')
        ax.set_title('bench: %s' % bench)
    axes[0][0].legend(fontsize=8, loc='lower left')
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def tune_all(entries, traces, args):
    """({name: tuning} in the entries' order, the Table II identification's folder; None when
    it failed, reported). The learned entry's training (Python) and Table II (once for every
    closed-loop campaign: it takes no scenario setting) run on a thread beside the grids'
    `recognize` processes; neither depends on the other."""
    import concurrent.futures
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as beside:
        learned = {entry['name']: beside.submit(
            train_entry, entry, args.dataset, args.out, traces['train'], traces['validation'])
            for entry in entries if entry.get('train') == 'learned'}
        identification = beside.submit(identify, args.out, args.jobs)
        tuned = {}
        for entry in entries:
            sys.stderr.write('leaderboard: tuning %s\n' % entry['name'])
            if entry['name'] not in learned:
                tuned[entry['name']] = tune_entry(entry, traces['train'], traces['validation'],
                                                  jobs=args.jobs)
        tuning = {entry['name']: (learned[entry['name']].result() if entry['name'] in learned
                                  else tuned[entry['name']]) for entry in entries}
        try:
            return tuning, identification.result()
        except IdentificationError as e:
            sys.stderr.write('leaderboard: %s\n' % e)
            return tuning, None


def write_board(boards, tuning, config, meta, args):
    """leaderboard.json, leaderboard.md and the figure, stamped (stamp())."""
    with atomic_write(os.path.join(args.out, 'leaderboard.json')) as handle:
        json.dump({'meta': meta, 'stamp': stamp(meta), 'trials': args.trials,
                   'boards': boards, 'tuning': tuning, 'ranks': {
                       bench: extra['ranks'] for bench, extra in args.extras.items()},
                   'strata': {bench: extra['strata'] for bench, extra in args.extras.items()},
                   'strata_edges': args.strata_edges,
                   'hidden': {bench: {'board': extra['hidden'],
                                      'specimens': extra['hidden_specimens']}
                              for bench, extra in args.extras.items()}},
                  handle, indent=1)
    with atomic_write(os.path.join(args.out, 'leaderboard.md')) as handle:
        handle.write(markdown(boards, tuning, config, meta, args))
    figure(boards, config, os.path.join(args.out, 'leaderboard.png'))


def board_settings(args, config, meta, test_per_case):
    """Sets args.cases, rpms, trials (default `test_per_case`), strata_edges and extras."""
    args.cases = config.get('cases') or list(design.CASES)
    args.rpms = [int(r) for r in (config.get('rpms') or [12000])]
    args.trials = args.trials or test_per_case
    args.strata_edges = board_stats.stratum_edges(
        os.path.join(args.dataset, 'train.npz'),
        (meta.get('hidden_conditions') or {}).get('density_reference_n'))
    args.extras = {}


def read_dataset(dataset_dir):
    """(split.json's meta, test trials per case and speed); LeaderboardError names a gap."""
    with open(os.path.join(dataset_dir, 'split.json')) as handle:
        meta = json.load(handle).get('meta')
    if not isinstance(meta, dict) or 'base_seed' not in meta:
        raise LeaderboardError('%s/split.json: no meta.base_seed (an older dataset?)'
                               % dataset_dir)
    with np.load(os.path.join(dataset_dir, 'test.npz')) as test:
        ids, cases, rpms = test['trial_trial_id'], test['trial_case'], test['trial_rpm']
    return meta, len(ids) // max(1, len(set(cases)) * len(set(rpms)))


def closed_loop(entries, tuning, benches, config, meta, args, identification):
    """{bench: board rows}: each entry (its `tuning` params) drills the test specimens on each
    bench, without and with the depth limit (args: board_settings', jobs, out; fills extras)."""
    boards = {}
    for bench in benches:
        scenario = os.path.join(PACKAGE_ROOT, 'config', config['benches'][bench])
        limited_scenario = scenario_with_depth_limit(
            scenario, os.path.join(args.out, 'closed_loop_depth_limit', bench))
        rows_by_entry = {}
        limited_by_entry = {}
        for entry in entries:
            sys.stderr.write('leaderboard: %s on the %s bench\n' % (entry['name'], bench))
            rows_by_entry[entry['name']] = run_campaign(
                entry, tuning[entry['name']]['params'], scenario, meta, args,
                os.path.join(args.out, 'closed_loop', bench, entry['name']), identification)
            sys.stderr.write('leaderboard: %s on the %s bench, depth limit on\n'
                             % (entry['name'], bench))
            limited_by_entry[entry['name']] = run_campaign(
                entry, tuning[entry['name']]['params'], limited_scenario, meta, args,
                os.path.join(args.out, 'closed_loop_depth_limit', bench, entry['name']),
                identification)
        boards[bench] = board_rows(rows_by_entry, config['reference'],
                                   limited_rows(limited_by_entry))
        args.extras[bench] = extras(rows_by_entry, args, meta)
    return boards


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='campaign_leaderboard',
        description='Recognizers tuned on the dataset\'s training split, compared in closed loop '
        'on its test split\'s specimens (doc/leaderboard.md).')
    parser.add_argument('--dataset', required=True, help='a campaign_dataset output folder')
    parser.add_argument('--out', required=True)
    parser.add_argument('--config', default=DEFAULT_CONFIG)
    parser.add_argument('--trials', type=int, default=None,
                        help='closed-loop trials per case and speed (default: the test split\'s)')
    parser.add_argument('--bench', action='append', default=None,
                        help='a bench of the configuration (repeatable; default: all)')
    parser.add_argument('--entry', action='append', default=None,
                        help='an entry of the configuration (repeatable; default: all; the '
                        'reference always runs)')
    parser.add_argument('--jobs', type=int, default=2)
    args = parser.parse_args(argv)
    try:
        config = load_config(args.config)
        meta, test_per_case = read_dataset(args.dataset)
    except (OSError, ValueError) as e:
        parser.error(str(e))
    board_settings(args, config, meta, test_per_case)
    benches = args.bench or list(config['benches'])
    for bench in benches:
        if bench not in config['benches']:
            parser.error('--bench %r is not one of: %s' % (bench, ', '.join(config['benches'])))
    if args.entry:
        unknown = set(args.entry) - {e['name'] for e in config['entries']}
        if unknown:
            parser.error('--entry %s: not in %s' % (', '.join(sorted(unknown)), args.config))
        config['entries'] = [e for e in config['entries']
                             if e['name'] in args.entry or e['name'] == config['reference']]
    os.makedirs(args.out, exist_ok=True)
    traces = {split: offline.export_traces(os.path.join(args.dataset, split + '.npz'),
                                   os.path.join(args.out, 'traces', split))
              for split in ('train', 'validation')}
    tuning, identification = tune_all(config['entries'], traces, args)
    with atomic_write(os.path.join(args.out, 'tuning.json')) as handle:
        json.dump(tuning, handle, indent=1)
    if identification is None:
        return 1
    boards = closed_loop(config['entries'], tuning, benches, config, meta, args, identification)
    write_board(boards, tuning, config, meta, args)
    sys.stderr.write('leaderboard: %s\n' % os.path.join(args.out, 'leaderboard.md'))
    return 0
