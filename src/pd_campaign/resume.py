"""A campaign's output folder: written by one campaign at a time (LOCK_FILE), and continued by
`campaign --resume` (ARGS_FILE: what the campaign in it was started with).

The lock is an flock(2) on LOCK_FILE in the folder, held while the campaign runs: the kernel
releases it when the process ends, however it ends (a SIGKILL leaves no stale lock). The file
stays; it holds the pid of its last holder, for the message of a campaign that finds it taken.
It is never removed: a campaign that removed it could let two others hold locks on two files.

A campaign writes ARGS_FILE before its first trial: its design (the report's meta data, the
shard), its scenario by content, the options that change its outputs and its trials' engine
key (pd_campaign.reuse: the build, the package's files, the Table II models). A campaign
started without --resume removes it first (the folder no longer holds the campaign it
described). `--resume` refuses a folder whose ARGS_FILE differs, naming what differs; it keeps
the trials that reuse.finished() accepts from the folder's trials.csv and runs the others. A
folder without ARGS_FILE has nothing that can be checked: nothing is kept."""
import errno
import fcntl
import json
import os
import time

from . import reuse, trials_csv
from .atomic import atomic_write

LOCK_FILE = 'campaign.lock'
ARGS_FILE = 'campaign_args.json'
_VERSION = 1
_WHY = {'engine_key': 'another build, package files or Table II models: '}


class Refused(Exception):
    """The folder is another campaign's (locked), or not this campaign's to resume."""


def _holder(path, wait_s=1.0):
    """The pid in the lock file `path` of a process that holds it (a holder writes its pid just
    after taking the lock: read until a live one is there, for at most `wait_s`)."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            with open(path) as handle:
                pid = int(handle.read().strip() or 0)
            if pid > 0:
                os.kill(pid, 0)
                return str(pid)
        except PermissionError:  # another user's live process
            return str(pid)
        except (OSError, ValueError):
            pass
        if time.monotonic() > deadline:
            return 'unknown'
        time.sleep(0.01)


class FolderLock:
    """`with FolderLock(folder):` holds `folder`'s LOCK_FILE, or raises Refused at once naming
    the folder and the holder's pid."""

    def __init__(self, folder):
        self.folder = folder
        self._fd = -1

    def __enter__(self):
        path = os.path.join(self.folder, LOCK_FILE)
        # Not through a temporary file: the lock is on this one file, its content a pid.
        self._fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)  # not atomic: lock
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            self.__exit__()
            if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise
            raise Refused('%s is being written by another campaign (pid %s): two campaigns '
                          'cannot write one folder; wait for it, stop it, or give another '
                          '--out' % (self.folder, _holder(path)))
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, b'%d\n' % os.getpid(), 0)
        return self

    def __exit__(self, *exc):
        if self._fd >= 0:
            os.close(self._fd)  # releases the lock
            self._fd = -1


def forget(folder):
    """`folder` no longer holds the campaign its ARGS_FILE described (one is about to start)."""
    try:
        os.remove(os.path.join(folder, ARGS_FILE))
    except FileNotFoundError:
        pass


def record(folder, identity):
    """ARGS_FILE: what the campaign in `folder` is started with (`identity`, a JSON mapping)."""
    with atomic_write(os.path.join(folder, ARGS_FILE)) as handle:
        json.dump(dict(identity, version=_VERSION), handle, indent=1, sort_keys=True)


def _flat(value, prefix=''):
    """{dotted key: value} of nested mappings (lists are values)."""
    if not isinstance(value, dict):
        return {prefix: value}
    out = {}
    for key, item in value.items():
        out.update(_flat(item, '%s.%s' % (prefix, key) if prefix else str(key)))
    return out


def check(folder, identity, keys):
    """True when `folder` holds a campaign to resume whose recorded `keys` (of its ARGS_FILE)
    equal `identity`'s; raises Refused naming what differs. False without ARGS_FILE (no
    campaign, or one that stopped before its first trial, or of an earlier version): nothing
    in the folder can be checked, so nothing is kept and every trial runs."""
    path = os.path.join(folder, ARGS_FILE)
    try:
        with open(path) as handle:
            recorded = json.load(handle)
    except FileNotFoundError:
        return False
    except (OSError, ValueError) as error:
        raise Refused('--resume: %s: unreadable: %s' % (path, error))
    if recorded.get('version') != _VERSION:
        raise Refused('--resume: %s is of version %r, not %d' % (
            path, recorded.get('version'), _VERSION))
    mine = _flat({k: json.loads(json.dumps(identity.get(k))) for k in keys})
    theirs = _flat({k: recorded.get(k) for k in keys})
    differ = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
    if differ:
        raise Refused('--resume: %s was started with other arguments: %s%s; run without '
                      '--resume to start it again, or give another --out' % (
                          folder, '; '.join('%s%s %s there, %s here' % (
                              _WHY.get(k, ''), k, json.dumps(theirs.get(k)),
                              json.dumps(mine.get(k))) for k in differ[:4]),
                          ' (and %d more)' % (len(differ) - 4) if len(differ) > 4 else ''))
    return True


def kept(folder, trials, samples=False):
    """{trial_id: row} of the `trials` (design entries) that the campaign stopped in `folder`
    finished (reuse.finished: in its trials.csv, the line whole, without an error, with its
    trace; and with `samples`, with its samples file)."""
    path = os.path.join(folder, 'trials.csv')
    if not os.path.exists(path):
        return {}
    rows = reuse.finished(folder, reuse.entries(trials),
                          trials_csv.read_trials_csv(path, whole_lines=True))
    if samples:
        rows = [r for r in rows
                if os.path.isfile(os.path.join(folder, 'samples', r['trial_id'] + '.npy'))]
    found = {}
    for row in rows:
        found.setdefault(row['trial_id'], row)
    return found
