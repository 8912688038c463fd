"""What the simulator scenarios' tests watch, shared: /clock and simulator/ground_truth under one
condition, and a wait on them bounded only to end a broken run (tests wait on events); a
lockstep participant for the lockstep's scenarios; and the start of a trial on the pipeline."""
import threading
import time

import rospy
from rosgraph_msgs.msg import Clock

from pedicle_drilling.msg import GroundTruth, StepAck


def start_trial(start, stop_on=None, attempts=100, **request):
    """Starts a trial through the planner's ~start_trial (`start`: a rospy.ServiceProxy of
    pedicle_drilling/StartTrial) with `request`, asking again every 0.2 s (ROS time) while it is
    refused: the moving modes are refused until the planner knows the ventilator's settings and
    breath phase (and the controller watch each controller's state). Returns the last answer:
    a success, the refusal `stop_on(answer)` accepts (a test expecting it), or the last of
    `attempts` refusals."""
    answer = None
    for _ in range(attempts):
        answer = start(**request)
        if answer.success or (stop_on is not None and stop_on(answer)):
            break
        rospy.sleep(0.2)
    return answer


class SimulatorEvents:
    """Mixin for a unittest.TestCase: call watch_simulator() in setUp."""
    WAIT_BOUND_S = 30.0  # wall seconds after which wait_for fails (a broken run)

    def watch_simulator(self):
        self.cond = threading.Condition()
        self.clock = None
        self.clock_stamp = None
        self.truth = None
        rospy.Subscriber('/clock', Clock, self.on_clock, queue_size=100)
        rospy.Subscriber('/simulator/ground_truth', GroundTruth, self.on_truth, queue_size=10)

    def on_clock(self, msg):
        with self.cond:
            self.clock = msg.clock.to_sec()
            self.clock_stamp = msg.clock  # exact (ns): stamps built from it are exact
            self.cond.notify_all()

    def on_truth(self, msg):
        with self.cond:
            self.truth = msg
            self.cond.notify_all()

    def wait_for(self, predicate, what, bound=None):
        """Waits (on events; the wall bound only ends a broken run) until predicate() holds."""
        deadline = time.monotonic() + (self.WAIT_BOUND_S if bound is None else bound)
        with self.cond:
            while not predicate():
                left = deadline - time.monotonic()
                if left <= 0:
                    self.fail('%s: not reached (clock %r)' % (what, self.clock))
                self.cond.wait(min(left, 0.2))


class StepParticipant(SimulatorEvents):
    """Mixin: the test is a lockstep participant (doc/running.md, "Lockstep"). Call participate(node) in
    setUp. It answers simulator/step while self.answering (under self.cond); a step it does not
    answer is kept in self.unanswered."""

    def participate(self, node):
        self.watch_simulator()
        self.node = node
        self.last_step = None
        self.answering = True
        self.unanswered = None
        self.ack = rospy.Publisher('/simulator/step_ack', StepAck, queue_size=100)
        rospy.Subscriber('/simulator/step', Clock, self.on_step, queue_size=100)

    def on_step(self, msg):
        with self.cond:
            self.last_step = msg.clock
            answer = self.answering
            if not answer:
                self.unanswered = msg.clock
            self.cond.notify_all()
        if answer:
            self.answer(msg.clock)

    def answer(self, stamp):
        self.ack.publish(StepAck(stamp=stamp, node=self.node))

    def join_lockstep(self):
        """Waits until the simulator steps on this test's answers; returns the step then."""
        self.wait_for(lambda: self.last_step is not None and self.truth is not None,
                      'simulator stepping')
        # Joined once an answer reaches the simulator: sim time then advances with our answers.
        deadline = time.monotonic() + 30.0
        while self.ack.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        self.assertGreater(self.ack.get_num_connections(), 0, 'the simulator hears no answer')
        with self.cond:
            first = self.last_step.to_sec()
        self.wait_for(lambda: self.last_step.to_sec() > first + 0.05, 'steps answered')
        return first
