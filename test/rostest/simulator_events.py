"""What the simulator scenarios' tests watch, shared: /clock and simulator/ground_truth under one
condition, and a wait on them bounded only to end a broken run (tests wait on events)."""
import threading
import time

import rospy
from rosgraph_msgs.msg import Clock

from pedicle_drilling.msg import GroundTruth


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
