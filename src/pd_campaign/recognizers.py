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
  speed) as the joint states last gave them, ``feed_command_m`` (the feed joint's commanded
  position, from the feed controller's state), ``tracker`` ((x, y, z), the latest tracked
  marker position in the tracker's frame) and ``tracker_stamp`` (NaN until heard); it returns
  what ``push`` returns. Only ``t`` and ``thrust`` are checked finite before the class sees them;
- optionally ``stop_reason()``, ``describe()`` and ``parameter_names()``.

Recognizer is the base class with that contract and the parameter handling, BlockMean the
pre-average the block-based classes share; ThresholdRecognizer is a force-threshold baseline
written with them, WrenchThresholdRecognizer the same on the whole wrench (push_sample)."""

import math

from pd_campaign.checks import fraction, positive
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
        return ('inner cortical layer reached (%s): %d block means above %.3g N after the '
                'cancellous layer, at t=%.3f s' % (
                    type(self).__name__, self.params['confirm'], self.params['cortical_n'],
                    self.stopped_at or 0.0))


# The lever of the drilling torque about the drill axis: kappa * D / 2 = 1.6 * 1.25 mm
# (doc/simulator_physics.md, section 2c: Orelaja et al. 2020, a 2.5 mm bit in bovine femur).
TORQUE_LEVER_M = 1.6 * 1.25e-3
# The torque channel's thrust equivalent weighed against the thrust by their noise: the sensor's
# white noise SDs (force 0.03 N, torque 0.5 N mm: doc/simulator_physics.md) give the torque's
# thrust 0.5e-3 / TORQUE_LEVER_M = 0.25 N, so inverse-variance weights 0.03^2 : 0.25^2.
TORQUE_WEIGHT = 0.03 ** 2 / (0.03 ** 2 + (0.5e-3 / TORQUE_LEVER_M) ** 2)


class WrenchThresholdRecognizer(ThresholdRecognizer):
    """ThresholdRecognizer on the whole wrench (push_sample). Its block means are of the thrust
    fused with the thrust the drilling torque implies (the torque about the drill axis over
    `torque_lever_m`), weighted `torque_weight` (inverse-variance weights of the sensor's
    noise), and two checks the thrust alone cannot make, each a stop that names it:

    - skiving: a block's mean lateral force (the magnitude of its x and y) above
      `lateral_max_n`: the bit is pushed sideways, as when it slips on an inclined cortex;
    - clogging: in bone (the block's thrust above `cancellous_n`), a block's torque per thrust
      above `torque_ratio_max` times the lever: torque without the thrust to cause it, as from
      flutes packed with chips.

    A non-finite torque or lateral force leaves that sample's channel out (the thrust alone). On
    the simulator the torque follows the thrust with one lever and the lateral force is the
    sensor's noise and spindle tone, so neither check stops a trial there; they are for a bench
    whose bit can slip or clog. The defaults are not tuned on trials."""

    PARAMETERS = dict(ThresholdRecognizer.PARAMETERS,
                      torque_lever_m=(float, TORQUE_LEVER_M, positive),
                      torque_weight=(float, TORQUE_WEIGHT, fraction),
                      lateral_max_n=(float, 1.0, positive),
                      torque_ratio_max=(float, 2.0, positive))

    def reset(self):
        super().reset()
        self.lateral = BlockMean(self.params['pre_average'])
        self.thrust = BlockMean(self.params['pre_average'])
        self.torque = BlockMean(self.params['pre_average'])
        self.check_reason = None

    def push_sample(self, sample):
        thrust = sample['thrust']
        torque = sample['torque'][2]
        fx, fy = sample['force'][0], sample['force'][1]
        fused = thrust
        if math.isfinite(torque):
            w = self.params['torque_weight']
            fused = (1.0 - w) * thrust + w * torque / self.params['torque_lever_m']
        lateral = math.hypot(fx, fy) if math.isfinite(fx) and math.isfinite(fy) else 0.0
        lateral_mean = self.lateral.add(lateral)
        thrust_mean = self.thrust.add(thrust)
        torque_mean = self.torque.add(torque if math.isfinite(torque) else thrust *
                                      self.params['torque_lever_m'])
        out = self.push(sample['t'], fused)
        if lateral_mean is None or self.check_reason or self.stopped_at is not None:
            return dict(out, stop=True) if self.check_reason else out
        if lateral_mean > self.params['lateral_max_n']:
            self.check_reason = ('skiving (WrenchThresholdRecognizer): mean lateral force %.3g N '
                                 '> %.3g N at t=%.3f s' % (lateral_mean,
                                                           self.params['lateral_max_n'],
                                                           sample['t']))
        elif thrust_mean > self.params['cancellous_n']:
            ratio = torque_mean / thrust_mean / self.params['torque_lever_m']
            if ratio > self.params['torque_ratio_max']:
                self.check_reason = ('clogging (WrenchThresholdRecognizer): torque %.3g N mm at '
                                     '%.3g N thrust, %.3g times the lever, > %.3g at t=%.3f s' % (
                                         torque_mean * 1e3, thrust_mean, ratio,
                                         self.params['torque_ratio_max'], sample['t']))
        if self.check_reason:
            out = dict(out, stop=True)
        return out

    def stop_reason(self):
        return self.check_reason or super().stop_reason()
