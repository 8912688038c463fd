"""Drilling-state recognizers written in Python, run in the closed loop wherever a
recognizer class is named: `python:pd_campaign.recognizers.ThresholdRecognizer` as the
StateRecognizer nodelet's `~recognizer`, `trial_engine --recognizer` or the campaign's
`--recognizer`. The C++ side (pedicle_drilling/python/python_recognizer.hpp) imports the class
from the Python path, makes it with no arguments and calls:

- ``configure(settings)``: a dict of parameter name -> value as text (`--recognizer-param
  name=value`, the nodelet's ``~recognizer_params``); unknown names and bad values raise
  ValueError whose message starts with the name;
- ``reset()``: a new trial, the parameters kept;
- ``push(t, raw_force)``: one raw thrust sample [s, N] (tared; at the sensor's rate), returning
  a dict with any of ``state`` and ``layer_state`` (idle, outer_cortical, outer_punctured,
  cancellous, inner_cortical, breakthrough), ``new_average`` (true when the averaged value is
  new: the nodelet then publishes drilling_state), ``averaged_force``, ``feature``,
  ``last_key_point`` and ``stop`` (the drill stops; latched by the C++ side until reset);
- optionally ``push_sample(sample)`` instead of ``push`` for each sample, when the class
  defines it: ``sample`` is a dict with ``t`` [s], ``thrust`` [N] (what ``push`` gets),
  ``force`` [N] and ``torque`` [N m] (the whole wrench, (x, y, z) tuples in the sensor's frame,
  tared), ``feed_depth_m`` (the feed joint's position) and ``spindle_rpm`` (the spindle joint's
  speed), the last two as the joint states last gave them (NaN until then); it returns what
  ``push`` returns. Only ``t`` and ``thrust`` are checked finite before the class sees them;
- optionally ``stop_reason()``, ``describe()`` and ``parameter_names()``.

Recognizer is the base class with that contract and the parameter handling, BlockMean the
pre-average the block-based classes share; ThresholdRecognizer is a force-threshold baseline
written with them."""

from pd_campaign.checks import positive
from pd_campaign.plugin_params import Configurable


class BlockMean:
    """The pre-average: the mean of each block of `size` consecutive raw samples."""

    def __init__(self, size):
        self.size = size
        self.sum = 0.0
        self.count = 0

    def add(self, value):
        """The block's mean when `value` completes a block, else None."""
        self.sum += value
        self.count += 1
        if self.count < self.size:
            return None
        mean = self.sum / self.count
        self.sum, self.count = 0.0, 0
        return mean


class Recognizer(Configurable):
    """Base class: declare PARAMETERS = {name: (type, default, check)}; check(value) -> bool
    (pd_campaign.plugin_params.Configurable: configure() raises ValueError naming a bad or
    unknown parameter). A configured recognizer starts a new trial."""

    def __init__(self):
        super().__init__()
        self.reset()

    def configured(self):
        self.reset()

    def reset(self):
        """A new trial."""

    def push(self, t, raw_force):
        """One raw sample; the output dict (see the module's documentation)."""
        raise NotImplementedError


class ThresholdRecognizer(Recognizer):
    """A force-threshold baseline: block means of `pre_average` raw samples; the outer cortex
    is a block mean above `cortical_n`, the cancellous bone a later one below `cancellous_n`,
    and the inner cortex `confirm` consecutive block means above `cortical_n` again: the stop.
    Its thresholds are absolute forces, so it depends on the specimen's force levels (the
    paper's recognizer normalises by its outer layer's amplitude, D). The defaults lie between
    the simulated specimens' cortical and cancellous block means (about 3 N and 1.3 N at
    12000 rpm, 0.5 mm/s: doc/simulator_physics.md); tune them on training data."""

    PARAMETERS = {
        'pre_average': (int, 50, positive),
        'cortical_n': (float, 2.2, positive),
        'cancellous_n': (float, 1.7, positive),
        'confirm': (int, 2, positive),
    }

    def reset(self):
        self.block_mean = BlockMean(self.params['pre_average'])
        self.state = 'idle'
        self.above = 0
        self.stopped_at = None

    def push(self, t, raw_force):
        mean = self.block_mean.add(raw_force)
        if mean is None:
            return {}
        high = mean > self.params['cortical_n']
        if self.state == 'idle' and high:
            self.state = 'outer_cortical'
        elif self.state == 'outer_cortical' and mean < self.params['cancellous_n']:
            self.state = 'cancellous'
        elif self.state == 'cancellous':
            self.above = self.above + 1 if high else 0
            if self.above >= self.params['confirm']:
                self.state = 'inner_cortical'
                self.stopped_at = t
        key_point = {'idle': 0, 'outer_cortical': 1, 'cancellous': 3, 'inner_cortical': 4}
        return {'new_average': True, 'averaged_force': mean, 'state': self.state,
                'layer_state': self.state, 'last_key_point': key_point[self.state],
                'stop': self.state == 'inner_cortical'}

    def stop_reason(self):
        return ('inner cortical layer reached (ThresholdRecognizer): %d block means above %.3g N '
                'after the cancellous layer, at t=%.3f s' % (
                    self.params['confirm'], self.params['cortical_n'], self.stopped_at or 0.0))
