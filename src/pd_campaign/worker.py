"""A campaign worker: its own ROS master on its own port, the full nodelet pipeline in sim time,
and a sequence of trials. Prints one JSON line per finished trial on stdout (the parent collects
them), so nothing finished is lost if the campaign is interrupted.

Run by `campaign`; not meant to be started by hand (but can be, for debugging):
  /usr/bin/python3 -m pd_campaign.worker --port 11411 --trials trials.json --out DIR
"""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time

from pd_campaign import tools
from pd_campaign.atomic import atomic_write
from pd_campaign.analysis import analyse_trial
from pd_campaign.bags import check_bag, start_bag, stop_bag
from pd_campaign.recorder import TrialRecorder
from pd_campaign.worker_config import NODE_CONFIGS, launch_arguments, plugin_config

PIPELINE_SERVICES = {
    'reset': '/simulator/reset',
    'identify': '/motion_identification/identify',
    'start_trial': '/compensation_planner/start_trial',
    'resume': '/simulator/resume',
}


# Sim time between two trials' starts (time_zero); half of it between a trial's two resets (the
# bench's model-played motion). Each half is more than a reset can be from the next: the hold
# (pre_trial_s, at most 60 s, the simulator's bound; the identification window with online
# identification), a breath (60 s at 1 bpm), max_duration_s (at most 600 s) and the run-on after DONE until the
# worker's next reset. A time_zero the simulator is already past falls back to the next 0.1 s
# (a valid trial, reported on stderr).
TRIAL_SPACING_S = 2000


def time_zero(trial, second=False):
    """The sim time of the trial's time 0 (a whole number of seconds, so on the simulator's
    0.1 s grid): set by its place in the campaign's design, so that the ROS pipeline's nodes see
    the same stamps, and do the same arithmetic on them, in every run of the trial. A second
    reset of the trial (the bench's model-played motion) starts half a spacing later. None
    without a place: the simulator's default (the next 0.1 s)."""
    position = trial.get('design_position')
    if position is None:
        return None
    return (int(position) + 1) * TRIAL_SPACING_S + (TRIAL_SPACING_S // 2 if second else 0)


def run_trial(rospy, srv, msgs, recorder, trial, args, trace_dir):
    wall_start = time.time()
    zeros = (time_zero(trial), time_zero(trial, second=True))
    trial = dict(trial)
    trial.pop('design_position', None)
    row = dict(trial)
    row['engine'] = 'ros'
    recorder.clear()
    moving = trial['case'] != 'stationary'
    # The trial starts where the core engine starts the seed's trial: the simulator holds sim
    # time there (pre_trial_s after the reset, then a breath phase drawn from the seed) until
    # the planner has started it (simulator/resume below).
    reply = _reset(srv, trial, moving, args, zeros[0])
    recorder.clear(reply.reset_time.to_sec(), reply.trial_start.to_sec())
    row['inner_cortical_mm'] = reply.inner_cortical_thickness_m * 1e3
    row['volunteer_id'] = reply.volunteer_id
    row['amplitude_scale'] = reply.patient_amplitude_scale
    row['ventilator_rate_bpm'] = reply.ventilator_rate_bpm
    row['tidal_volume_ml'] = reply.ventilator_tidal_volume_ml
    row['force_noise_sd_n'] = reply.force_noise_sd_n
    row['arm_stiffness_scale'] = reply.arm_stiffness_scale
    # The recognizer and the safety monitor are reset by the planner's start_trial (the trial
    # sequence owns that); what the previous trial still had in transit is older than the reset.
    model_path = os.path.abspath(os.path.join(args.out, 'models', '%s.yaml' % trial['trial_id']))
    if moving and args.models_dir:
        # The simulator's virtual patient is one of the five virtual volunteers (the reset
        # reports which): use the model identified beforehand from that volunteer's own
        # spontaneous-breathing recording, as in the paper.
        model_path = os.path.join(args.models_dir, 'volunteer_%d_%s.yaml'
                                  % (reply.volunteer_id, args.model))
        if not os.path.exists(model_path):
            raise RuntimeError('no identified model %s' % model_path)
    elif moving:
        # Record breathing for the identification window (sim time: the hold is after it),
        # then identify.
        _wait_sim_until(recorder, reply.trial_start.to_sec())
        ident = srv['identify'](model=args.model, method='ceres', output_path=model_path)
        if not ident.success:
            raise RuntimeError('identification failed: %s' % ident.message)
        ap = [a for a in ident.model.axes if a.axis == 'AP']
        row['identification_r2_ap'] = ap[0].r2 if ap else None
    else:
        model_path = args.default_model
    rospy.set_param('/compensation_planner/patient_model_path', model_path)
    if moving and args.bone_motion == 'model':
        # The paper's bench protocol (Algorithm 1: "SPMS and RSSSII do move"): the SPMS plays
        # the displacement the patient's model predicts. The same seed draws the same trial
        # again; only what the bone plays changes.
        rospy.set_param('/simulator/bone_motion_model_path', model_path)
        try:
            reply = _reset(srv, trial, moving, args, zeros[1])
        finally:
            rospy.set_param('/simulator/bone_motion_model_path', '')
        recorder.clear(reply.reset_time.to_sec(), reply.trial_start.to_sec())
    bag = start_bag(args, trial) if args.bags else None
    try:
        try:
            reply = srv['start_trial'](mode=trial['case'], spindle_rpm=trial['rpm'],
                                       feed_rate_mm_s=args.feed_rate,
                                       max_duration_s=args.max_duration)
        finally:
            srv['resume']()  # started or refused, sim time runs on
        if not reply.success:
            raise RuntimeError('start_trial failed: %s' % reply.message)
        row = finish_trial(recorder, row, trial, args, trace_dir, wall_start)
    finally:
        if bag is not None:
            stop_bag(bag)
    if bag is not None:
        # A kept recording says what it lost: <trial>.bag.json beside it, and the row.
        bag_path = os.path.join(args.out, 'bags', trial['trial_id'] + '.bag')
        try:
            check = check_bag(bag_path)
        except Exception as error:  # a bag the recorder did not close (killed) or cannot read
            check = {'bag': os.path.basename(bag_path), 'complete': False,
                     'summary': 'unreadable bag: %s' % ' '.join(str(error).split())}
        with atomic_write(bag_path + '.json') as handle:
            json.dump(check, handle, indent=1)
        row['bag_lost'] = check['summary'] if check['summary'] else 'nothing'
    return row


def _wait_until(predicate, bound_s, period_s=0.01, what=None):
    """Polls predicate() until it holds (True) or `bound_s` of wall time passed (False): the
    bound only keeps a dead node from hanging the worker. A wait named `what` that took over
    5 s of wall time, or ran out, is reported on stderr (the campaign's log)."""
    start = time.time()
    deadline = start + bound_s
    held = True
    while not predicate():
        if time.time() >= deadline:
            held = False
            break
        time.sleep(period_s)
    if what and (not held or time.time() - start > 5.0):
        sys.stderr.write('campaign worker: waited %.1f s for %s%s\n'
                         % (time.time() - start, what, '' if held else ' (gave up)'))
    return held


def finish_trial(recorder, row, trial, args, trace_dir, wall_start):
    from pedicle_drilling.msg import TrialStatus  # ROS engine only
    if not _wait_until(lambda: recorder.phase in (TrialStatus.DONE, TrialStatus.FAILED),
                       args.trial_timeout, 0.02, 'the trial to end'):
        raise RuntimeError('trial did not finish within %.0f s wall (status: %s)' % (
            args.trial_timeout, recorder.status[-1][1] if recorder.status else 'none'))
    if recorder.phase == TrialStatus.FAILED:
        raise RuntimeError('the planner failed the trial (statuses: %s)'
                           % ' '.join(s for _, s in recorder.status))
    # The monitor checks the sensor's tare when it hears the retreat end: wait for its result
    # (an event; the bound only keeps a trial whose monitor is gone from hanging).
    t_done = recorder.status_time('done')

    def fresh():
        return (recorder.retare is not None and t_done is not None
                and recorder.retare['t'] >= t_done - 1e-3)
    if not _wait_until(fresh, 5.0, what='the re-tare check'):
        recorder.retare = None  # none for this trial (a previous trial's, latched, is not it)
    # The monitor's diagnostics at the trial's end (its input streams, complete): the status it
    # published when it heard the trial end (an event: trial_running turns false; the stamp is
    # the monitor's ROS time, the latest /clock, which can trail DONE by a clock period).
    _wait_until(lambda: recorder.trial_end_inputs() is not None, 5.0,
                what="the monitor's status at the trial's end")
    # Each topic has its own connection: on a loaded machine the ground truth and the
    # recognizer's states may trail the status that said DONE. Wait until both have reached the
    # trial's end (events: the simulator and the recognizer go on publishing after it), so that
    # nothing the trial recorded is cut off; the bound only keeps a dead node from hanging it.
    def caught_up():
        truth = recorder.last_truth
        return (t_done is not None and truth is not None
                and truth.header.stamp.to_sec() >= t_done
                and (not recorder.states or recorder.states[-1][0] >= t_done))
    _wait_until(caught_up, 30.0, what='the ground truth and the states to reach DONE')
    # The stops come on their own connection too: wait until every stop the planner handled in
    # the trial (its DONE status counts them) is recorded; one still missing after the bound is
    # an error, not a trial without a stop.
    def stops_in():
        return len([s for s in recorder.stops if t_done is None or s[0] <= t_done]) >= \
            recorder.stops_heard
    if not _wait_until(stops_in, 30.0, what='the stops the planner handled'):
        raise RuntimeError('the record has %d of the %d stop(s) the planner handled'
                           % (len(recorder.stops), recorder.stops_heard))
    if t_done is not None:
        recorder.end_at(t_done)
    row['wall_s'] = time.time() - wall_start
    return analyse_trial(recorder, row, trial, trace_dir)


def _reset(srv, trial, moving, args, zero_s=None):
    """simulator/reset for the trial, holding sim time at the engine's start of the trial; its
    time 0 at sim time zero_s (see time_zero) when given."""
    import rospy
    stamp = rospy.Time(int(zero_s)) if zero_s is not None else rospy.Time()
    reply = srv['reset'](seed=trial['seed'], moving_bone=moving, hold_at_trial_start=True,
                         pre_trial_s=args.pre_trial_s, time_zero=stamp)
    if not reply.success:
        raise RuntimeError('simulator reset failed: %s' % reply.message)
    if zero_s is not None and reply.reset_time != stamp:
        # The simulator was already past it (a stalled worker): a valid trial, whose stamps
        # (and so the last bits of its numbers) are not those of another run.
        sys.stderr.write('campaign worker: %s started at sim time %.1f s, not %d s\n'
                         % (trial['trial_id'], reply.reset_time.to_sec(), zero_s))
    return reply


def _wait_sim_until(recorder, stamp):
    """Waits until the ground truth reaches sim time `stamp` (the simulator's hold)."""
    if not _wait_until(lambda: (recorder.last_truth is not None and
                                recorder.last_truth.header.stamp.to_sec() >= stamp - 1e-6),
                       120.0):
        raise RuntimeError('sim time did not reach %.3f s' % stamp)


class PipelineDown(RuntimeError):
    """The worker's master or pipeline did not come up: no trial can run."""


def wait_for_pipeline(rospy, service, launch, log_path, bound_s=60.0):
    """Waits for the launched pipeline's `service`, at most `bound_s` of wall time. A launch
    that exited (a launch file that is not there or does not parse, an argument it does not
    take) is PipelineDown at once, with the end of its log, not a timeout a minute later; a
    service not up in time is PipelineDown too (the worker then names the launch's processes
    that died: died_processes)."""
    deadline = time.monotonic() + bound_s
    while True:
        if launch.poll() is not None:
            with open(log_path, errors='replace') as handle:
                text = re.sub(r'\x1b\[[0-9;]*[A-Za-z]|\x1b\][^\x07]*\x07', '', handle.read())
            tail = [line.strip() for line in text.splitlines() if line.strip()]
            raise PipelineDown('the pipeline\'s roslaunch exited (%s) before %s was up; its log '
                               '%s ends: %s' % (launch.returncode, service, log_path,
                                                ' | '.join(tail[-6:])))
        try:
            left = deadline - time.monotonic()
            rospy.wait_for_service(service, timeout=max(0.05, min(1.0, left)))
            return
        except rospy.ROSException:
            if time.monotonic() >= deadline:
                raise PipelineDown('%s not up %.0f s after the pipeline\'s launch; its log: %s'
                                   % (service, bound_s, log_path)) from None


def batch_scheduling():
    """This worker and everything it starts (inherited) under SCHED_BATCH: a thread woken by
    another (a message queued, a condition notified) does not preempt it. Under the lockstep the
    simulator's thread then publishes a whole step before the participants run, and the
    participants' thread handles all of it at once, instead of one thread switch per message
    (a third of the ROS trial's wall time; doc/benchmarks.md). Only the order of execution
    changes, which the lockstep makes irrelevant to the trial. An unprivileged process may
    choose it; where it is refused the worker says so and runs as it is."""
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError) as error:
        sys.stderr.write('campaign worker: SCHED_BATCH refused (%s); running as it is\n' % error)


def parse_args(argv=None):
    """The worker's options (the campaign's _ros_worker gives them)."""
    parser = argparse.ArgumentParser()
    parser.add_argument('--port', type=int, required=True)
    parser.add_argument('--trials', required=True)
    parser.add_argument('--out', required=True)
    parser.add_argument('--scenario', default='')
    parser.add_argument('--bags', action='store_true')
    parser.add_argument('--feed-rate', type=float, default=0.5)
    parser.add_argument('--max-duration', type=float, default=60.0)
    parser.add_argument('--trial-timeout', type=float, default=120.0)
    parser.add_argument('--identification-window-s', type=float, default=30.0)
    parser.add_argument('--pre-trial-s', type=float, default=None,
                        help='sim time from the reset to the trial (then a breath phase drawn '
                        'from the seed); default: 1 s (the core engine\'s), or the '
                        'identification window when the model is identified online')
    parser.add_argument('--default-model', required=True)
    parser.add_argument('--models-dir', default='',
                        help='identified volunteer models (volunteer_<id>_<model>.yaml); '
                        'empty: identify online on the simulator')
    parser.add_argument('--model', default='linear')
    parser.add_argument('--recognizer', default='pedicle_drilling/PaperRecognizer',
                        help='the StateRecognizer nodelet\'s ~recognizer class')
    parser.add_argument('--compensator', default='pedicle_drilling/PaperCompensator',
                        help='the CompensationPlanner nodelet\'s ~compensator class')
    parser.add_argument('--recognizer-param', action='append', default=[],
                        metavar='NAME=VALUE', help='a recognizer parameter (campaign\'s)')
    parser.add_argument('--compensator-param', action='append', default=[],
                        metavar='NAME=VALUE', help='a compensator parameter (campaign\'s)')
    parser.add_argument('--segment-profile', default='rest_to_rest',
                        help="the planner's ~segment_profile (scenario key compensation_profile)")
    parser.add_argument('--depth-limit', default='true', choices=('true', 'false'),
                        help="the plan's depth limit (scenario key depth_limit): false runs the "
                             "paper's system without a plan (drilling_pipeline.launch "
                             "depth_limit:=false)")
    parser.add_argument('--bone-motion', default='virtual_patient',
                        choices=('model', 'virtual_patient'),
                        help='model: the SPMS plays the trial\'s identified model (the paper\'s '
                        'bench protocol); virtual_patient: the volunteer\'s truth with lag, '
                        'drift and small movements')
    parser.add_argument('--simulator-overrides', default='{}',
                        help='JSON of the scenario\'s simulator section: '
                        '{group: {key: value}} under /simulator/trial_distribution')
    parser.add_argument('--simulator-param', action='append', default=[],
                        help='NAME=VALUE (VALUE in JSON): a Simulator parameter read at every '
                        'reset (scenario keys simulator_params, and engine_delays as '
                        'command_delay_s, command_jitter_s, tracker_delay_s)')
    parser.add_argument('--launch', default='campaign_pipeline.launch')
    parser.add_argument('--real-time-factor', type=float, default=20.0)
    parser.add_argument('--cpu', type=int, default=None,
                        help='run this worker and everything it starts on this CPU (campaign '
                        '--pin-workers)')
    return parser.parse_args(argv)


def _prepare(args):
    """The worker's process (its CPU, its scheduling), its environment (the master's port on
    loopback, its log folder) and its output folders; (log folder, trace folder)."""
    if args.cpu is not None:
        # Inherited by the master, roslaunch and the nodelet manager started below: the
        # lockstep's thread hand-offs stay on one CPU (no cross-CPU wake-ups).
        os.sched_setaffinity(0, {args.cpu})
    batch_scheduling()
    if args.pre_trial_s is None:
        args.pre_trial_s = args.identification_window_s if not args.models_dir else 1.0
    # Loopback only, whatever the shell exported (doc/network.md): the
    # master, rosout, the launch's nodes, rosbag and this node. ROS_HOSTNAME names the host in
    # the URIs; roscpp keeps its topics and services on loopback only with ROS_IP=127.x.
    os.environ['ROS_MASTER_URI'] = 'http://127.0.0.1:%d' % args.port
    os.environ['ROS_HOSTNAME'] = '127.0.0.1'
    os.environ['ROS_IP'] = '127.0.0.1'
    log_dir = os.path.join(args.out, 'logs', 'worker-%d' % args.port)
    os.makedirs(log_dir, exist_ok=True)
    os.environ['ROS_LOG_DIR'] = log_dir
    trace_dir = os.path.join(args.out, 'traces')
    os.makedirs(trace_dir, exist_ok=True)
    os.makedirs(os.path.join(args.out, 'models'), exist_ok=True)
    return log_dir, trace_dir


def _stopper(children):
    """shutdown(): the `children` processes stopped (SIGINT, then SIGKILL after 10 s); SIGTERM
    stops them and ends the worker at once."""
    def shutdown(*_):
        for child in reversed(children):
            if child.poll() is None:
                try:
                    os.killpg(child.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        for child in reversed(children):
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(child.pid, signal.SIGKILL)

    def terminate(*_):
        # Stop the children, then leave at once: an exception raised here (SystemExit) would
        # surface inside whatever rospy call the main thread was in, and rospy turns some of
        # those into its own errors, which the trial loop records and goes on past (a master
        # gone: five trials of 'unable to contact master').
        shutdown()
        os._exit(143)

    signal.signal(signal.SIGTERM, terminate)
    return shutdown


def _start_master(args, children, log):
    """roscore on the worker's port, up."""
    children.append(subprocess.Popen(['roscore', '-p', str(args.port)], stdout=log,
                                     stderr=subprocess.STDOUT, start_new_session=True))
    import rosgraph
    for _ in range(200):
        if rosgraph.is_master_online():
            return
        time.sleep(0.1)
    raise PipelineDown('roscore on port %d did not start' % args.port)


def _launch_pipeline(rospy, args, children, log, log_dir):
    """The pipeline launched with the classes' parameter files; {key: service proxy} once its
    services are up."""
    from pedicle_drilling.srv import IdentifyMotion, ResetSimulation, StartTrial
    from std_srvs.srv import Trigger
    configs = []
    for kind, launch_arg in (('recognizer', 'recognizer_config'),
                             ('compensator', 'planner_config')):
        try:
            path = plugin_config(kind, getattr(args, kind), getattr(args, kind + '_param'),
                                 tools.package_dir(), os.path.join(log_dir, NODE_CONFIGS[kind]))
        except ValueError as error:
            raise PipelineDown(str(error)) from None
        if path:
            configs.append('%s:=%s' % (launch_arg, path))
    children.append(subprocess.Popen(
        ['roslaunch', 'pedicle_drilling', args.launch] + configs + launch_arguments(args),
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
    types = {'reset': ResetSimulation, 'identify': IdentifyMotion, 'start_trial': StartTrial,
             'resume': Trigger}
    srv = {}
    for key, name in PIPELINE_SERVICES.items():
        wait_for_pipeline(rospy, name, children[-1], log.name)
        srv[key] = rospy.ServiceProxy(name, types[key])
    return srv


def _set_simulator(rospy, args, srv, trials):
    """The scenario's simulator section: set after the launch loaded config/simulator.yaml,
    read by the simulator at every reset. One reset checks it before any trial (exit 2 when
    refused)."""
    for setting in args.simulator_param:  # read at every reset
        name, value = setting.split('=', 1)
        rospy.set_param('/simulator/%s' % name, json.loads(value))  # a number or a flag
    overrides = json.loads(args.simulator_overrides)
    for group, values in overrides.items():
        for key, value in values.items():
            rospy.set_param('/simulator/trial_distribution/%s/%s' % (group, key), value)
    if (overrides or args.simulator_param) and trials:
        reply = srv['reset'](seed=trials[0]['seed'], moving_bone=False)
        if not reply.success:
            sys.stderr.write('campaign worker: the scenario\'s simulator section or '
                             'command delay was refused: %s\n' % reply.message)
            sys.exit(2)


def _subscribe(rospy, recorder):
    """The recorder subscribed to every topic it records, each connected to its publisher."""
    from diagnostic_msgs.msg import DiagnosticArray
    from pedicle_drilling.msg import (DrillingState, GroundTruth, RetareCheck, StopCommand,
                                      TrialStatus)
    subscribers = [
        rospy.Subscriber('/drilling_state', DrillingState, recorder.on_state,
                         queue_size=10000),
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, recorder.on_truth,
                         queue_size=10000),
        rospy.Subscriber('/drill/stop', StopCommand, recorder.on_stop, queue_size=100),
        rospy.Subscriber('/safety_monitor/retare_check', RetareCheck, recorder.on_retare,
                         queue_size=10),
        rospy.Subscriber('/compensation/status', TrialStatus, recorder.on_status,
                         queue_size=100),
        rospy.Subscriber('/diagnostics', DiagnosticArray, recorder.on_diagnostics,
                         queue_size=100)]
    # Every recorded topic connected before the first trial: a connection made during it
    # cut the trial's record (a worker's first trial once lost its ground truth up to the
    # inner layer: no F_in, no stop depth; test_engine_agreement).
    for sub in subscribers:
        if not _wait_until(lambda: sub.get_num_connections() > 0, 60.0,
                           what='a publisher of %s' % sub.name):
            raise PipelineDown('nothing publishes %s 60 s after the pipeline came up'
                               % sub.name)


def _run_trials(rospy, srv, recorder, trials, args, trace_dir):
    """Each trial run, its row printed on stdout as one JSON line."""
    for trial in trials:
        try:
            row = run_trial(rospy, srv, None, recorder, trial, args, trace_dir)
        except Exception as error:  # recorded, the campaign goes on
            row = dict(trial)
            row['engine'] = 'ros'
            row['success'] = False
            row['error'] = str(error).replace('\n', ' ')[:300]
        # A finished trial's line is written whole: SIGTERM waits until it is out.
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
        sys.stdout.write(json.dumps(row) + '\n')
        sys.stdout.flush()
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})


def main(argv=None):
    args = parse_args(argv)
    log_dir, trace_dir = _prepare(args)
    with open(args.trials) as handle:
        trials = json.load(handle)
    children = []
    shutdown = _stopper(children)
    devnull = open(os.path.join(log_dir, 'children.log'), 'w')  # not atomic: a live log
    down = False
    try:
        _start_master(args, children, devnull)
        import rospy  # after ROS_MASTER_URI is set
        # The worker runs on wall time: it is initialised before /use_sim_time is set, so it
        # does not have to follow a /clock that runs many times faster than real time.
        rospy.init_node('campaign_worker_%d' % args.port, disable_signals=True)
        rospy.set_param('/use_sim_time', True)
        srv = _launch_pipeline(rospy, args, children, devnull, log_dir)
        _set_simulator(rospy, args, srv, trials)
        recorder = TrialRecorder()
        _subscribe(rospy, recorder)
        _run_trials(rospy, srv, recorder, trials, args, trace_dir)
    except PipelineDown as error:  # no trial ran: said once, not a traceback per worker
        sys.stderr.write('campaign worker: %s\n' % error)
        down = True
    finally:
        shutdown()
        devnull.close()
        # A process of the launch that died (the nodelet manager's crash ends every service
        # call with a transport error) is named on stderr, which the campaign shows.
        for line in died_processes(os.path.join(log_dir, 'children.log')):
            sys.stderr.write('campaign worker: %s\n' % line)
    if down:
        sys.exit(1)


def died_processes(log_path):
    """The lines of roslaunch's log (children.log) that report a process of the launch dead,
    with its exit code (-11: a segmentation fault)."""
    try:
        with open(log_path, errors='replace') as handle:
            return [line.strip() for line in handle if 'process has died' in line]
    except OSError:
        return []


if __name__ == '__main__':
    main()
