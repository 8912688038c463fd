#!/usr/bin/env python3
"""Runs the rostest scenarios in parallel lanes, each lane on an X display of its own.

Every scenario starts its own ROS master on a free port (rostest's default), so scenarios do not
share a graph; the rviz scenarios take screenshots of the whole display, so each lane runs its
scenarios one after another on a private Xvfb (started with -displayfd: the server picks a free
display number itself, no race between lanes). Scenarios are handed out longest first: by the
durations the previous run wrote (LOGS/rostest_seconds.tsv), else by their declared time-limit.
The wall-clock scenarios (the simulator without lockstep, as the lab's hardware runs: their
timeouts and controller checks see every scheduling gap of the machine) run alone, one after
another, when the others have finished: no other scenario runs beside them, as when every
scenario ran on its own.

Prints "ok NAME (N s)" or "FAILED NAME (N s), log: PATH" with the log's failure lines, as
run_tests.sh prints the other tiers; a scenario that leaves no result file gets a failing
JUnit file, so that summarize_test_results.py counts it.
"""

import argparse
import glob
import os
import re
import subprocess
import sys
import threading
import time

from pd_campaign.atomic import atomic_write

# A python test's failure lines, and the lines rostest and gtest print on a failure.
FAILURE_LINE = re.compile(r'FAIL|Error|error|Traceback|assert|Assertion|not true')
SCENARIO_TIMEOUT_S = 900
# The folders of .test files, relative to the checkout: every one is run.
SCENARIO_FOLDERS = ('test/rostest', 'test/rostest_gtest')


def declared_limit(path):
    """The largest time-limit of a scenario's <test> elements (rostest's default 60 s)."""
    with open(path, encoding='utf-8') as handle:
        limits = [float(value) for value in re.findall(r'time-limit="([0-9.]+)"', handle.read())]
    return max(limits, default=60.0)


def runs_on_wall_clock(path):
    """Whether a scenario runs the simulator without lockstep (on the wall clock)."""
    with open(path, encoding='utf-8') as handle:
        return re.search(r'name="lockstep"\s+value="false"', handle.read()) is not None


class Scenarios:
    """The scenarios still to run, longest first: the wall-clock ones alone, after the others."""

    def __init__(self, wall_clock, other):
        self._wall_clock = list(wall_clock)
        self._other = list(other)
        self._wall_clock_running = False
        self._others_running = 0
        self._changed = threading.Condition()

    def take(self):
        """The next scenario for a free lane: (name, whether it runs on the wall clock), or None
        when none is left. A lane that finds only wall-clock scenarios left waits until no other
        scenario runs."""
        with self._changed:
            while True:
                if self._other:
                    self._others_running += 1
                    return self._other.pop(0), False
                if (self._wall_clock and not self._wall_clock_running and
                        self._others_running == 0):
                    self._wall_clock_running = True
                    return self._wall_clock.pop(0), True
                if not self._wall_clock and not self._other:
                    return None
                self._changed.wait()

    def done(self, wall_clock):
        """A lane finished a scenario taken from take()."""
        with self._changed:
            if wall_clock:
                self._wall_clock_running = False
            else:
                self._others_running -= 1
            self._changed.notify_all()


def previous_seconds(path):
    """Scenario name -> seconds of the previous run, from the durations file (empty if none)."""
    seconds = {}
    try:
        with open(path, encoding='utf-8') as handle:
            for line in handle:
                name, _, value = line.strip().partition('\t')
                try:
                    seconds[name] = float(value)
                except ValueError:
                    continue
    except OSError:
        pass
    return seconds


def start_display():
    """Starts a private Xvfb and returns (process, display string)."""
    read_end, write_end = os.pipe()
    server = subprocess.Popen(
        ['Xvfb', '-displayfd', str(write_end), '-screen', '0', '1280x1024x24', '-nolisten', 'tcp'],
        pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    with os.fdopen(read_end) as reader:  # not atomic: reads the display number
        number = reader.readline().strip()
    if not number.isdigit():
        server.kill()
        raise RuntimeError('Xvfb did not report a display number')
    return server, ':' + number


def failure_excerpt(log_path):
    """The lines of a failed scenario's log worth printing, each cut to 300 characters."""
    try:
        with open(log_path, encoding='utf-8', errors='replace') as handle:
            lines = handle.read().splitlines()
    except OSError:
        return []
    picked = [line[:300] for line in lines if FAILURE_LINE.search(line)][:20]
    # A python test's failure message and the lines it adds.
    for index, line in enumerate(lines):
        if line.startswith('AssertionError'):
            picked.extend(text[:300] for text in lines[index:index + 5])
            break
    return picked


def crash_result(results_dir, name, status):
    """A failing JUnit file for a scenario that wrote none (crashed, timed out)."""
    path = os.path.join(results_dir, 'rostest-%s-crash.xml' % name)
    with atomic_write(path) as handle:
        handle.write('<testsuite name="%s" tests="1" failures="1"><testcase classname="rostest" '
                     'name="%s"><failure message="rostest exit %s"/></testcase></testsuite>\n'
                     % (name, name, status))


def run_lane(jobs, args, printer, durations):
    """Runs scenarios taken from `jobs` one after another on this lane's own display."""
    try:
        server, display = start_display()
    except (OSError, RuntimeError) as error:
        printer('  lane not started: %s' % error)
        return
    env = dict(os.environ, DISPLAY=display)
    results_dir = os.path.join(args.results_base_dir, 'pedicle_drilling')
    try:
        while True:
            taken = jobs.take()
            if taken is None:
                return
            name, wall_clock = taken
            log_path = os.path.join(args.logs, 'rostest_%s.log' % name)
            start = time.monotonic()
            with open(log_path, 'w', encoding='utf-8') as log:  # not atomic: a live log
                status = subprocess.call(
                    ['timeout', str(SCENARIO_TIMEOUT_S), 'rostest',
                     '--results-filename', 'rostest_%s.xml' % name,
                     '--results-base-dir', args.results_base_dir,
                     'pedicle_drilling', name + '.test'],
                    stdout=log, stderr=subprocess.STDOUT, env=env)
            seconds = time.monotonic() - start
            jobs.done(wall_clock)
            durations[name] = seconds
            if status == 0:
                printer('  ok     %s (%d s)' % (name, seconds))
                continue
            lines = ['  FAILED %s (%d s), log: %s' % (name, seconds, log_path)]
            lines.extend(failure_excerpt(log_path))
            printer('\n'.join(lines))
            # rostest's own result file (rostest-<results-filename>); a glob on the name would
            # also find another scenario's (ft_zero_service in ft_zero_service_missing).
            if not os.path.exists(os.path.join(results_dir, 'rostest-rostest_%s.xml' % name)):
                crash_result(results_dir, name, status)
    finally:
        server.terminate()
        server.wait()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--root', required=True, help='the package checkout')
    parser.add_argument('--results-base-dir', required=True)
    parser.add_argument('--logs', required=True)
    parser.add_argument('--filter', default='', help='only scenarios whose name has this')
    parser.add_argument('--jobs', type=int, default=2, help='lanes run at once (at least 1)')
    args = parser.parse_args()
    os.makedirs(args.logs, exist_ok=True)
    os.makedirs(os.path.join(args.results_base_dir, 'pedicle_drilling'), exist_ok=True)
    if args.jobs < 1:
        parser.error('--jobs must be at least 1, got %d' % args.jobs)
    scenarios = sorted(path for folder in SCENARIO_FOLDERS
                       for path in glob.glob(os.path.join(args.root, folder, '*.test')))
    names = {os.path.basename(path)[:-len('.test')]: path for path in scenarios}
    names = {name: path for name, path in names.items() if args.filter in name}
    seconds_path = os.path.join(args.logs, 'rostest_seconds.tsv')
    previous = previous_seconds(seconds_path)
    order = sorted(names, key=lambda name: (-previous.get(name, declared_limit(names[name])), name))
    wall_clock = {name for name in order if runs_on_wall_clock(names[name])}
    jobs = Scenarios([name for name in order if name in wall_clock],
                     [name for name in order if name not in wall_clock])
    lock = threading.Lock()

    def printer(text):
        with lock:
            print(text, flush=True)

    durations = {}
    lanes = [threading.Thread(target=run_lane, args=(jobs, args, printer, durations))
             for _ in range(min(args.jobs, max(len(order), 1)))]
    start = time.monotonic()
    for lane in lanes:
        lane.start()
    for lane in lanes:
        lane.join()
    results_dir = os.path.join(args.results_base_dir, 'pedicle_drilling')
    for name in order:
        if name not in durations:  # no lane started its display, or a lane failed (above)
            print('  FAILED %s: not run (no lane could run it; see above)' % name, flush=True)
            crash_result(results_dir, name, 'not run')
    previous.update(durations)
    with atomic_write(seconds_path) as handle:
        for name in sorted(previous):
            handle.write('%s\t%.1f\n' % (name, previous[name]))
    print('  %d scenarios on %d lanes in %d s' % (len(durations), len(lanes),
                                                   time.monotonic() - start))
    return 0


if __name__ == '__main__':
    sys.exit(main())
