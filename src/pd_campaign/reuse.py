"""Trials a core-engine campaign takes from finished campaigns instead of running them again
(`campaign --reuse-trials ROOT`).

A core trial's record is a function of the trial (its id, case, speed, seed, fault) and of what
trial_engine runs it with: the build, the package's files it reads at run time (urdf/, config/,
the plugin manifests) and its options, the Table II models among them. `engine_key` digests all
of these but the trial, files by their content (not their path); two trials with equal keys and
equal trial entries have the same record, bit for bit (doc/experiments.md, "Reproducibility"),
so the same trials.csv row and trace. `make run` runs some trials twice without this: each
sensitivity sweep's nominal campaign repeats the first trials of a main campaign, and the speed
sweep repeats trials of the paper bench's sweep.

A finished campaign writes SOURCE_FILE (its key) after its report; a campaign in that folder
removes it first, so a folder with SOURCE_FILE holds a complete campaign of that key. A trial is
taken only without an error, with its trace present."""
import glob
import hashlib
import json
import os

from . import tools, trials_csv
from .atomic import atomic_write

SOURCE_FILE = 'trial_source.json'
# trial_engine options whose value is a file or a folder: digested by content (a folder: the
# files of that name pattern in it, the ones trial_engine reads)
_FILE_OPTIONS = {'--models-dir': 'volunteer_*.yaml', '--default-model': None, '--urdf': None}
# options that do not change a trial's record: the trials' source; a side output is refused
_DROPPED_OPTIONS = ('--trials',)
_PACKAGE_PATTERNS = ('urdf/**/*', 'config/**/*', '*_plugins.xml')
_VERSION = b'pedicle_drilling core trial record 1\0'


def _digest_path(digest, path, pattern='**/*'):
    """The content of a file, or of the files of `pattern` in a folder (sorted names)."""
    if os.path.isdir(path):
        names = sorted(os.path.relpath(p, path)
                       for p in glob.glob(os.path.join(glob.escape(path), pattern),
                                          recursive=True)
                       if os.path.isfile(p))
        for name in names:
            digest.update(b'F' + name.encode() + b'\0')
            _digest_path(digest, os.path.join(path, name))
        return
    tools.update_digest(digest, path)
    digest.update(b'\0')


def unkeyable(command, build):
    """Why a trial run by `command` cannot be keyed (None: it can): code outside the build
    (a Python class of another package, plugins of PEDICLE_DRILLING_PLUGIN_XML) or no build to
    identify (the tools found through rosrun only)."""
    if build is None:
        return 'the build is not identified (trial_engine found through rosrun only)'
    if os.environ.get('PEDICLE_DRILLING_PLUGIN_XML'):
        return 'PEDICLE_DRILLING_PLUGIN_XML adds plugins outside the build'
    for option, value in zip(command, command[1:]):
        if option in ('--recognizer', '--compensator') and value.startswith('python:') \
                and not value.startswith('python:pd_campaign.'):
            return '%s %s is Python code outside the build' % (option, value)
    return None


def engine_key(command, package_root, build=None):
    """Digest of what a trial's record depends on besides the trial: the build
    (tools.build_id(), or `build`), the package's run-time files under `package_root` and
    trial_engine's `command` (its executable, covered by the build, and `--trials` left out;
    file and folder options by content, and so is the file a NAME=VALUE names). None when
    unkeyable()."""
    build = build or tools.build_id()
    if unkeyable(command, build):
        return None
    digest = hashlib.sha256(_VERSION)
    digest.update(build.encode() + b'\0')
    files = sorted({os.path.relpath(p, package_root) for pattern in _PACKAGE_PATTERNS
                    for p in glob.glob(os.path.join(glob.escape(package_root), pattern),
                                       recursive=True)
                    if os.path.isfile(p)})
    for name in files:
        digest.update(b'P' + name.encode() + b'\0')
        _digest_path(digest, os.path.join(package_root, name))
    args = list(command[1:])
    k = 0
    while k < len(args):
        option = args[k]
        if option in _DROPPED_OPTIONS:
            k += 2
            continue
        digest.update(b'A' + option.encode() + b'\0')
        if option in _FILE_OPTIONS and k + 1 < len(args):
            _digest_path(digest, args[k + 1], _FILE_OPTIONS[option] or '**/*')
            k += 2
            continue
        value = option.partition('=')[2]
        if value and os.path.isfile(value):  # e.g. a learned recognizer's model=PATH
            _digest_path(digest, value)
        k += 1
    return digest.hexdigest()


def _trial_text(trial):
    return json.dumps(trial, sort_keys=True)


def unmark(out_dir):
    """`out_dir` no longer holds a finished campaign (one is about to run there)."""
    try:
        os.remove(os.path.join(out_dir, SOURCE_FILE))
    except FileNotFoundError:
        pass


def mark(out_dir, key):
    """`out_dir` holds a finished campaign whose trials were run with `key`."""
    with atomic_write(os.path.join(out_dir, SOURCE_FILE)) as handle:
        json.dump({'engine_key': key}, handle)


def sources(root, key, exclude=None):
    """Folders at most two levels below `root` (and `root`) holding a finished campaign of
    `key`, sorted; `exclude` (a campaign's own folder) left out."""
    found = []
    for depth in ('', '*', os.path.join('*', '*')):
        for path in glob.glob(os.path.join(glob.escape(root), depth, SOURCE_FILE)):
            folder = os.path.dirname(os.path.abspath(path))
            if exclude and os.path.abspath(exclude) == folder:
                continue
            try:
                with open(path) as handle:
                    if json.load(handle).get('engine_key') == key:
                        found.append(folder)
            except (OSError, ValueError, AttributeError):
                continue  # not a source (being written, or not ours)
    return sorted(set(found))


def _mark_of(folder):
    """The identity (inode, modification time) of `folder`'s SOURCE_FILE; None without one."""
    try:
        status = os.stat(os.path.join(folder, SOURCE_FILE))
    except FileNotFoundError:
        return None
    return status.st_ino, status.st_mtime_ns


def entries(trials):
    """{trial_id: entry text} of design entries, as finished() compares them."""
    return {t['trial_id']: _trial_text(t) for t in trials}


def finished(folder, wanted, rows):
    """The `rows` (of `folder`'s trials.csv) of the `wanted` trials (entries()) that the campaign
    in `folder` ran, with the same entry in its design.json, without an error and with its trace:
    the trials a campaign takes (--reuse-trials) or keeps (--resume) instead of running them."""
    with open(os.path.join(folder, 'design.json')) as handle:
        ran = entries(json.load(handle)['trials'])
    return [row for row in rows
            if wanted.get(row['trial_id']) is not None
            and ran.get(row['trial_id']) == wanted[row['trial_id']] and not row.get('error')
            and os.path.isfile(os.path.join(folder, 'traces', row['trial_id'] + '.json'))]


def _read_source(folder, wanted):
    """{trial_id: (row, trace bytes)} of the `wanted` trials {trial_id: entry text} that the
    campaign in `folder` ran without an error and with its trace."""
    found = {}
    rows = trials_csv.read_trials_csv(os.path.join(folder, 'trials.csv'))
    for row in finished(folder, wanted, rows):
        trial_id = row['trial_id']
        try:
            with open(os.path.join(folder, 'traces', trial_id + '.json'), 'rb') as handle:
                found[trial_id] = (row, handle.read())
        except FileNotFoundError:
            continue
    return found


def find(root, key, trials, exclude=None, unreadable=None):
    """{trial_id: (row, trace bytes)} of the `trials` (design entries) that a finished campaign
    of `key` under `root` ran without an error and with its trace. A folder in which another
    campaign starts while it is read (its SOURCE_FILE removed or replaced) gives nothing; one
    that stays marked but cannot be read gives nothing either, and is appended to `unreadable`
    (a list) as "folder: why"."""
    wanted = entries(trials)
    taken = {}
    for folder in sources(root, key, exclude):
        before = _mark_of(folder)
        try:
            found = _read_source(folder, wanted) if before is not None else {}
        except (OSError, ValueError, KeyError, TypeError) as error:
            if _mark_of(folder) == before and unreadable is not None:
                unreadable.append('%s: %s' % (folder, error))
            continue
        if _mark_of(folder) != before:
            continue
        for trial_id, value in found.items():
            taken.setdefault(trial_id, value)
    return taken


def take(trial_id, row, trace, out_dir):
    """The trial's trace (bytes) written into `out_dir`/traces (atomically); its row."""
    with atomic_write(os.path.join(out_dir, 'traces', trial_id + '.json'), 'wb') as handle:
        handle.write(trace)
    return row
