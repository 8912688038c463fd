"""Motion compensators written in Python, run in the closed loop wherever a
compensator class is named: `python:pd_campaign.compensators.PhaseTemplateCompensator` as the
CompensationPlanner nodelet's `~compensator`, `trial_engine --compensator` or the campaign's
`--compensator`. The C++ side (pedicle_drilling/python/python_compensator.hpp) imports the class
from the Python path, makes it with no arguments (one object per trial) and calls:

- ``configure(settings)``: a dict of parameter name -> value as text; unknown names and bad
  values raise ValueError whose message starts with the name (Compensator does this from its
  PARAMETERS);
- ``set_patient(model, params)``: the patient's identified model, ``{'ap'|'si'|'lr': {'kind':
  'linear'|'hysteresis', 'q0', 'q1', 'q2'}}`` (mm, ml, s: Eq. 7-9), and the planner's
  conventions, ``{'feed_rate_m_s', 'period_s', 'latency_s', 'predict_axis': [ap, si, lr],
  'compensate_lateral', 'drill_axis': [x, y, z], 'axis_direction': {'ap'|'si'|'lr': [x, y, z]}}``
  (unit vectors in the world frame);
- ``set_ventilator(settings)``: ``{'tv_max_ml', 'rate_bpm', 'ie_inspiratory', 'ie_expiratory',
  'waveform', 'pause_fraction'}``, whenever the ventilator's settings are (re)published;
- ``set_breath_start(t)``: the start time of a breath [s], from the ventilator's stream;
- ``observe_marker(stamp, position)`` (optional): a tracked marker position [m, numpy array of 3,
  world frame, origin arbitrary] measured at `stamp`, from the registration on;
- ``ready()``: True once ``displacement`` can be asked;
- ``displacement(t)``: the predicted vertebra displacement at time t [s]: three numbers (numpy
  array, list or tuple), metres, world frame, any constant origin (the planner uses its change
  since the registration). The planner asks up to one segment period plus its latency ahead of
  the last input: a compensator predicts, it is never told the future. Non-finite values are an
  error;
- optionally ``velocity_steps(t0, t1)`` (times in (t0, t1] where the predicted velocity steps),
  ``describe()`` and ``parameter_names()``.

Times are the driver's clock (ROS time on the nodelet, simulated time on the core engine).
Compensator is the base class; PhaseTemplateCompensator a tracker-driven example written with it."""

import math

import numpy as np

from pd_campaign.checks import at_least
from pd_campaign.plugin_params import Configurable


class Compensator(Configurable):
    """Base class: declare PARAMETERS; the inputs are kept in `patient`, `planner`,
    `ventilator` and `breath_start`; subclasses implement ready() and displacement()."""

    def __init__(self):
        super().__init__()
        self.patient = None
        self.planner = None
        self.ventilator = None
        self.breath_start = None

    def set_patient(self, model, params):
        self.patient, self.planner = model, params

    def set_ventilator(self, settings):
        self.ventilator = settings

    def set_breath_start(self, t):
        self.breath_start = t

    def observe_marker(self, stamp, position):
        """A tracker sample (ignored by default)."""

    def ready(self):
        raise NotImplementedError

    def displacement(self, t):
        raise NotImplementedError

    def breath_period_s(self):
        """The ventilator's breath period [s] (None before its settings)."""
        return None if self.ventilator is None else 60.0 / self.ventilator['rate_bpm']


class PhaseTemplateCompensator(Compensator):
    """Breath-phase template of the tracked marker: a prediction without the patient model.

    Each tracker sample is filed by its phase in the ventilated breath (from the ventilator's
    breath starts and rate) into one of `bins` bins, whose mean position is the template; the
    displacement at t is the template at t's phase, interpolated between bin centres. The
    ventilator repeats the same breath, so the template predicts any time ahead, as a
    repetitive-motion predictor of the respiratory-compensation literature does (e.g. Ernst et
    al., "Prediction of respiratory motion with a multi-frequency based Extended Kalman Filter",
    2007; here the period is known from the ventilator's settings, not estimated). Until every
    bin has `min_samples` samples it holds the last measurement (a tracker-feedback
    compensator, as the C++ TrackedMarkerCompensator)."""

    PARAMETERS = {
        'bins': (int, 20, at_least(4)),
        'min_samples': (int, 1, at_least(1)),
    }

    def configured(self):
        self.reset_template()

    def reset_template(self):
        bins = self.params['bins']
        self.sums = np.zeros((bins, 3))
        self.counts = np.zeros(bins, dtype=int)
        self.last = None

    def __init__(self):
        super().__init__()
        self.reset_template()

    def _phase(self, t):
        period = self.breath_period_s()
        if period is None or self.breath_start is None:
            return None
        return ((t - self.breath_start) % period) / period

    def observe_marker(self, stamp, position):
        position = np.asarray(position, dtype=float)
        self.last = position
        phase = self._phase(stamp)
        if phase is None:
            return
        k = min(int(phase * self.params['bins']), self.params['bins'] - 1)
        self.sums[k] += position
        self.counts[k] += 1

    def ready(self):
        return self.last is not None

    def template_complete(self):
        return bool(np.all(self.counts >= self.params['min_samples']))

    def displacement(self, t):
        phase = self._phase(t)
        if phase is None or not self.template_complete():
            return self.last
        bins = self.params['bins']
        x = phase * bins - 0.5  # bin centres at (k + 0.5) / bins
        k0 = math.floor(x)
        w = x - k0
        lower, upper = k0 % bins, (k0 + 1) % bins
        means = self.sums / self.counts[:, None]
        return (1.0 - w) * means[lower] + w * means[upper]
