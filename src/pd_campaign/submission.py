"""A leaderboard entry submitted from outside the package (doc/leaderboard.md, "Submit an
entry"): a recognizer's Python file anywhere and a small YAML of its own in; the board rows and
a result file out, without editing config/leaderboard.yaml.

    rosrun pedicle_drilling campaign_submit --entry my_entry.yaml --dataset DATA --out DIR

The entry's YAML (ENTRY_KEYS; a path in it is relative to the YAML's folder):

    name: mean_rise                  # the row's name
    module: mean_rise.py             # the recognizer's Python file
    class: MeanRise                  # its class (pd_campaign.recognizers' contract)
    source: a sentence: the method and where it comes from
    params: {contact_n: 1.0}         # fixed parameters
    tune: {rise_n: [0.4, 0.8, 1.2]}  # a grid, chosen as the board chooses (optional)
    fit: fit                         # a function of the module: your training (optional)
    files: [model]                   # parameters that name a file, relative to the YAML

The steps are the leaderboard's own (pd_campaign.leaderboard): `fit(train, validation, out)`,
when given, is called with the training and validation splits (pd_campaign.splits.Split: never
the test split) and returns parameters fixed for the entry (e.g. the path of a model it wrote
into `out`); the grid is scored offline on the training split, the best re-scored on
validation (tune_all, beside the Table II identification); the entry and the board's
reference drill the test split's specimens on the benches, with and without the depth limit
(closed_loop); DIR/leaderboard.md, .json and .png are the board of the two (write_board), and
DIR/result.json (RESULT_NAME, written atomically) the entry, its chosen parameters, its rows
and the reference's, the stamp (dataset version and build, the board's build) and the seeds of
every closed-loop trial."""
import argparse
import csv
import importlib
import importlib.util
import json
import os
import re
import sys

import yaml

from . import leaderboard, offline
from .atomic import atomic_write

RESULT_NAME = 'result.json'
ENTRY_KEYS = ('name', 'module', 'class', 'recognizer', 'source', 'params', 'tune', 'fit',
              'files')
NAME = re.compile(r'^[A-Za-z0-9_.-]+$')


class SubmissionError(ValueError):
    """A bad entry, dataset or option, named."""


def add_module(path):
    """Makes the Python file `path` importable by its name: its folder first on sys.path and on
    PYTHONPATH (the engines and tools this process starts then import it). Returns the
    module's name; SubmissionError when the file is not one or another module has its name."""
    path = os.path.abspath(str(path))
    folder, base = os.path.split(path)
    name = base[:-3] if base.endswith('.py') else ''
    if not os.path.isfile(path) or not name.isidentifier():
        raise SubmissionError('module: %s is not a Python file with a module\'s name' % path)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    parts = [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]
    if folder not in parts:
        os.environ['PYTHONPATH'] = os.pathsep.join([folder] + parts)
    importlib.invalidate_caches()
    spec = importlib.util.find_spec(name)
    if spec is None or os.path.realpath(spec.origin or '') != os.path.realpath(path):
        raise SubmissionError('module: the name %r of %s is another module\'s (%s): rename '
                              'the file' % (name, path, spec and spec.origin))
    return name


def texts(keyword, mapping):
    """{name: value as text} of a mapping of parameters; SubmissionError names `keyword`."""
    if mapping is None:
        return {}
    if not isinstance(mapping, dict):
        raise SubmissionError('%s: %r is not a mapping {name: value}' % (keyword, mapping))
    out = {}
    for name, value in mapping.items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        if not isinstance(value, (str, int, float)):
            raise SubmissionError('%s: %s: %r is not a number, a bool or a text'
                                  % (keyword, name, value))
        out[str(name)] = str(value)
    return out


def grid(mapping):
    """A tuning grid {name: [values as text]}; SubmissionError names `tune`."""
    if mapping is None:
        return {}
    if not isinstance(mapping, dict):
        raise SubmissionError('tune: %r is not a mapping {name: [values]}' % (mapping,))
    out = {}
    for name, values in mapping.items():
        if not isinstance(values, list) or not values:
            raise SubmissionError('tune: %s: not a non-empty list of values' % name)
        out[str(name)] = list(texts('tune', {str(k): v for k, v in enumerate(values)}).values())
    return out


def _load_yaml(path):
    try:
        with open(path) as handle:
            data = yaml.safe_load(handle)
    except (OSError, yaml.YAMLError) as error:
        raise SubmissionError('entry: %s: cannot read: %s' % (path, ' '.join(
            str(error).split()))) from None
    if not isinstance(data, dict):
        raise SubmissionError('entry: %s is not a mapping of %s' % (path, ', '.join(ENTRY_KEYS)))
    return data


def _module_class(data, base):
    """(recognizer name, module path, the module) of an entry's module and class."""
    if 'class' not in data or not str(data['class']).isidentifier():
        raise SubmissionError('class: the recognizer\'s class name in %s is required'
                              % data['module'])
    path = os.path.join(base, str(data['module']))
    name = add_module(path)
    try:
        module = importlib.import_module(name)
    except Exception as error:
        raise SubmissionError('module: %s does not import: %s: %s' % (
            path, type(error).__name__, error)) from None
    if not isinstance(getattr(module, data['class'], None), type):
        raise SubmissionError('class: %s has no class %s' % (path, data['class']))
    return 'python:%s.%s' % (name, data['class']), os.path.abspath(path), module


def read_entry(entry):
    """An entry (its YAML's path, or the mapping) checked, as the leaderboard's entries are
    (name, recognizer, source, params, tune) with `fit` (a callable or None) and `module`."""
    base = os.getcwd()
    if isinstance(entry, (str, os.PathLike)):
        base = os.path.dirname(os.path.abspath(str(entry)))
        entry = _load_yaml(str(entry))
    if not isinstance(entry, dict):
        raise SubmissionError('entry: %r is not a YAML path or a mapping' % (entry,))
    unknown = sorted(set(entry) - set(ENTRY_KEYS))
    if unknown:
        raise SubmissionError('entry: unknown key %s (known: %s)' % (
            ', '.join(unknown), ', '.join(ENTRY_KEYS)))
    if not NAME.match(str(entry.get('name', ''))):
        raise SubmissionError('name: %r is required: letters, digits, _ . -' % entry.get('name'))
    out = {'name': str(entry['name']), 'source': str(entry.get('source', '')),
           'params': texts('params', entry.get('params')), 'tune': grid(entry.get('tune')),
           'module': None, 'fit': None}
    module = None
    if 'module' in entry:
        out['recognizer'], out['module'], module = _module_class(entry, base)
    elif isinstance(entry.get('recognizer'), str) and entry['recognizer']:
        out['recognizer'] = entry['recognizer']
    else:
        raise SubmissionError('module: the recognizer\'s Python file is required (or '
                              'recognizer: a class name)')
    if entry.get('fit') is not None:
        fit = getattr(module, str(entry['fit']), None) if module else None
        if not callable(fit):
            raise SubmissionError('fit: %r is not a function of the module' % entry['fit'])
        out['fit'] = fit
    for name in entry.get('files') or []:
        if name not in out['params']:
            raise SubmissionError('files: %s is not one of the params' % name)
        out['params'][name] = os.path.join(base, out['params'][name])
    return out


def _settings(dataset_dir, out, benches, trials, jobs, config_path):
    """(the board's configuration, the reference entry, args, meta), checked."""
    try:
        config = leaderboard.load_config(config_path)
        meta, per_case = leaderboard.read_dataset(dataset_dir)
    except leaderboard.LeaderboardError as error:
        raise SubmissionError(str(error)) from None
    except (OSError, ValueError) as error:
        raise SubmissionError('dataset: %s: %s' % (dataset_dir, error)) from None
    benches = benches or list(config['benches'])
    for bench in benches:
        if bench not in config['benches']:
            raise SubmissionError('bench: %r is not one of %s' % (bench, ', '.join(
                config['benches'])))
    if trials is not None and (isinstance(trials, bool) or not isinstance(trials, int)
                               or trials < 1):
        raise SubmissionError('trials: %r is not a positive count' % (trials,))
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not 1 <= jobs <= 64:
        raise SubmissionError('jobs: %r is not in 1..64' % (jobs,))
    args = argparse.Namespace(dataset=dataset_dir, out=out, trials=trials, jobs=jobs,
                              benches=benches)
    leaderboard.board_settings(args, config, meta, per_case)
    reference = next(e for e in config['entries'] if e['name'] == config['reference'])
    return config, reference, args, meta


def _fitted(entry, fit, dataset_dir, out):
    """The entry's fixed parameters, with those its `fit` returns from the training and
    validation splits."""
    fit = fit or entry['fit']
    if fit is None:
        return dict(entry['params'])
    from . import splits  # pandas: only for an entry that trains
    try:
        train, validation = (splits.Split(dataset_dir, name) for name in ('train', 'validation'))
    except splits.SplitError as error:
        raise SubmissionError(str(error)) from None
    given = fit(train, validation, out)
    return dict(entry['params'], **texts('fit (its return value)', given))


def _seeds(out, bench, name):
    """[{trial_id, seed}] of an entry's closed-loop trials on a bench."""
    with open(os.path.join(out, 'closed_loop', bench, name, 'trials.csv')) as handle:
        return [{'trial_id': row['trial_id'], 'seed': int(row['seed'])}
                for row in csv.DictReader(handle)]


def run(entry, dataset_dir, out, fit=None, benches=None, trials=None, jobs=2,
        config_path=leaderboard.DEFAULT_CONFIG, log=sys.stderr):
    """The submission of `entry` (read_entry's) into `out`: the module's steps; returns the
    result (what result.json holds). `fit` replaces the entry's own."""
    config, reference, args, meta = _settings(os.path.abspath(dataset_dir), out, benches,
                                              trials, jobs, config_path)
    if entry['name'] == reference['name']:
        raise SubmissionError('name: %r is the reference\'s: choose another' % entry['name'])
    os.makedirs(out, exist_ok=True)
    board_entry = {'name': entry['name'], 'recognizer': entry['recognizer'],
                   'source': entry['source'], 'tune': entry['tune'],
                   'params': _fitted(entry, fit, args.dataset, out)}
    traces = {split: offline.export_traces(os.path.join(args.dataset, split + '.npz'),
                                               os.path.join(out, 'traces', split))
              for split in ('train', 'validation')}
    entries = [reference, board_entry]
    tuning, identification = leaderboard.tune_all(entries, traces, args)
    if identification is None:
        raise RuntimeError('the Table II identification failed (its message above)')
    board_config = dict(config, entries=entries)
    boards = leaderboard.closed_loop(entries, tuning, args.benches, board_config, meta, args,
                                     identification)
    leaderboard.write_board(boards, tuning, board_config, meta, args)
    result = {'entry': dict(board_entry, module=entry['module'],
                            params=tuning[entry['name']]['params']),
              'reference': reference['name'], 'tuning': tuning[entry['name']],
              'stamp': leaderboard.stamp(meta),
              'dataset': {'path': args.dataset, 'version': meta.get('dataset_version'),
                          'build_id': meta.get('build_id'), 'base_seed': meta['base_seed'],
                          'seed_space': 'evaluation'},
              'cases': args.cases, 'rpms': args.rpms, 'trials_per_case': args.trials,
              'board_rows': [dict(row, bench=bench) for bench, rows in boards.items()
                             for row in rows],
              'seeds': {bench: _seeds(out, bench, entry['name']) for bench in args.benches}}
    with atomic_write(os.path.join(out, RESULT_NAME)) as handle:
        json.dump(result, handle, indent=1)
    log.write('campaign_submit: %s and %s\n' % (os.path.join(out, RESULT_NAME),
                                                 os.path.join(out, 'leaderboard.md')))
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='campaign_submit', description='Put a recognizer of your own on the leaderboard '
        'without editing the package: its Python file and a YAML of its own in, its board rows '
        'and a result file out (doc/leaderboard.md, "Submit an entry").')
    parser.add_argument('--entry', required=True, help='the entry\'s YAML (name, module, '
                        'class, source, params, tune, fit, files)')
    parser.add_argument('--dataset', required=True, help='a campaign_dataset output folder')
    parser.add_argument('--out', required=True)
    parser.add_argument('--bench', action='append', default=None,
                        help='a bench of the board (repeatable; default: all)')
    parser.add_argument('--trials', type=int, default=None,
                        help='closed-loop trials per case and speed (default: the test split\'s)')
    parser.add_argument('--config', default=leaderboard.DEFAULT_CONFIG,
                        help='the board whose benches, cases and reference it runs')
    parser.add_argument('--jobs', type=int, default=2)
    args = parser.parse_args(argv)
    try:
        run(read_entry(args.entry), args.dataset, os.path.abspath(args.out),
            benches=args.bench, trials=args.trials, jobs=args.jobs, config_path=args.config)
    except SubmissionError as error:
        sys.stderr.write('campaign_submit: %s\n' % error)
        return 2
    return 0
