"""ChangePointRecognizer: Bayesian online change-point detection (Adams and MacKay 2007) on the
logarithm of block means, with a segment logic on relative levels; a baseline recognizer of the
leaderboard (`python:pd_campaign.baselines.ChangePointRecognizer`)."""
import math

import numpy as np

from pd_campaign.checks import at_least, fraction, positive
from pd_campaign.offline import KEY_POINTS
from pd_campaign.recognizers import BlockMean, Recognizer


# --- Bayesian online change-point detection -------------------------------------------------

class RunLengthPosterior:
    """Bayesian online change-point detection (R. P. Adams and D. J. C. MacKay, "Bayesian Online
    Changepoint Detection", arXiv:0710.3742, 2007: the run-length recursion of their Algorithm
    1), for Gaussian observations with an unknown segment mean (conjugate Normal prior
    N(mu0, prior_sd^2)) and a known variance sigma^2, and a constant hazard H = P(a change
    before an observation). The run-length posterior is kept for run lengths 1..max_run (the
    current segment holds the last r observations, the newest included): a run grows with
    probability 1 - H times the observation's predictive density under the run's posterior, and
    a new run starts with probability H times its density under the prior predictive (the
    newest observation is the new segment's first, so r = 1 means "changed just before it").
    The support is truncated at max_run: the mass of longer runs is dropped and the rest
    renormalised, so that each update costs O(max_run) whatever the time."""

    def __init__(self, hazard, sigma, prior_sd, max_run):
        self.log_hazard = math.log(hazard)
        self.log_continue = math.log1p(-hazard)
        self.var = sigma * sigma
        self.prior_var = prior_sd * prior_sd
        self.max_run = int(max_run)
        self.start(0.0)

    def start(self, mu0):
        """Forgets every observation; new segments' means are drawn around mu0."""
        self.mu0 = float(mu0)
        self.log_w = np.zeros(0)  # log P(r | y_1..t), r = 1..len
        self.sums = np.zeros(0)   # sum of the last r observations
        self.runs = np.zeros(0)   # r
        self.count = 0

    def _log_predictive(self, y):
        """log p(y | the last r observations) for every kept run length r."""
        precision = 1.0 / self.prior_var + self.runs / self.var
        mean = (self.mu0 / self.prior_var + self.sums / self.var) / precision
        var = 1.0 / precision + self.var
        return -0.5 * (np.log(2.0 * math.pi * var) + (y - mean) ** 2 / var)

    def update(self, y):
        """One observation: the run-length posterior after it."""
        var0 = self.prior_var + self.var
        new_run = -0.5 * (math.log(2.0 * math.pi * var0) + (y - self.mu0) ** 2 / var0)
        if self.count:
            grown = self.log_w + self._log_predictive(y) + self.log_continue
            log_w = np.concatenate(([new_run + self.log_hazard], grown))[:self.max_run]
        else:
            log_w = np.array([new_run])
        log_w -= log_w.max()
        log_w -= math.log(np.exp(log_w).sum())
        self.log_w = log_w
        self.sums = np.concatenate(([y], self.sums + y))[:self.max_run]
        self.runs = np.arange(1.0, len(log_w) + 1.0)
        self.count += 1

    def map_run(self):
        """The most probable run length (observations in the current segment)."""
        return int(np.argmax(self.log_w)) + 1

    def segment_mean(self, run):
        """Posterior mean of the segment mean, given that the segment holds the last `run`."""
        precision = 1.0 / self.prior_var + run / self.var
        return (self.mu0 / self.prior_var + float(self.sums[run - 1]) / self.var) / precision


class ChangePointRecognizer(Recognizer):
    """Change-point recognizer: Bayesian online change-point detection (BOCPD; Adams and MacKay
    2007, arXiv:0710.3742; RunLengthPosterior) on the block means of `pre_average` raw samples
    (50, as the paper's recognizer averages), with a segment logic on relative levels.

    Observations: y = log(max(block mean, contact_n / 2)), so that a change of the force by a
    factor is a shift of the same size at every spindle speed (forces are lower at higher
    speed), and the detector's noise `sigma` is relative (0.05: about 5 %). Each segment's mean
    is unknown (Normal prior of sd `prior_sd` around the first block in contact); the variance
    is known; the hazard is constant (`hazard` per block, 1/mean segment length); the
    run-length posterior is truncated at `max_run` blocks.

    The current segment is the one of the most probable (MAP) run length; its level is the
    posterior mean of its mean (exp of it, in N); a segment counts only once it holds `min_run`
    blocks (a one-block dip of a breathing contact is no layer). Segment logic: idle until a
    block mean exceeds `contact_n` (contact: the detector starts); outer cortical, its level the
    highest segment level seen; a segment that begins after the peak's segment with a level
    below `cancellous_ratio` x the outer level: cancellous bone; a segment that begins after the
    one current on entering the cancellous bone (a detected change) with a level above
    `inner_ratio` x the outer level and above the lowest cancellous level: the inner cortex,
    once that holds for `confirm` consecutive blocks. Then the stop, latched until reset.

    The outer cortex is the reference because the inner cortex is cut with about the outer
    layer's force (the paper's recognizer normalises by the same amplitude, D); a rise above
    the cancellous minimum alone also fires on the cancellous bone's own density changes.
    The defaults of hazard, min_run, cancellous_ratio, inner_ratio, sigma and confirm are the
    ones `tune` chose on a dataset of `campaign_dataset --trials 40 --rpm 12000,16000,20000`
    (best 5 of 324 combinations on train, chosen on validation: calibration seeds of base seed
    3201 only; its test split was never read)."""

    PARAMETERS = {
        'pre_average': (int, 50, at_least(1)),
        'contact_n': (float, 0.3, positive),
        'hazard': (float, 0.02, fraction),
        'sigma': (float, 0.05, positive),
        'prior_sd': (float, 1.0, positive),
        'max_run': (int, 100, at_least(2)),
        'cancellous_ratio': (float, 0.5, fraction),
        'inner_ratio': (float, 0.7, lambda v: math.isfinite(v) and 0 < v <= 2),
        'min_run': (int, 2, at_least(1)),
        'confirm': (int, 1, at_least(1)),
    }

    def reset(self):
        p = self.params
        self.detector = RunLengthPosterior(p['hazard'], p['sigma'], p['prior_sd'], p['max_run'])
        self.block_mean = BlockMean(p['pre_average'])
        self.blocks = 0  # blocks since contact
        self.state = 'idle'
        self.outer_level = 0.0
        self.peak_start = 0
        self.cancellous_start = 0
        self.low = math.inf
        self.above = 0
        self.level = 0.0
        self.stopped_at = None

    def push(self, t, raw_force):
        mean = self.block_mean.add(raw_force)
        if mean is None:
            return {}
        if self.state == 'idle':
            if mean > self.params['contact_n']:
                self.detector.start(self._log(mean))
                self.state = 'outer_cortical'
                self._segment(t, mean)
        elif self.state != 'inner_cortical':
            self._segment(t, mean)
        return {'new_average': True, 'averaged_force': mean, 'feature': self.level,
                'state': self.state, 'layer_state': self.state,
                'last_key_point': KEY_POINTS[self.state], 'stop': self.state == 'inner_cortical'}

    def _log(self, mean):
        return math.log(max(mean, 0.5 * self.params['contact_n']))

    def _segment(self, t, mean):
        """One block after contact: the detector's update and the segment logic."""
        p = self.params
        self.detector.update(self._log(mean))
        self.blocks += 1
        run = self.detector.map_run()
        start = self.blocks - run  # blocks since contact before the current segment began
        self.level = math.exp(self.detector.segment_mean(run))
        if run < p['min_run']:
            self.above = 0  # a segment too short to tell a level
        elif self.state == 'outer_cortical':
            if self.level > self.outer_level:
                self.outer_level, self.peak_start = self.level, start
            elif start > self.peak_start and self.level < p['cancellous_ratio'] * self.outer_level:
                self.state, self.cancellous_start, self.low = 'cancellous', start, self.level
        elif self.state == 'cancellous':
            self.low = min(self.low, self.level)
            rises = (start > self.cancellous_start and self.level > self.low and
                     self.level > p['inner_ratio'] * self.outer_level)
            self.above = self.above + 1 if rises else 0
            if self.above >= p['confirm']:
                self.state, self.stopped_at = 'inner_cortical', t

    def stop_reason(self):
        return ('inner cortical layer reached (ChangePointRecognizer): a segment at %.3g N after '
                'the cancellous one, above %.2f x the outer level %.3g N, at t=%.3f s' % (
                    self.level, self.params['inner_ratio'], self.outer_level,
                    self.stopped_at or 0.0))
