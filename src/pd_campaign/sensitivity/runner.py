"""Running the sweep's campaigns: each bench's campaign forked from the campaign server, a finished
one of the same build kept, up to --jobs at once, the Table II identification once."""
import collections
import json
import os
import signal
import threading
import time

from .. import campaign_process, tools, trials_csv
from ..atomic import atomic_write
from ..identification import identify
from ..progress import clock
from .sweep import TOOL, SweepError, label, scenario_text

# --- running the sub-campaigns -------------------------------------------------------------------

def is_complete(directory, text, expected):
    """Whether `directory` holds the finished campaign of this scenario text and design: the same
    scenario.yaml, a design.json whose meta has the `expected` values, every trial of the design
    in trials.csv, and its summary.json."""
    try:
        with open(os.path.join(directory, 'scenario.yaml')) as handle:
            if handle.read() != text:
                return False
        with open(os.path.join(directory, 'design.json')) as handle:
            meta = json.load(handle)['meta']
        if any(meta.get(key) != value for key, value in expected.items()):
            return False
        rows = trials_csv.read_trials_csv(os.path.join(directory, 'trials.csv'))
        return os.path.isfile(os.path.join(directory, 'summary.json')) \
            and len(rows) == meta['design_size']
    except (OSError, ValueError, KeyError, TypeError):
        return False


# The sweep's running campaigns (run_campaign_process), so that a stop of the sweep reaches them.
_RUNNING = set()
_RUNNING_LOCK = threading.Lock()
STOP_GRACE_S = 10.0  # a campaign's own Ctrl-C handling, before the sweep sends it SIGINT


def run_campaign_process(argv, log_path):
    """Runs the campaign with `argv`, its output to `log_path`; its exit status. A campaign
    stopped by SIGINT (Ctrl-C reaches the whole process group; stop_running() sends it to the
    campaigns when only the sweep got it) stops its own workers and keeps its finished trials
    (exit 130). The campaign is forked from a server that imported its modules once
    (campaign_process)."""
    with open(log_path, 'w'):  # not atomic: the sub-campaign's live log, written by it
        pass
    process = campaign_process.CampaignProcess(argv, log_path)
    with _RUNNING_LOCK:
        _RUNNING.add(process)
    try:
        return process.wait()
    finally:
        with _RUNNING_LOCK:
            _RUNNING.discard(process)


def stop_running(futures):
    """Stops the sweep's running campaigns: each gets STOP_GRACE_S to end by itself (a Ctrl-C on
    the terminal reached it too), then SIGINT; waits for `futures` (their threads) to end."""
    import concurrent.futures
    _, still = concurrent.futures.wait(futures, timeout=STOP_GRACE_S)
    if still:
        with _RUNNING_LOCK:
            running = list(_RUNNING)
        for process in running:
            try:
                process.send_signal(signal.SIGINT)
            except ProcessLookupError:
                pass
        concurrent.futures.wait(still)


BUILD_FILE = 'build.json'


def built_by(directory):
    """The build_id() a finished campaign in `directory` was run by (None: unknown)."""
    try:
        with open(os.path.join(directory, BUILD_FILE)) as handle:
            return json.load(handle).get('build_id')
    except (OSError, ValueError, AttributeError):
        return None


def is_kept(condition, expected, base_path, build):
    """A bench whose directory holds its finished campaign already, run by the same build
    (`build`, tools.build_id(); None: never kept)."""
    directory = condition['dir']
    return build is not None and built_by(directory) == build and \
        is_complete(directory, scenario_text(condition, base_path), expected)


def run_condition(condition, argv, expected, base_path, build=None):
    """('kept' | 'ran', exit status) of one bench: kept when is_kept(), else run into its
    directory."""
    if is_kept(condition, expected, base_path, build):
        return 'kept', 0
    directory = condition['dir']
    text = scenario_text(condition, base_path)
    os.makedirs(directory, exist_ok=True)
    stamp = os.path.join(directory, BUILD_FILE)
    if os.path.exists(stamp):
        os.remove(stamp)  # the campaign about to run is not the one it described
    path = os.path.join(directory, 'scenario.yaml')
    with atomic_write(path) as handle:
        handle.write(text)
    status = run_campaign_process(argv + ['--scenario', path, '--out', directory],
                                  os.path.join(directory, 'campaign.log'))
    if status == 0 and build is not None:
        with atomic_write(stamp) as handle:
            json.dump({'build_id': build}, handle)
    return 'ran', status


def _log_tail(directory, lines=5):
    try:
        with open(os.path.join(directory, 'campaign.log')) as handle:
            return ''.join(handle.readlines()[-lines:])
    except OSError:
        return ''


def run_all(benches, argv, expected, base_path, stream, jobs=1, out=None):
    """Runs every bench that needs a campaign, up to `jobs` campaigns at once (each one
    trial_engine process: a trial depends on its seed only, so the campaigns' trials do not
    depend on it), one line on `stream` per finished one; {id: status} (0 for a kept one). The
    Table II identification runs once, into `out` (None: each campaign identifies itself). Stops
    starting campaigns at the first that refuses its scenario (2), lets the running ones finish,
    then raises SweepError."""
    import concurrent.futures
    todo = [c for c in benches if c['scenario'] is not None]
    statuses, start, ran = {}, time.time(), 0
    build = tools.build_id()
    pending = [c for c in todo if not is_kept(c, expected, base_path, build)]
    if pending and out is not None:
        argv = argv + ['--identification', identify(out, jobs), '--no-figures']
    refused = None

    def one(condition):
        began = time.time()
        how, status = run_condition(condition, argv, expected, base_path, build)
        return condition, how, status, time.time() - began

    waiting = collections.deque(todo)
    running = set()
    done_count = 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        try:
            while waiting or running:
                # At most `jobs` campaigns at a time; none starts after a refusal.
                while waiting and len(running) < max(1, jobs) and refused is None:
                    running.add(pool.submit(one, waiting.popleft()))
                if not running:
                    break
                finished, running = concurrent.futures.wait(
                    running, return_when=concurrent.futures.FIRST_COMPLETED)
                for future in finished:
                    condition, how, status, took = future.result()
                    done_count += 1
                    statuses[condition['id']] = status
                    ran += how == 'ran'
                    elapsed = time.time() - start
                    eta = elapsed / ran * (len(todo) - done_count) if ran else 0
                    what = ('finished in %s (exit %d)' % (clock(took), status)
                            if how == 'ran' else 'complete already, kept')
                    stream.write('%s: [%d/%d] %s: %s; elapsed %s, ETA %s\n' % (
                        condition.get('tool', TOOL), done_count, len(todo), label(condition),
                        what, clock(elapsed), clock(eta)))
                    stream.flush()
                    if status == 130:
                        raise KeyboardInterrupt()
                    if status == 2 and refused is None:
                        refused = condition  # the running ones finish; no new one starts
        except BaseException:
            # Ctrl-C, or anything else: the running campaigns keep their finished trials and
            # stop; none starts after.
            stop_running(running)
            raise
    if refused is not None:
        raise SweepError('the campaign refused %s (%s):\n%s' % (
            label(refused), refused['dir'], _log_tail(refused['dir'])))
    return statuses


def read_results(benches):
    """{bench id: its fault-free trial rows}; an end equal to the nominal value gets the
    nominal's rows."""
    out = {}
    for condition in benches:
        rows = trials_csv.read_trials_csv(os.path.join(condition['dir'], 'trials.csv'))
        out[condition['id']] = [r for r in rows if (r.get('fault') or 'none') == 'none']
    return out
