"""`rosrun pedicle_drilling campaign` and `rosrun pedicle_drilling campaign_merge`: the campaign's
run (its identification, workers, collected trials and outputs) and the merge of its shards. Its
command line is arguments.py's, its scenario scenario.py's."""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time

from . import aggregate, engine_core, profile, report, resume, reuse, tools, trials_csv
from .arguments import prepare
from .atomic import atomic_path, atomic_write, remove_temporaries
from .design import build_design, shard
from .identification import TABLE2_FILES, check_identification, identification_files
from .progress import Progress
from .scenario import (COMPENSATION_PROFILES, DEFAULT_MODEL, FAULT_PARAMS, INTEGER_FAULT_PARAMS,
                       PACKAGE_ROOT, ROS_DELAYS, UsageError)

# Options that change a campaign's outputs besides its design and scenario: --resume refuses a
# folder whose campaign had others (resume.check). The others may differ: --jobs, --base-port,
# --pin-workers and --reuse-trials change no trial; --identification is the folder's own once
# it is complete, and the Table II models are compared by content (the engine key); --profile is
# refused with --resume.
RESUME_OPTIONS = ('bags', 'samples', 'real_time_factor', 'lockstep_every_step', 'no_figures')


def worker_cpus(jobs, mode, allowed):
    """The CPU each of `jobs` ROS workers is pinned to (None: not pinned), from the CPU set
    `allowed` (os.sched_getaffinity: a Slurm allocation's CPUs, not the machine's) and
    --pin-workers `mode`: auto pins one worker per CPU when there are no more workers than
    CPUs, on pins round robin, off never. A trial does not depend on it (the lockstep)."""
    cpus = sorted(allowed)
    if mode == 'off' or not cpus or (mode == 'auto' and jobs > len(cpus)):
        return [None] * jobs
    return [cpus[k % len(cpus)] for k in range(jobs)]


def write_outputs(rows, meta, out_dir, notes='', figures=True):
    """trials.csv, summary.json, report.md and (`figures`) the figures from the finished
    rows."""
    trials_csv.write_trials_csv(rows, os.path.join(out_dir, 'trials.csv'))
    # Everything below from the rows as trials.csv keeps them (6 significant digits), so that a
    # merge of shards, which can only read trials.csv, gives the very same summary and report.
    rows = trials_csv.read_trials_csv(os.path.join(out_dir, 'trials.csv'))
    summary = aggregate.summarise(rows)
    faults = aggregate.fault_summary(rows)
    rows = [r for r in rows if r['fault'] == 'none']  # the paper's figures: fault-free trials
    aggregate.write_summary_json(summary, meta, os.path.join(out_dir, 'summary.json'), faults)
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


def _meta(setup, design):
    """The report's meta data: the design only, so that merged shards report the same."""
    scenario = setup.settings
    meta = {'cases': setup.cases, 'rpms': setup.rpms, 'trials': setup.trials, 'seed': setup.seed,
            'seed_space': setup.args.seed_space,
            'design_size': len(design), 'simulator': scenario.simulator,
            'model': scenario.model,
            'bone_motion': scenario.bone_motion,
            'compensation_profile': scenario.compensation_profile,
            'depth_limit': scenario.depth_limit,
            'protocol': scenario.protocol,
            'simulator_params': scenario.simulator_params,
            'planner_params': scenario.planner_params,
            'engine_delays': scenario.engine_delays,
            'recognizer': setup.recognizer,
            'compensator': setup.compensator,
            'engine': setup.args.engine}
    for kind in ('recognizer', 'compensator'):
        if setup.params[kind]:
            meta[kind + '_params'] = setup.params[kind]
    if setup.faults:
        meta['faults'] = list(setup.faults)
        meta['fault_params'] = {k: float(v) for k, v in
                                sorted(scenario.fault_params.items())}
    return meta


def _identify(args, scenario, out_dir, own=False):
    """The folder of the Table II models the trials use ('' without: identification online);
    None when the identification failed (said on stderr). `own`: a resumed campaign keeps its
    folder's identification when it is complete (its trials used it)."""
    if scenario.identification != 'volunteers':
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
    scenario, params = setup.settings, setup.params
    pose = engine_core.drilling_pose(PACKAGE_ROOT)

    def command(samples_dir=None, profile_path=None):
        return engine_core.trial_engine_command(
            '-', pose, models_dir,
            scenario.model, scenario.bone_motion, float(scenario.feed_rate_mm_s),
            float(scenario.max_duration_s), DEFAULT_MODEL,
            COMPENSATION_PROFILES[scenario.compensation_profile],
            [(FAULT_PARAMS[k], int(v) if k in INTEGER_FAULT_PARAMS else float(v))
             for k, v in sorted(scenario.fault_params.items())],
            setup.recognizer, setup.compensator, params['recognizer'], params['compensator'],
            scenario.simulator, scenario.protocol, scenario.simulator_params,
            planner_settings(scenario), scenario.engine_delays, samples_dir, profile_path)
    return command


def planner_settings(scenario):
    """The core engine's planner settings: the scenario's planner_params, and
    depth_limit/require_plan false for a scenario without the depth limit (key depth_limit).
    `scenario`: a Scenario."""
    settings = dict(scenario.planner_params)
    if not scenario.depth_limit:
        settings['depth_limit/require_plan'] = False
    return settings


def _master_port(base_port, k):
    """The k-th ROS worker's master port: a block of 8 ports per campaign process above
    base_port (by its pid, so that campaigns running at once, as in a parallel test run, start
    apart), the first of them from k on that no process listens on."""
    port = base_port + (os.getpid() % 400) * 8 + k
    for candidate in range(port, port + 64):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            try:
                probe.bind(('127.0.0.1', candidate))
            except OSError:
                continue
            return candidate
    return port


def _ros_worker(setup, out_dir, k, part, models_dir, cpu):
    """The k-th --engine ros worker, started on its trials `part`."""
    args, scenario, params = setup.args, setup.settings, setup.params
    trial_file = os.path.join(out_dir, 'worker-%d-trials.json' % k)
    with atomic_write(trial_file) as handle:
        json.dump(part, handle)
    command = ['/usr/bin/python3', '-m', 'pd_campaign.worker',
               '--port', str(_master_port(args.base_port, k)),
               '--trials', trial_file, '--out', out_dir,
               '--feed-rate', str(scenario.feed_rate_mm_s),
               '--max-duration', str(scenario.max_duration_s),
               '--identification-window-s', str(scenario.identification_window_s),
               '--default-model', DEFAULT_MODEL,
               '--real-time-factor', str(args.real_time_factor),
               '--models-dir', models_dir,
               '--model', scenario.model,
               '--bone-motion', scenario.bone_motion,
               '--segment-profile', COMPENSATION_PROFILES[scenario.compensation_profile],
               '--simulator-overrides', json.dumps(scenario.simulator),
               '--recognizer', setup.recognizer,
               '--compensator', setup.compensator,
               '--depth-limit', 'true' if scenario.depth_limit else 'false']
    # The classes' parameters as the core engine takes them (NAME=VALUE text); the worker
    # puts them in the nodelets' parameter files (worker_config.plugin_config).
    for kind in ('recognizer', 'compensator'):
        for name, value in sorted(params[kind].items()):
            command += ['--%s-param' % kind, '%s=%s' % (name, value)]
    for name, value in sorted(scenario.engine_delays.items()):
        command += ['--simulator-param', '%s=%r' % (ROS_DELAYS[name], float(value))]
    for name, value in sorted(scenario.simulator_params.items()):
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
        self.appender = trials_csv.TrialsAppender(os.path.join(out_dir, 'trials.csv'), first)
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
                row = trials_csv.normalise_row({k: ('' if v is None else v)
                                                for k, v in raw.items()})
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
    models_dir = _identify(args, setup.settings, out_dir, own=resuming)
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
    """`campaign ARGV`: its exit status (2: refused, naming the option or the scenario key)."""
    try:
        setup = prepare(argv)
    except UsageError as error:
        sys.stderr.write('campaign: %s\n' % error)
        return 2
    return run_prepared(setup)


def run_prepared(setup):
    """The campaign of `setup` (arguments.prepare's, checked) in its --out folder: its exit
    status (0 complete, 1 trials missing or an output not written, 2 refused, 130 Ctrl-C).
    pd_campaign.api runs its campaigns through it, as the command line does."""
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
            shard_rows = trials_csv.read_trials_csv(os.path.join(directory, 'trials.csv'))
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
