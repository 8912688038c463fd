"""The campaign from Python (a notebook, a script): keyword arguments in, pandas tables out.

    from pd_campaign import api
    campaign = api.run_campaign(case='compensated', rpm=12000, trials=4, seed=7)
    campaign.rows                      # trials.csv as a DataFrame, one row per trial
    campaign.trace(campaign.rows.trial_id[0])   # a trial's recognizer trace
    train = api.load_split('data', 'train')      # a dataset split (doc/dataset.md)
    api.score_offline('pedicle_drilling/PaperRecognizer', 'data', 'validation')
    api.submit('my_entry.yaml', 'data', 'my_board')   # a leaderboard row (doc/leaderboard.md)

A thin layer over the command line's code: a campaign's keywords become the options of
`campaign` (run_campaign's OPTIONS), checked by the same arguments.prepare (the scenario's
validation, the classes loaded by trial_engine) and run by the same cli.run_prepared; a refusal
raises ApiError naming the keyword. Offline scoring is the leaderboard's (the `recognize` tool
over a split's raw force, the object the closed loop runs); closed-loop scoring and submission
are pd_campaign.submission's, the leaderboard's own steps. Nothing here changes a trial: a
campaign run here writes the same trials.csv as `campaign` with the same options."""
import json
import os
import re
import sys
import tempfile
import warnings

import numpy as np
import pandas

from . import arguments, cli, leaderboard, offline, splits, submission, trials_csv
from .scenario import UsageError

# keyword -> the campaign's option; a list or tuple value is joined with commas.
OPTIONS = {'scenario': '--scenario', 'case': '--case', 'rpm': '--rpm', 'trials': '--trials',
           'seed': '--seed', 'seed_space': '--seed-space', 'recognizer': '--recognizer',
           'compensator': '--compensator', 'engine': '--engine', 'jobs': '--jobs',
           'identification': '--identification', 'reuse_trials': '--reuse-trials',
           'shard': '--shard', 'real_time_factor': '--real-time-factor'}
# keyword -> the campaign's flag (True: given).
FLAGS = {'samples': '--samples', 'profile': '--profile', 'resume': '--resume',
         'bags': '--bags'}
# keyword -> the repeatable NAME=VALUE option its mapping becomes.
PARAM_OPTIONS = {'recognizer_params': '--recognizer-param',
                 'compensator_params': '--compensator-param'}


class ApiError(submission.SubmissionError):
    """A bad argument, named by its keyword (a ValueError)."""


def add_module(path):
    """Makes the Python file `path` importable by its name (its folder first on sys.path, and
    on PYTHONPATH for the engines and tools this process starts); returns the module's name, so
    that `'python:%s.MyClass' % add_module('my/file.py')` names a recognizer class in it."""
    try:
        return submission.add_module(path)
    except submission.SubmissionError as error:
        raise ApiError(str(error)) from None


def _text(keyword, value):
    """An option's value as the command line's text; lists joined with commas."""
    if isinstance(value, (list, tuple)):
        if not value:
            raise ApiError('%s: an empty list' % keyword)
        return ','.join(_text(keyword, item) for item in value)
    if isinstance(value, bool) or not isinstance(value, (str, int, float, os.PathLike)):
        raise ApiError('%s: %r is not a number, a text or a list of them' % (keyword, value))
    return repr(value) if isinstance(value, float) else str(value)


def _scenario_file(scenario, out_dir):
    """A scenario given as a mapping, written to OUT/scenario.yaml (the campaign validates it
    as any scenario file); a path as it is."""
    if not isinstance(scenario, dict):
        return scenario
    import yaml
    from .atomic import atomic_write
    path = os.path.join(out_dir, 'scenario.yaml')
    with atomic_write(path) as handle:
        yaml.safe_dump(scenario, handle, sort_keys=False)
    return path


def campaign_argv(out, figures=False, **keywords):
    """The `campaign` command line of run_campaign's keywords (ApiError names a bad one)."""
    argv = ['--out', str(out)]
    for keyword, value in keywords.items():
        if value is None:
            continue
        if keyword in OPTIONS:
            argv += [OPTIONS[keyword], _text(keyword, value)]
        elif keyword in FLAGS:
            if not isinstance(value, bool):
                raise ApiError('%s: %r is not True or False' % (keyword, value))
            argv += [FLAGS[keyword]] if value else []
        elif keyword in PARAM_OPTIONS:
            if not isinstance(value, dict):
                raise ApiError('%s: %r is not a mapping {name: value}' % (keyword, value))
            for name, item in sorted(value.items()):
                argv += [PARAM_OPTIONS[keyword], '%s=%s' % (name, _text(keyword, item))]
        else:
            raise ApiError('%s: not a keyword of run_campaign (known: %s)' % (keyword, ', '.join(
                sorted(list(OPTIONS) + list(FLAGS) + list(PARAM_OPTIONS) + ['out', 'figures']))))
    if not figures:
        argv.append('--no-figures')
    return argv


def _keyword_error(message):
    """The campaign's message with each option it names followed by its keyword here."""
    keywords = {option: keyword for keyword, option in
                list(OPTIONS.items()) + list(FLAGS.items()) + list(PARAM_OPTIONS.items())}
    return ApiError(re.sub(r'--[a-z-]+', lambda m: '%s (keyword %s)' % (
        m.group(0), keywords[m.group(0)]) if m.group(0) in keywords else m.group(0), message))


def run_campaign(out=None, figures=False, **keywords):
    """Runs a campaign (its keywords: OPTIONS, FLAGS and PARAM_OPTIONS, as `campaign`'s options;
    `scenario` a YAML path or a mapping of scenario keys) into `out` (default: a new temporary
    folder); returns a Campaign. Raises ApiError naming the keyword the campaign refuses;
    warns when trials are missing (Campaign.status 1)."""
    out = os.path.abspath(out or tempfile.mkdtemp(prefix='pd_campaign_'))
    os.makedirs(out, exist_ok=True)
    if 'scenario' in keywords:
        keywords['scenario'] = _scenario_file(keywords['scenario'], out)
    argv = campaign_argv(out, figures, **keywords)
    try:
        setup = arguments.prepare(argv)
    except UsageError as error:
        raise _keyword_error(str(error)) from None
    except SystemExit:
        raise ApiError('the campaign refused its arguments %s (its message above)' % argv)
    status = cli.run_prepared(setup)
    if status == 130:
        raise KeyboardInterrupt
    if status == 2:
        raise ApiError('the campaign refused its scenario (its message above; %s)' % out)
    if status != 0:
        warnings.warn('campaign %s: not every trial finished (exit %d): see its report' % (
            out, status))
    return Campaign(out, status)


def run_trial(case='compensated', rpm=12000, seed=1, **keywords):
    """One trial (a campaign of one: `case`, `rpm`, the design's first seed of base `seed`;
    the other keywords as run_campaign's); returns a Trial (its row and its trace)."""
    campaign = run_campaign(case=case, rpm=rpm, trials=1, seed=seed, jobs=1, **keywords)
    return Trial(campaign)


class Campaign:
    """A campaign's folder read as tables: `rows` (trials.csv), `summary` (summary.json),
    `trace(trial_id)`; `status` the campaign's exit status."""

    def __init__(self, out, status=0):
        self.out = out
        self.status = status
        self._rows = None

    @property
    def rows(self):
        """trials.csv as a DataFrame, one row per trial, in design order."""
        if self._rows is None:
            self._rows = pandas.DataFrame(
                trials_csv.read_trials_csv(os.path.join(self.out, 'trials.csv')))
        return self._rows

    @property
    def summary(self):
        """summary.json (per case and speed: successes with Wilson intervals, ...)."""
        with open(os.path.join(self.out, 'summary.json')) as handle:
            return json.load(handle)

    def trace(self, trial_id):
        """A trial's trace (traces/<trial_id>.json) as a DataFrame: t (s from the start of
        drilling), force (the recognizer's averaged force, N) and feature; its attrs hold
        key_points and stop_t."""
        path = os.path.join(self.out, 'traces', '%s.json' % trial_id)
        if not os.path.isfile(path):
            raise ApiError('trial_id: %r has no trace in %s' % (trial_id, self.out))
        with open(path) as handle:
            data = json.load(handle)
        frame = pandas.DataFrame({key: data[key] for key in ('t', 'force', 'feature')})
        frame.attrs.update(key_points=data['key_points'], stop_t=data['stop_t'])
        return frame

    def traces(self):
        """{trial_id: trace} of every trial."""
        return {trial_id: self.trace(trial_id) for trial_id in self.rows['trial_id']}


class Trial:
    """One trial: `row` (a Series of trials.csv's columns), `trace` and its `campaign`."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.row = campaign.rows.iloc[0]
        self.trace = campaign.trace(self.row['trial_id'])


Split = splits.Split


def load_split(dataset_dir, split='train'):
    """A Split of a campaign_dataset folder (pd_campaign.splits): train, validation or test
    (look at the test split only to report, never to choose)."""
    try:
        return splits.Split(dataset_dir, split)
    except splits.SplitError as error:
        raise ApiError(str(error)) from None


def _texts(params):
    try:
        return submission.texts('params', params)
    except submission.SubmissionError as error:
        raise ApiError(str(error)) from None


def _grid(grid):
    try:
        return submission.grid(grid)
    except submission.SubmissionError as error:
        raise ApiError(str(error).replace('tune:', 'grid:', 1)) from None


def _recognizer_name(recognizer):
    """A class name as the engines take it; a Python class given itself is named by its module
    (which must be importable by that name: add_module)."""
    if isinstance(recognizer, type):
        return 'python:%s.%s' % (recognizer.__module__, recognizer.__qualname__)
    if not isinstance(recognizer, str) or not recognizer:
        raise ApiError('recognizer: %r is not a class name (pkg/Class or python:module.Class) '
                       'or a Python class' % (recognizer,))
    return recognizer


def score_offline(recognizer, dataset_dir, split='validation', params=None):
    """A recognizer's stops over a split's raw force (the leaderboard's tuning score: the
    `recognize` tool, the object the closed loop runs): {correct, shallow, early, late,
    none} (doc/leaderboard.md)."""
    split = load_split(dataset_dir, split)
    with tempfile.TemporaryDirectory(prefix='pd_score_') as scratch:
        traces = offline.export_traces(split.path, scratch)
        try:
            return leaderboard.offline_score(_recognizer_name(recognizer), _texts(params),
                                             traces)
        except leaderboard.LeaderboardError as error:
            raise ApiError('recognizer: %s' % error) from None


def tune_offline(recognizer, dataset_dir, grid, params=None, jobs=2):
    """The leaderboard's choice of a grid `{name: [values]}` (with the fixed `params`): scored
    on the training split, the best few re-scored on validation; {params, train, validation,
    grid_size, top}."""
    entry = {'name': 'tuned', 'recognizer': _recognizer_name(recognizer),
             'params': _texts(params), 'tune': _grid(grid)}
    with tempfile.TemporaryDirectory(prefix='pd_tune_') as scratch:
        traces = {name: offline.export_traces(load_split(dataset_dir, name).path,
                                                  os.path.join(scratch, name))
                  for name in ('train', 'validation')}
        return leaderboard.tune_entry(entry, traces['train'], traces['validation'],
                                      log=_Quiet(), jobs=jobs)


class _Quiet:
    def write(self, text):
        pass


def score_closed_loop(recognizer, dataset_dir, out=None, params=None, name='entry', **options):
    """A recognizer (with fixed `params`) in closed loop on the dataset's test specimens beside
    the leaderboard's reference, on its benches: a Submission (its board rows). `options` as
    submit's."""
    entry = {'name': name, 'recognizer': _recognizer_name(recognizer),
             'params': _texts(params)}
    return submit(entry, dataset_dir, out, **options)


def submit(entry, dataset_dir, out=None, fit=None, bench=None, trials=None, jobs=2,
           config=leaderboard.DEFAULT_CONFIG):
    """A leaderboard entry submitted from outside (doc/leaderboard.md, "Submit an entry"): its
    YAML's path or its mapping, the dataset folder, the output folder (default: a new
    temporary one); `fit(train, validation, out)` (optional, your code) gets the two Splits and
    returns parameters fixed for the entry; `bench` one bench or a list (default all). Returns
    a Submission: `rows` (its board rows and the reference's), `result` (result.json)."""
    out = os.path.abspath(out or tempfile.mkdtemp(prefix='pd_submit_'))
    if fit is not None and not callable(fit):
        raise ApiError('fit: %r is not callable' % (fit,))
    benches = [bench] if isinstance(bench, str) else bench
    try:
        submission.run(submission.read_entry(entry), str(dataset_dir), out, fit=fit,
                       benches=benches, trials=trials, jobs=jobs, config_path=config,
                       log=sys.stderr)
    except submission.SubmissionError as error:
        if isinstance(error, ApiError):
            raise
        raise ApiError(str(error)) from None
    return Submission(out)


class Submission:
    """A submission's folder: `result` (result.json), `rows` (its leaderboard rows as a
    DataFrame, the reference's too, with a `bench` column), `board` (leaderboard.md)."""

    def __init__(self, out):
        self.out = out
        with open(os.path.join(out, submission.RESULT_NAME)) as handle:
            self.result = json.load(handle)
        self.rows = pandas.DataFrame(self.result['board_rows'])

    @property
    def board(self):
        with open(os.path.join(self.out, 'leaderboard.md')) as handle:
            return handle.read()
