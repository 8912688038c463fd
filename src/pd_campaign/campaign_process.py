"""A campaign run as a child process of a tool that runs many (campaign_sensitivity's benches,
the leaderboard's closed-loop campaigns), forked from one server process that imported the
campaign's modules once (multiprocessing's forkserver).

A campaign started as `campaign ...` spends about 0.4 s of CPU before and after its trials
importing the interpreter's and the report's modules (scipy.stats alone 0.25 s): a hundred
campaigns of a sweep paid it a hundred times. A child forked from the server starts with them
imported; it is still a process of its own (its own exit status, signals and output), running
the same `cli.run_campaign` with the same arguments, so its outputs are the same."""
import multiprocessing
import os
import signal
import sys

# Imported once by the server, before any campaign is forked from it; '__main__' (the tool's
# script, whose entry point is guarded) too, else each child would run it again to import it.
PRELOAD = ['__main__', 'pd_campaign.cli', 'pd_campaign.report', 'pd_campaign.engine_core',
           'scipy.stats']
_CONTEXT = None


def _context():
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = multiprocessing.get_context('forkserver')
        _CONTEXT.set_forkserver_preload(PRELOAD)
    return _CONTEXT


def _main(argv, log_path, python_path):
    """The child: its output appended to `log_path` (None: the tool's own), its PYTHONPATH the
    caller's when it started the child (the server's may be older: a submitted recognizer's
    folder is added to it at run time, pd_campaign.api.add_module), then the campaign."""
    if python_path is None:
        os.environ.pop('PYTHONPATH', None)
    else:
        os.environ['PYTHONPATH'] = python_path
    if log_path is not None:
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND
        handle = os.open(log_path, flags, 0o644)  # not atomic: the live log, appended to
        os.dup2(handle, 1)
        os.dup2(handle, 2)
        os.close(handle)
    # The forkserver's child ignores nothing the campaign handles: Ctrl-C stops it (exit 130).
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.argv = ['campaign'] + list(argv)  # argparse's messages name the campaign
    from pd_campaign import cli
    sys.exit(cli.run_campaign(list(argv)))


class CampaignProcess:
    """`campaign ARGV` as a child process, with Popen's wait() and send_signal(); its output
    appended to `log_path` (the caller creates or empties it), else the tool's own."""

    def __init__(self, argv, log_path=None):
        self._process = _context().Process(target=_main, args=(
            list(argv), log_path, os.environ.get('PYTHONPATH')))
        self._process.start()

    @property
    def pid(self):
        return self._process.pid

    def send_signal(self, number):
        if self._process.exitcode is not None:
            return  # ended and reaped: its pid may be another process's now
        try:
            os.kill(self._process.pid, number)
        except ProcessLookupError:
            pass

    def wait(self):
        """Its exit status (negative: the signal that ended it, as Popen's)."""
        self._process.join()
        return self._process.exitcode


def run(argv, log_path=None):
    """Runs `campaign ARGV` to its end; its exit status."""
    return CampaignProcess(argv, log_path).wait()
