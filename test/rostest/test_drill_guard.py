#!/usr/bin/python3
"""Safe whatever dies, on the simulated pipeline (drilling_pipeline.launch sim:=true, its
processes as the .test file lays them out). One compensated trial; once the drill is 1 mm into
the bone (the simulator's ground truth) the test does ~scenario:

  kill_planner     SIGKILL the planner's nodelet manager (planner, recognizer);
  kill_monitor     SIGKILL the safety monitor's (the drill guard's) nodelet manager (the
                   launch gives each its own process);
  prediction_lost  stop relaying the planner's predicted marker pose to the monitor (the launch
                   remaps the monitor's input to /test_relay/predicted_marker_pose);
  reset_refused    call the recognizer's and the monitor's ~reset, and again after the trial.

The kills: the simulated drivers must hold the feed within ~feed_bound_s and stop the spindle
within ~spindle_bound_s of the kill (sim time, from the last ground truth heard before it, so
the measured delay is an upper bound), and the bone must breathe into the stopped drill for
~watch_s without a breakthrough. prediction_lost: the monitor stops the drill (reason
prediction_lost) within ~stop_bound_s of the last relayed prediction; the trial retreats, no
breakthrough. reset_refused: both resets answer success false, saying why; the trial ends in a
recognizer stop without a breakthrough (the resets changed nothing); after it both resets work."""
import os
import signal
import sys
import threading
import time
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest
from geometry_msgs.msg import PoseStamped
from std_srvs.srv import Trigger

from pedicle_drilling.msg import GroundTruth, StopCommand, TrialStatus
from pedicle_drilling.srv import StartTrial
from simulator_events import start_trial

INJECT_DEPTH_M = 1.0e-3  # the deepest cut when the fault comes: in the outer cortex


def node_pid(name):
    """The pid of the ROS node `name` (its XML-RPC getPid)."""
    uri = rosgraph.Master('/test_drill_guard').lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid('/test_drill_guard')
    if code != 1:
        raise RuntimeError('no pid for ' + name)
    return pid


class DrillGuardTest(unittest.TestCase):
    def setUp(self):
        self.lock = threading.Lock()
        self.truth, self.stops, self.status = [], [], []
        self.deep = threading.Event()
        self.relay_on = True
        self.last_relayed = None
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.on_truth, queue_size=1000)
        rospy.Subscriber('/drill/stop', StopCommand, self.keep(self.stops), queue_size=10)
        rospy.Subscriber('/compensation/status', TrialStatus, self.keep(self.status),
                         queue_size=100)
        self.relay = rospy.Publisher('/test_relay/predicted_marker_pose', PoseStamped,
                                     queue_size=50)
        rospy.Subscriber('/compensation/predicted_marker_pose', PoseStamped, self.on_predicted,
                         queue_size=50)

    def keep(self, store):
        def cb(msg):
            with self.lock:
                store.append((msg.header.stamp.to_sec(), msg))
        return cb

    def on_truth(self, msg):
        with self.lock:
            self.truth.append(msg)
        if msg.max_depth_cut_m >= INJECT_DEPTH_M:
            self.deep.set()

    def on_predicted(self, msg):
        with self.lock:
            if not self.relay_on:
                return
            self.last_relayed = msg.header.stamp.to_sec()
        self.relay.publish(msg)

    def wait_until(self, predicate, bound_s, what):
        """Waits until predicate() holds; bound_s of wall time (sim time stalls while the
        lockstep waits for a killed participant) bounds a broken run only."""
        end = time.monotonic() + bound_s
        while not rospy.is_shutdown() and time.monotonic() < end:
            with self.lock:
                if predicate():
                    return
            time.sleep(0.02)
        self.fail('timed out waiting for ' + what)

    def start(self):
        rospy.wait_for_service('/compensation_planner/start_trial', 60.0)
        start = rospy.ServiceProxy('/compensation_planner/start_trial', StartTrial)
        res = start_trial(start, mode='compensated', spindle_rpm=12000.0, feed_rate_mm_s=0.5,
                          max_duration_s=60.0)
        self.assertTrue(res.success, res.message)
        self.assertTrue(self.deep.wait(120.0), 'the drill never reached 1 mm')
        with self.lock:
            self.assertEqual(self.stops, [], 'a stop before the fault')
            return self.truth[-1].header.stamp.to_sec()

    def finish(self):
        """Waits for the trial's end; its stops, ground truth and phase names."""
        self.wait_until(lambda: self.status and self.status[-1][1].phase_name in ('done', 'failed'),
                        120.0, 'the end of the trial')
        with self.lock:
            return (list(self.stops), list(self.truth),
                    [s.phase_name for _, s in self.status])

    def report(self, text):
        sys.stdout.write(text + '\n')
        artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS')
        if artifacts:
            os.makedirs(artifacts, exist_ok=True)
            name = rospy.get_param('~scenario')
            with open(os.path.join(artifacts, 'drill_guard_%s.txt' % name), 'w') as handle:
                handle.write(text + '\n')

    def test_scenario(self):
        scenario = rospy.get_param('~scenario')
        getattr(self, 'run_' + scenario)()

    # ------------------------------------------------------------------------------ kills

    def run_kill(self, node):
        feed_bound = rospy.get_param('~feed_bound_s')
        spindle_bound = rospy.get_param('~spindle_bound_s')
        watch = rospy.get_param('~watch_s')
        pid = node_pid(node)
        self.start()
        with self.lock:
            depth_kill = self.truth[-1].max_depth_cut_m
        # The latest sim time known (/clock every 1 ms): at most the kill's, so the delays
        # measured from it are upper bounds.
        t_kill = rospy.get_rostime().to_sec()
        os.kill(pid, signal.SIGKILL)
        self.wait_until(lambda: self.truth[-1].header.stamp.to_sec() > t_kill + watch,
                        120.0, '%.1f s of sim time after the kill' % watch)
        with self.lock:
            after = [g for g in self.truth if g.header.stamp.to_sec() > t_kill]
        halted = [g for g in after if g.drives_halted]
        self.assertTrue(halted, 'the drivers never halted after the kill of ' + node)
        t_halt = halted[0].header.stamp.to_sec()
        stopped = [g for g in after if g.spindle_rpm == 0.0]
        self.assertTrue(stopped, 'the spindle never stopped')
        t_spin = stopped[0].header.stamp.to_sec()
        held = [g.feed_joint_m for g in after if g.header.stamp.to_sec() >= t_halt]
        text = ('%s killed at <= %.3f s (sim), %.3f mm deep: drivers halted %.3f s later, '
                'spindle stopped %.3f s later; feed after the halt moved %.4f mm; deepest cut '
                '%.3f mm (the bone breathing into the drill while the spindle ran down), '
                'canal wall at %.3f mm; breakthrough %s; guard trips %d' %
                (node, t_kill, depth_kill * 1e3, t_halt - t_kill, t_spin - t_kill,
                 (max(held) - min(held)) * 1e3, after[-1].max_depth_cut_m * 1e3,
                 after[-1].inner_cortical_end_m * 1e3, after[-1].breakthrough,
                 after[-1].drive_guard_trips))
        self.report(text)
        self.assertLessEqual(t_halt - t_kill, feed_bound, text)
        self.assertLessEqual(t_spin - t_kill, spindle_bound, text)
        self.assertLess(max(held) - min(held), 0.02e-3, text)  # the feed holds (drive lag only)
        self.assertTrue(all(g.drives_halted for g in after if g.header.stamp.to_sec() >= t_halt),
                        text)
        self.assertFalse(any(g.breakthrough for g in after), text)

    def run_kill_planner(self):
        self.run_kill('/pedicle_drilling_manager')

    def run_kill_monitor(self):
        self.run_kill('/pedicle_drilling_guard')

    # ---------------------------------------------------------------------- prediction lost

    def run_prediction_lost(self):
        bound = rospy.get_param('~stop_bound_s')
        self.start()
        with self.lock:
            self.relay_on = False
            t_last = self.last_relayed
        self.assertIsNotNone(t_last, 'no prediction was relayed before the fault')
        stops, truth, names = self.finish()
        self.assertTrue(stops, 'no stop after the prediction stream ended')
        t_stop, first = stops[0]
        text = ('prediction stream ended after the one stamped %.3f s: first stop %.3f s later '
                'from %s: %s; phases %s; breakthrough %s' %
                (t_last, t_stop - t_last, first.source, first.reason, names[-3:],
                 truth[-1].breakthrough))
        self.report(text)
        self.assertIn('safety_monitor', first.source, text)
        self.assertTrue(first.reason.startswith('prediction_lost'), text)
        self.assertLessEqual(t_stop - t_last, bound, text)
        self.assertIn('retreating', names, text)
        self.assertFalse(any(g.breakthrough for g in truth), text)

    # ----------------------------------------------------------------------- reset refused

    def run_reset_refused(self):
        for name in ('/state_recognizer/reset', '/safety_monitor/reset'):
            rospy.wait_for_service(name, 60.0)
        self.start()
        answers = {}
        for name in ('/state_recognizer/reset', '/safety_monitor/reset'):
            answers[name] = rospy.ServiceProxy(name, Trigger)()
        stops, truth, names = self.finish()
        text = ('resets during drilling: %s; stops %s; phases %s; breakthrough %s' %
                ({k: (a.success, a.message) for k, a in answers.items()},
                 [(s.source, s.reason) for _, s in stops], names[-3:], truth[-1].breakthrough))
        self.report(text)
        for name, answer in answers.items():
            self.assertFalse(answer.success, name + ': ' + text)
            self.assertIn('refused', answer.message, text)
        self.assertIn('drilling', answers['/state_recognizer/reset'].message, text)
        self.assertTrue(stops, text)
        self.assertIn('state_recognizer', stops[0][1].source, text)
        self.assertEqual(names[-1], 'done', text)
        self.assertFalse(any(g.breakthrough for g in truth), text)
        for name in answers:  # the trial is over: once the node has heard so, it resets
            call = rospy.ServiceProxy(name, Trigger)
            end = time.monotonic() + 10.0  # wall time: bounds a broken run only
            answer = call()
            while not answer.success and time.monotonic() < end:
                time.sleep(0.05)
                answer = call()
            self.assertTrue(answer.success, name + ': ' + answer.message)


if __name__ == '__main__':
    rospy.init_node('test_drill_guard')
    rostest.rosrun('pedicle_drilling', 'drill_guard', DrillGuardTest, sys.argv)
