"""What one --engine ros trial records from the pipeline's topics (TrialRecorder): the recognizer's
states, the ground truth, the stops, the planner's statuses, the monitor's re-tare check and
diagnostics, all with sim-time stamps; analysis.analyse_trial turns it into a row."""
import threading


def _recording(handler):
    """A TrialRecorder callback: under the recorder's lock, and dropped once the trial's record
    is closed (end_at): rospy's threads go on delivering what the simulator publishes after
    DONE while the worker analyses the record."""
    def wrapped(self, msg):
        with self._lock:
            if not self.closed:
                handler(self, msg)
    wrapped.__doc__ = handler.__doc__
    return wrapped


class TrialRecorder:
    """Collects what one trial needs from the topics (all sim-time stamps)."""

    def __init__(self):
        self._lock = threading.Lock()
        self.clear()

    def clear(self, min_stamp=0.0, trial_start=0.0):
        with self._lock:
            self._clear(min_stamp, trial_start)

    def _clear(self, min_stamp, trial_start):
        self.closed = False       # end_at closed the record: nothing more is added
        # Messages stamped before min_stamp are the previous trial's, still in transit: dropped.
        # Stops before the trial's start are not the trial's (a monitor that stops between the
        # reset and the start is reset by the start; the core engine's cannot stop before it).
        self.min_stamp = min_stamp
        self.trial_start = max(min_stamp, trial_start)
        self.states = []          # (t, averaged_force, feature, state_name, last_key_point)
        self.key_points = []      # (id, t)
        self.truth = []           # (t, layer, max_depth, residual, breakthrough, rel_ap, contact,
                                  #  contact losses so far)
        self.last_truth = None
        self.truth_msgs = []      # the GroundTruth messages of self.truth (ROS engine)
        self.stops = []           # (t, source, reason, retreat)
        self.status = []          # (t, phase name)
        self.phase = None         # the latest TrialStatus phase (ROS engine)
        self.stops_heard = 0      # the planner's count of the trial's stops at that phase
        self.retare = None        # the monitor's re-tare check when the retreat ended
        self.inputs = None        # (t, {key: value}): the monitor's input streams, latest
        self.monitor_statuses = []  # every (t, {key: value}) of the monitor, in order
        self._last_kp = 0

    @_recording
    def on_state(self, msg):
        t = msg.header.stamp.to_sec()
        if t < self.min_stamp:
            return
        self.states.append((t, msg.averaged_force, msg.feature, msg.state_name,
                            msg.last_key_point))
        if msg.last_key_point > self._last_kp:
            for kp in range(self._last_kp + 1, msg.last_key_point + 1):
                self.key_points.append((kp, t))
            self._last_kp = msg.last_key_point

    @_recording
    def on_truth(self, msg):
        if msg.header.stamp.to_sec() < self.min_stamp:
            return
        self.last_truth = msg
        self.truth_msgs.append(msg)
        self.truth.append((msg.header.stamp.to_sec(), msg.specimen_layer, msg.max_depth_cut_m,
                           msg.residual_inner_cortical_m, msg.breakthrough, msg.relative_ap_m,
                           msg.contact, msg.contact_loss_count))

    @_recording
    def on_stop(self, msg):
        if msg.header.stamp.to_sec() < self.trial_start:
            return
        self.stops.append((msg.header.stamp.to_sec(), msg.source, msg.reason, msg.retreat))

    @_recording
    def on_retare(self, msg):
        """pedicle_drilling/RetareCheck: the SafetyMonitor's re-tare check after the retreat."""
        if msg.done and msg.header.stamp.to_sec() >= self.min_stamp:
            self.retare = {'t': msg.header.stamp.to_sec(), 'drift': msg.drift,
                           'offset_n': msg.offset_n, 'message': msg.message}

    @_recording
    def on_diagnostics(self, msg):
        """/diagnostics: the SafetyMonitor's status carries its input streams as received."""
        t = msg.header.stamp.to_sec()
        if t < self.min_stamp:
            return
        for status in msg.status:
            if status.name.endswith(': monitor'):
                self.inputs = (t, {kv.key: kv.value for kv in status.values})
                self.monitor_statuses.append(self.inputs)

    @_recording
    def on_status(self, msg):
        """pedicle_drilling/TrialStatus: the phase, stamped with the (sim) time of the change."""
        if msg.header.stamp.to_sec() < self.min_stamp:
            return
        self.phase = msg.phase
        self.status.append((msg.header.stamp.to_sec(), msg.phase_name))
        self.stops_heard = msg.stops  # the planner's count of the trial's stops, so far

    def status_time(self, name):
        return next((t for (t, s) in self.status if s == name), None)

    def end_at(self, t_done):
        """The ROS engine's simulator runs on after DONE until the next reset (as fast as the
        machine allows at --real-time-factor 0): the trial's record ends at DONE, whenever the
        worker got to it. The ground truth up to the first sample at or after DONE (the one the
        core engine records at DONE), the recognizer's states and key points up to DONE, and the
        monitor's inputs as it reported them when it heard the trial end (its first status with
        trial_running false after one with true; the latest one without that key)."""
        with self._lock:
            self.closed = True
        end = next((k for k, row in enumerate(self.truth) if row[0] >= t_done), None)
        if end is not None:
            self.truth = self.truth[:end + 1]
            self.truth_msgs = self.truth_msgs[:end + 1]
            self.last_truth = self.truth_msgs[-1]
        self.states = [s for s in self.states if s[0] <= t_done]
        self.stops = [s for s in self.stops if s[0] <= t_done]
        self.key_points = [k for k in self.key_points if k[1] <= t_done]
        inputs = self.trial_end_inputs()
        if inputs is not None:
            self.inputs = inputs

    def trial_end_inputs(self):
        """The monitor's status when it heard the trial end (see end_at), or None yet."""
        running = False
        for t, values in list(self.monitor_statuses):
            if values.get('trial_running') == 'true':
                running = True
            elif running and values.get('trial_running') == 'false':
                return (t, values)
        return None
