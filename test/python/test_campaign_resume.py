"""A campaign's output folder under faults: `--resume` continues a campaign killed part-way
(the same trials.csv as an uninterrupted run), a second campaign cannot write a folder a running
one holds, and an output that cannot be written (a full disk) stops the campaign with one line
naming the file, keeping what was written before."""
import csv
import errno
import filecmp
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import threading
import time

import pytest

from pd_campaign import cli, resume, reuse, trials_csv

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
CAMPAIGN = os.path.join(ROOT, 'scripts', 'campaign')
SCENARIO = os.path.join(ROOT, 'config', 'scenario_paper.yaml')
# 36 trials of the core engine (about 5 s on 2 cores), without figures.
ARGS = ['--engine', 'core', '--scenario', SCENARIO, '--case', 'all', '--rpm', '12000',
        '--trials', '12', '--jobs', '2', '--seed', '61', '--no-figures']
TOTAL = 36
DEADLINE_S = 300.0  # a bound on a broken run, not a pacing


def _start(out, *extra):
    """The campaign as its own process (group), its stderr in OUT.log; SIGINT at its default,
    as a terminal's Ctrl-C finds it."""
    log = open(str(out) + '.log', 'w')
    process = subprocess.Popen(['/usr/bin/python3', CAMPAIGN] + ARGS + ['--out', str(out)] +
                               list(extra), stdout=subprocess.DEVNULL, stderr=log,
                               start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    log.close()
    return process


def _with(args, *extra):
    """`args` with the options of `extra` (option, then its value unless it is a flag): an
    option given in both takes `extra`'s value (the campaign refuses one given twice)."""
    args, extra = list(args), list(extra)
    k = 0
    while k < len(extra):
        flag = k + 1 == len(extra) or extra[k + 1].startswith('--')
        if extra[k] in args and not flag:
            args[args.index(extra[k]) + 1] = extra[k + 1]
        else:
            args += extra[k:k + (1 if flag else 2)]
        k += 1 if flag else 2
    return args


def _run(out, *extra, args=ARGS):
    return subprocess.run(['/usr/bin/python3', CAMPAIGN] + _with(args, *extra) +
                          ['--out', str(out)], capture_output=True, text=True,
                          timeout=DEADLINE_S)


def _rows_on_disk(out):
    """The whole rows of the live trials.csv (0 before it exists)."""
    try:
        return trials_csv.read_trials_csv(str(out / 'trials.csv'), whole_lines=True)
    except (OSError, ValueError):
        return []


def _wait_for_rows(process, out, count):
    """Waits until `count` trials of the running campaign are on disk."""
    deadline = time.monotonic() + DEADLINE_S
    while len(_rows_on_disk(out)) < count:
        assert process.poll() is None, 'the campaign ended before %d rows: %s' % (
            count, open(str(out) + '.log').read()[-3000:])
        assert time.monotonic() < deadline, 'no %d rows in time' % count
        time.sleep(0.01)


def _same_outputs(a, b):
    for name in ('trials.csv', 'summary.json', 'report.md'):
        assert filecmp.cmp(a / name, b / name, shallow=False), name
    names = sorted(os.listdir(a / 'traces'))
    assert names == sorted(os.listdir(b / 'traces'))
    match, mismatch, errors = filecmp.cmpfiles(a / 'traces', b / 'traces', names, shallow=False)
    assert not mismatch and not errors and len(match) == len(names)


def _temporaries(folder):
    return [n for _, _, names in os.walk(str(folder)) for n in names if '.tmp' in n]


def _snapshot(folder):
    """{relative path: (bytes, mtime)} of every file in `folder` but the lock file."""
    found = {}
    for directory, _, names in os.walk(str(folder)):
        for name in names:
            path = os.path.join(directory, name)
            if name != resume.LOCK_FILE:
                with open(path, 'rb') as handle:
                    found[os.path.relpath(path, str(folder))] = (handle.read(),
                                                                 os.stat(path).st_mtime_ns)
    return found


@pytest.fixture(scope='module')
def reference(tmp_path_factory):
    """The campaign of ARGS run without interruption."""
    out = tmp_path_factory.mktemp('resume') / 'reference'
    result = _run(out)
    assert result.returncode == 0, result.stderr[-3000:]
    assert len(_rows_on_disk(out)) == TOTAL
    return out


# --- --resume ---------------------------------------------------------------------------------

@pytest.mark.parametrize('number', [signal.SIGKILL, signal.SIGINT], ids=['SIGKILL', 'SIGINT'])
def test_a_campaign_killed_part_way_and_resumed_writes_what_an_uninterrupted_one_writes(
        tmp_path, reference, number):
    """Killed once 8 trials are on disk (SIGKILL: the live trials.csv as appended, with a trial
    whose trace was written and whose line was cut by the kill, and temporary files of writes it
    cut; SIGINT: exit 130, its report written), then
    `--resume` with another --jobs: it keeps the finished trials (their traces are not written
    again) and runs only the others; trials.csv, summary.json, report.md and every trace are
    byte for byte the uninterrupted run's (the core engine's trials.csv has no wall time:
    wall_s is empty), and no temporary file is left."""
    out = tmp_path / 'out'
    process = _start(out)
    _wait_for_rows(process, out, 8)
    os.killpg(process.pid, number)
    assert process.wait(timeout=60) == (-9 if number == signal.SIGKILL else 130)
    done = {row['trial_id'] for row in _rows_on_disk(out)}
    assert 8 <= len(done) < TOTAL, 'killed part-way'
    if number == signal.SIGKILL:
        with open(reference / 'trials.csv', newline='') as handle:
            lines = handle.read().splitlines(keepends=True)
        cut = next(line for line in lines[1:] if line.split(',')[0] not in done)
        trace = 'traces/%s.json' % cut.split(',')[0]
        if not (out / trace).exists():  # written before its line
            shutil.copyfile(str(reference / trace), str(out / trace))
        with open(out / 'trials.csv', 'a', newline='') as handle:
            handle.write(cut[:len(cut) // 2])  # the trial's line cut by the kill
        for left in ('.summary.json.tmpa1b2c3d4',
                     'traces/.%s.json.tmp_9z8y7x6' % cut.split(',')[0]):
            (out / left).write_text('{"half": ')  # a write cut by the kill
    traces = {trial_id: os.stat(out / 'traces' / (trial_id + '.json')).st_ino
              for trial_id in done}
    result = _run(out, '--resume', '--jobs', '1')
    assert result.returncode == 0, result.stderr[-3000:]
    assert '%d kept from the stopped campaign (--resume)' % len(done) in result.stderr
    assert traces == {trial_id: os.stat(out / 'traces' / (trial_id + '.json')).st_ino
                      for trial_id in done}, 'a finished trial ran again'
    _same_outputs(out, reference)
    assert not _temporaries(out)
    assert (out / reuse.SOURCE_FILE).exists(), 'finished: its trials may be taken'


@pytest.fixture(scope='module')
def small(tmp_path_factory):
    """A finished 3-trial campaign (its Table II identification serves as others'
    --identification)."""
    out = tmp_path_factory.mktemp('resume_small') / 'small'
    args = _with(ARGS, '--trials', '1', '--jobs', '1')
    result = _run(out, args=args)
    assert result.returncode == 0, result.stderr[-3000:]
    return out, args


@pytest.mark.parametrize('change, named', [
    (['--seed', '62'], 'design.meta.seed 61 there, 62 here'),
    (['--case', 'stationary'], 'design.meta.cases'),
    (['--shard', '1/2'], 'design.shard "1/1" there, "1/2" here'),
    (['--samples'], 'options.samples false there, true here'),
    (['--recognizer-param', 'cancellous_deadline=40'], 'design.meta.recognizer_params'),
    ('scenario', 'scenario.feed_rate_mm_s 0.5 there, 0.6 here'),
    ('build', 'another build, package files or Table II models: engine_key "another build" '
              'there'),
])
def test_resume_refuses_a_folder_whose_campaign_had_other_arguments(tmp_path, small, change,
                                                                    named):
    """Exit 2, naming the folder and what differs; nothing in the folder changes."""
    source, args = small
    out = tmp_path / 'small'
    shutil.copytree(str(source), str(out))
    extra = change if isinstance(change, list) else []
    if change == 'scenario':
        scenario = tmp_path / 'scenario.yaml'
        scenario.write_text(open(SCENARIO).read().replace('feed_rate_mm_s: 0.5',
                                                          'feed_rate_mm_s: 0.6'))
        assert scenario.read_text() != open(SCENARIO).read()
        extra = ['--scenario', str(scenario)]
    if change == 'build':  # as if the build or the package's files had changed since
        recorded = json.loads((out / resume.ARGS_FILE).read_text())
        recorded['engine_key'] = 'another build'
        (out / resume.ARGS_FILE).write_text(json.dumps(recorded))
    before = _snapshot(out)
    result = _run(out, '--resume', *extra, args=args)
    assert result.returncode == 2, result.stderr[-3000:]
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith('campaign: --resume: %s was started with other arguments: ' % out)
    assert named in line, line
    assert _snapshot(out) == before


def test_resume_continues_only_a_campaign_it_can_check(tmp_path, small):
    """Another --jobs (or --base-port, --identification) is no other campaign: every trial
    kept. Without --resume a campaign starts over in a folder of an earlier one, as it always
    did: every trial runs again. A folder without the record of its campaign's arguments (or
    without a campaign) keeps nothing: every trial runs."""
    source, args = small
    out = tmp_path / 'small'
    assert _run(out, args=args).returncode == 0  # its own: a key recorded just now
    result = _run(out, '--resume', '--jobs', '2', '--base-port', '12000', '--identification',
                  str(source / 'identification'), args=args)
    assert result.returncode == 0, result.stderr[-3000:]
    assert '3 kept from the stopped campaign (--resume)' in result.stderr
    _same_outputs(out, source)
    traces = {p.name: p.stat().st_ino for p in (out / 'traces').iterdir()}
    result = _run(out, args=args)
    assert result.returncode == 0, result.stderr[-3000:]
    assert 'kept' not in result.stderr
    assert all(p.stat().st_ino != traces[p.name] for p in (out / 'traces').iterdir())
    _same_outputs(out, source)
    for folder in (out, tmp_path / 'fresh'):  # no record of a campaign: nothing can be kept
        if folder.exists():
            (folder / resume.ARGS_FILE).unlink()
            traces = {p.name: p.stat().st_ino for p in (folder / 'traces').iterdir()}
        result = _run(folder, '--resume', args=args)
        assert result.returncode == 0, result.stderr[-3000:]
        assert ('campaign: --resume: %s holds no record of a campaign (%s): nothing is kept, '
                'every trial runs' % (folder, resume.ARGS_FILE)) in result.stderr
        assert '0 kept from the stopped campaign' in result.stderr
        assert all(p.stat().st_ino != traces.get(p.name) for p in (folder / 'traces').iterdir())
        _same_outputs(folder, source)


def test_resume_leaves_out_rows_without_their_trace_or_with_an_error(tmp_path, small):
    """A trial whose row has an error, or whose trace is missing, runs again."""
    source, args = small
    out = tmp_path / 'small'
    assert _run(out, args=args).returncode == 0
    with open(out / 'trials.csv', newline='') as handle:
        rows = list(csv.DictReader(handle))
    rows[0]['error'] = 'trial_engine: something failed'
    with open(out / 'trials.csv', 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out / 'traces' / (rows[1]['trial_id'] + '.json')).unlink()
    result = _run(out, '--resume', args=args)
    assert result.returncode == 0, result.stderr[-3000:]
    assert '1 kept from the stopped campaign (--resume)' in result.stderr
    _same_outputs(out, source)


# --- one campaign per folder --------------------------------------------------------------------

def test_a_second_campaign_in_a_running_ones_folder_exits_at_once_naming_it(tmp_path,
                                                                           reference):
    """While a campaign runs, another one into its folder (even with --resume) is exit 2 at once,
    naming the folder and the running one's pid, and writes nothing there. The lock dies with
    its process: after a SIGKILL, --resume takes the folder and finishes the campaign."""
    out = tmp_path / 'out'
    process = _start(out)
    _wait_for_rows(process, out, 1)
    # Held where it is (its whole process group stopped): however slow the machine, it cannot
    # finish, and so give up its folder, while the second campaigns try.
    os.killpg(process.pid, signal.SIGSTOP)
    for extra in ([], ['--resume']):
        began = time.monotonic()
        result = _run(out, *extra)
        took = time.monotonic() - began
        assert result.returncode == 2, result.stderr[-3000:]
        assert ('campaign: %s is being written by another campaign (pid %d)'
                % (out, process.pid)) in result.stderr
        assert took < 30.0, 'not at once: %.1f s' % took
        assert 'trials (full design)' not in result.stderr, 'it started its trials'
    assert process.poll() is None, 'the first campaign was disturbed'
    os.killpg(process.pid, signal.SIGKILL)
    assert process.wait(timeout=60) == -9
    result = _run(out, '--resume')
    assert result.returncode == 0, result.stderr[-3000:]
    _same_outputs(out, reference)


def test_the_folder_lock_is_held_once_and_released_with_its_holder(tmp_path):
    with resume.FolderLock(str(tmp_path)):
        with pytest.raises(resume.Refused) as refused:
            with resume.FolderLock(str(tmp_path)):
                pass
        assert str(refused.value).startswith(
            '%s is being written by another campaign (pid %d)' % (tmp_path, os.getpid()))
    with resume.FolderLock(str(tmp_path)):
        pass
    # A holder killed with SIGKILL: the kernel releases its lock; the pid it wrote is stale.
    holder = subprocess.Popen(['/usr/bin/python3', '-c', 'import sys, time\n'
                               'from pd_campaign import resume\n'
                               'with resume.FolderLock(sys.argv[1]):\n'
                               '    print("held", flush=True)\n'
                               '    time.sleep(600)\n', str(tmp_path)],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline() == 'held\n'
    with pytest.raises(resume.Refused, match=r'\(pid %d\)' % holder.pid):
        with resume.FolderLock(str(tmp_path)):
            pass
    holder.kill()
    holder.wait()
    holder.stdout.close()
    with resume.FolderLock(str(tmp_path)):
        assert (tmp_path / resume.LOCK_FILE).read_text() == '%d\n' % os.getpid()


# --- outputs that cannot be written ------------------------------------------------------------

# 6 trials on one worker (they finish in design order), the identification taken from `small`.
FULL_ARGS = ['--engine', 'core', '--scenario', SCENARIO, '--case', 'all', '--rpm', '12000',
             '--trials', '2', '--jobs', '1', '--no-figures']


class DiskFull:
    """Makes this process's writes fail as a full disk does, from the `after`-th write of the
    output `name` in `out` on: an fsync of its temporary file (an atomic output), or with
    `live` an os.write of the live file itself (trials.csv while the campaign runs). That write
    and every later write or fsync under `out` fail with ENOSPC; a write that fails first
    writes half its bytes (a short write), as write(2) does when the space runs out."""

    def __init__(self, monkeypatch, out, name, after=1, live=False):
        self.out, self.name, self.left = os.path.realpath(str(out)) + os.sep, name, after
        self.live = live
        self.full = False
        self._write, self._fsync = os.write, os.fsync
        monkeypatch.setattr(os, 'write', self.write)
        monkeypatch.setattr(os, 'fsync', self.fsync)

    def _hits(self, fd, live):
        """False (not failing), 'first' (the first failing write) or True."""
        try:
            path = os.readlink('/proc/self/fd/%d' % fd)
        except OSError:
            return False
        if not path.startswith(self.out):
            return False
        if self.full:
            return True
        base = os.path.basename(path)
        if live != self.live or not (base == self.name if live else re.match(
                r'^\.%s\.tmp' % re.escape(self.name), base)):
            return False
        self.left -= 1
        self.full = self.left <= 0
        return self.full and 'first'

    def write(self, fd, data):
        hit = self._hits(fd, live=True)
        if hit == 'first' and len(data) > 1:
            return self._write(fd, data[:len(data) // 2])
        if hit:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self._write(fd, data)

    def fsync(self, fd):
        if self._hits(fd, live=False):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self._fsync(fd)


def _campaign_in_process(argv):
    """cli.run_campaign(argv) in a thread of this process (the fault injected here reaches it);
    its exit status."""
    result = {}
    run = threading.Thread(target=lambda: result.update(status=cli.run_campaign(argv)),
                           daemon=True)
    run.start()
    run.join(timeout=DEADLINE_S)
    assert not run.is_alive(), 'the campaign hangs'
    return result.get('status')


@pytest.fixture(scope='module')
def full_disk_folders(tmp_path_factory, small):
    """An earlier campaign's folder (seed 71) and the reference run of seed 72."""
    root = tmp_path_factory.mktemp('full_disk')
    ident = ['--identification', str(small[0] / 'identification')]
    for name, seed in (('earlier', '71'), ('reference', '72')):
        result = _run(root / name, *ident, '--seed', seed, args=FULL_ARGS)
        assert result.returncode == 0, result.stderr[-3000:]
    return root, ident


def _whole_rows(path):
    """trials.csv's rows, each line checked whole (its line ending, every column)."""
    with open(path, newline='') as handle:
        text = handle.read()
    assert text.endswith('\r\n'), 'a cut line at the end'
    rows = list(csv.DictReader(text.splitlines(keepends=True)))
    assert all(None not in row and None not in row.values() for row in rows), 'a cut line'
    return rows


@pytest.mark.parametrize('name, after, rows_kept', [
    ('design.json', 1, None),  # before any trial: the earlier campaign's files all stay
    ('stationary-12000-001.json', 1, 3),  # a trace: the trials before it stay in trials.csv
    ('trials.csv', 4, 3),  # the live trials.csv: its 4th trial's line
    ('summary.json', 1, 6),  # at the end: trials.csv is the new one, the summary the earlier
    ('report.md', 1, 6),
])
def test_an_output_that_cannot_be_written_stops_the_campaign_with_one_line_naming_it(
        tmp_path, monkeypatch, capsys, full_disk_folders, name, after, rows_kept):
    """A full disk (ENOSPC from write or fsync) while the campaign writes `name`: exit 1, one
    line naming the file, no traceback, no temporary file; the files written before are intact
    (the earlier campaign's summary and report, the whole lines of the trials finished before:
    each the uninterrupted run's row); no mark of a finished campaign. --resume then finishes
    it: the outputs of the uninterrupted run."""
    root, ident = full_disk_folders
    out = tmp_path / 'out'
    shutil.copytree(str(root / 'earlier'), str(out))
    earlier = _snapshot(out)
    folder = out / 'traces' if name.endswith('001.json') else out
    DiskFull(monkeypatch, folder, name, after, live=name == 'trials.csv')
    status = _campaign_in_process(FULL_ARGS + ident + ['--seed', '72', '--out', str(out)])
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert status == 1, err[-3000:]
    assert 'Traceback' not in err and 'Exception in thread' not in err, err[-3000:]
    last = err.strip().splitlines()[-1]
    assert last == ('campaign: stopped: %s: No space left on device (the files written before '
                    'it are kept; --resume continues)' % (folder / name)), last
    assert not _temporaries(out)
    assert not (out / reuse.SOURCE_FILE).exists()
    now = _snapshot(out)
    assert now['report.md'] == earlier['report.md']
    if name != 'report.md':
        assert now['summary.json'] == earlier['summary.json']
    if rows_kept is None:
        assert now['trials.csv'] == earlier['trials.csv']
    else:
        rows = _whole_rows(out / 'trials.csv')
        assert len(rows) == rows_kept, [r['trial_id'] for r in rows]
        with open(root / 'reference' / 'trials.csv', newline='') as handle:
            expected = {r['trial_id']: r for r in csv.DictReader(handle)}
        assert all(row == expected[row['trial_id']] for row in rows)
    status = _campaign_in_process(FULL_ARGS + ident + ['--seed', '72', '--resume',
                                                       '--out', str(out)])
    assert status == 0, capsys.readouterr().err[-3000:]
    _same_outputs(out, root / 'reference')


def test_a_real_write_failure_in_the_command_is_one_line_without_traceback(tmp_path,
                                                                            full_disk_folders):
    """The campaign command under a file size limit (RLIMIT_FSIZE, no root needed: the kernel
    fails a write past it with EFBIG, "File too large") smaller than its larger outputs: exit 1
    with one line naming the file that did not fit, no traceback, no temporary file, and
    trials.csv whole."""
    root, ident = full_disk_folders
    out = tmp_path / 'out'

    def limited():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of the signal
        resource.setrlimit(resource.RLIMIT_FSIZE, (4500, 4500))

    result = subprocess.run(['/usr/bin/python3', CAMPAIGN] + FULL_ARGS + ident +
                            ['--seed', '72', '--out', str(out)], capture_output=True, text=True,
                            timeout=DEADLINE_S, preexec_fn=limited)
    assert result.returncode == 1, result.stderr[-3000:]
    assert 'Traceback' not in result.stderr, result.stderr[-3000:]
    last = result.stderr.strip().splitlines()[-1]
    assert re.match(r'^campaign: stopped: %s/[^ ]+: File too large \(the files written before '
                    r'it are kept; --resume continues\)$' % re.escape(str(out)), last), last
    assert _whole_rows(out / 'trials.csv') is not None
    assert not _temporaries(out)
