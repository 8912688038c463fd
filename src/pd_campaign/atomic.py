"""Output files written whole or not at all, as core::AtomicFile does for the C++ tools.

Every file a script keeps (trials.csv, summary.json, report.md, design.json, traces, figures,
tables, bags) is written to a temporary file in the destination's own folder
(`.<name>.tmpXXXXXXXX`), flushed to disk and renamed over the destination (os.replace is atomic
within a file system). An exception, Ctrl-C or a crash midway leaves the previous file, or
none, and no temporary file (the temporary file is removed; only a SIGKILL leaves one, hidden).
A write that fails (a full disk, a quota, an I/O error: any OSError of the temporary file, of
its writer when it names no file, or of the rename) raises that OSError with the destination as
its filename, as core::AtomicFile names it: a caller reports "PATH: No space left on device",
never the temporary file's name.
test_atomic_outputs.py checks that the scripts open no output file for writing any other way.
"""
import contextlib
import os
import re
import tempfile

# The mode of a finished file, as core::AtomicFile gives it.
FILE_MODE = 0o644
# A temporary file's name: .<name>.tmp and mkstemp's 8 characters (core::AtomicFile: 6).
_TEMPORARY = re.compile(r'^\..+\.tmp[A-Za-z0-9_]{6,8}$')


def _remove(path):
    try:
        os.remove(path)
    except FileNotFoundError:
        pass


@contextlib.contextmanager
def atomic_path(path):
    """A temporary path beside `path`, for writers that open the file themselves (rosbag,
    shutil.copyfile). Renamed to `path` when the block ends normally; removed when it raises.
    The writer must have closed the file when the block ends."""
    directory, name = os.path.split(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix='.%s.tmp' % name, dir=directory)
    except OSError as error:
        raise named(error, path, error.filename)
    try:
        os.fchmod(fd, FILE_MODE)
        os.close(fd)
        fd = -1
        yield tmp
        with open(tmp, 'rb') as handle:  # what the writer wrote reaches the disk first
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as error:
        if fd >= 0:
            os.close(fd)
        _remove(tmp)
        if isinstance(error, OSError):
            raise named(error, path, tmp)
        raise


def remove_temporaries(folder):
    """Removes the temporary files (this module's and core::AtomicFile's) that writers killed
    with SIGKILL left in `folder`; for a folder no other writer is writing (its campaign's
    lock held)."""
    for name in os.listdir(folder):
        if _TEMPORARY.match(name):
            _remove(os.path.join(folder, name))


def named(error, path, tmp=None):
    """`error`, an OSError met writing the output `path` (through its temporary file `tmp`),
    naming `path`; an error that names another file (a copy's source) is left as it is."""
    if error.filename is None or (tmp is not None and tmp in (error.filename, error.filename2)):
        error.filename, error.filename2 = path, None
    return error


@contextlib.contextmanager
def atomic_write(path, mode='w', **kwargs):
    """open(path, mode, **kwargs) for writing, all or nothing: the handle writes to a temporary
    file that replaces `path` when the block ends normally."""
    if 'w' not in mode:
        raise ValueError('atomic_write writes a whole new file: mode %r has no w' % mode)
    with atomic_path(path) as tmp:
        with open(tmp, mode, **kwargs) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())


def atomic_savefig(fig, path, **kwargs):
    """fig.savefig(path, **kwargs), all or nothing. The format is the one of `path`'s extension
    unless `format` is given (the temporary file's name has none)."""
    kwargs.setdefault('format', os.path.splitext(path)[1].lstrip('.').lower() or None)
    with atomic_write(path, 'wb') as handle:
        fig.savefig(handle, **kwargs)
