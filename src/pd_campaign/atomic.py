"""Output files written whole or not at all, as core::AtomicFile does for the C++ tools.

Every file a script keeps (trials.csv, summary.json, report.md, design.json, traces, figures,
tables, bags) is written to a temporary file in the destination's own folder
(`.<name>.tmpXXXXXXXX`), flushed to disk and renamed over the destination (os.replace is atomic
within a file system). An exception, Ctrl-C or a crash midway leaves the previous file, or
none, and no temporary file (the temporary file is removed; only a SIGKILL leaves one, hidden).
test_atomic_outputs.py checks that the scripts open no output file for writing any other way.
"""
import contextlib
import os
import tempfile

# The mode of a finished file, as core::AtomicFile gives it.
FILE_MODE = 0o644


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
    fd, tmp = tempfile.mkstemp(prefix='.%s.tmp' % name, dir=directory)
    try:
        os.fchmod(fd, FILE_MODE)
        os.close(fd)
        fd = -1
        yield tmp
        with open(tmp, 'rb') as handle:  # what the writer wrote reaches the disk first
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        if fd >= 0:
            os.close(fd)
        _remove(tmp)
        raise


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
