"""Two 2026 baselines of the leaderboard (doc/leaderboard.md), Python recognizers (numpy only)
under their documented paths `python:pd_campaign.baselines.<Class>`:

- ``GaussianProcessRecognizer``: a model-free online Gaussian-process breakthrough detector (the
  IJCARS 2026 detector that beat thresholds with force and joint velocity), here with what the
  recognizer sees: the thrust, against the feed travelled since contact.
- ``ForceDropRecognizer``: a transient force-drop detector on the F/T signal (Zhu et al. 2026,
  about 1 mm of overdrill).

A recognizer is given the raw thrust and its time only (pd_campaign.recognizers); the feed is
the scenario's constant feed rate (0.5 mm/s, `feed_mm_s`), so the feed travelled since contact is
`feed_mm_s` times the time since contact: a depth proxy, not a measured joint velocity."""
import math

import numpy as np

from pd_campaign.checks import at_least, fraction, positive
from pd_campaign.offline import KEY_POINTS
from pd_campaign.recognizers import BlockMean, Recognizer


def gp_predict(x, y, x_new, length, signal_sd, noise_sd):
    """Posterior mean and standard deviation at `x_new` of a Gaussian process with a constant
    mean (the mean of `y`), a squared-exponential kernel (length scale `length`, signal sd
    `signal_sd`) and white noise `noise_sd`, fitted to (x, y); the sd includes the noise (the
    predictive distribution of a new observation)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    mean = y.mean()
    s2, n2 = signal_sd * signal_sd, noise_sd * noise_sd
    d = x[:, None] - x[None, :]
    k = s2 * np.exp(-0.5 * (d / length) ** 2) + n2 * np.eye(len(x))
    k_star = s2 * np.exp(-0.5 * ((x - x_new) / length) ** 2)
    chol = np.linalg.cholesky(k)
    alpha = np.linalg.solve(chol.T, np.linalg.solve(chol, y - mean))
    v = np.linalg.solve(chol, k_star)
    var = max(s2 + n2 - float(v @ v), n2)
    return mean + float(k_star @ alpha), math.sqrt(var)


class GaussianProcessRecognizer(Recognizer):
    """Online Gaussian-process detector: block means of `pre_average` raw samples (50, as the
    paper's recognizer averages), each against the feed travelled since contact (`feed_mm_s`
    times the time since the first block above `contact_n`). A GP with a constant mean, a
    squared-exponential kernel (`length_mm`) and white noise is fitted to the last `window`
    blocks but the newest `lead` and predicts the current one (a rise spread over the drill's
    cone, a few blocks long, is then a surprise, where a GP fitted up to the block before follows
    it); the signal and noise sds are estimated from the fitted blocks themselves (model-free:
    their sd and their successive differences' sd / sqrt 2, the noise at least `min_noise_n`). A block is a surprise when it lies more than `z` predictive sds from the
    prediction. Logic: idle until contact; outer cortex, its level the highest block mean; a
    surprising fall below `cancellous_ratio` x that level: the cancellous bone (the GP
    restarts there); then `confirm` consecutive surprising rises above `inner_ratio` x the outer
    level: the inner cortex, and the stop, latched until reset."""

    PARAMETERS = {
        'pre_average': (int, 50, at_least(1)),
        'contact_n': (float, 0.3, positive),
        'feed_mm_s': (float, 0.5, positive),
        'window': (int, 12, at_least(3)),
        'lead': (int, 4, at_least(0)),
        'length_mm': (float, 0.5, positive),
        'min_noise_n': (float, 0.03, positive),
        'z': (float, 2.5, positive),
        'cancellous_ratio': (float, 0.6, fraction),
        'inner_ratio': (float, 0.7, lambda v: math.isfinite(v) and 0 < v <= 2),
        'confirm': (int, 2, at_least(1)),
    }

    def reset(self):
        self.block_mean = BlockMean(self.params['pre_average'])
        self.state = 'idle'
        self.contact_t = None
        self.xs, self.ys = [], []
        self.outer_level = 0.0
        self.above = 0
        self.score = 0.0
        self.stopped_at = None

    def push(self, t, raw_force):
        mean = self.block_mean.add(raw_force)
        if mean is None:
            return {}
        if self.state == 'idle' and mean > self.params['contact_n']:
            self.state, self.contact_t = 'outer_cortical', t
        if self.state in ('outer_cortical', 'cancellous'):
            self._block(self.params['feed_mm_s'] * (t - self.contact_t), mean, t)
        return {'new_average': True, 'averaged_force': mean, 'feature': self.score,
                'state': self.state, 'layer_state': self.state,
                'last_key_point': KEY_POINTS[self.state], 'stop': self.state == 'inner_cortical'}

    def _surprise(self, x, y):
        """The block's standardized residual against the GP of the window but its newest `lead`
        blocks (0 while fewer than 3 remain)."""
        kept = len(self.ys) - self.params['lead']
        if kept < 3:
            return 0.0
        ys = np.asarray(self.ys[:kept])
        noise = max(self.params['min_noise_n'], float(np.std(np.diff(ys))) / math.sqrt(2.0))
        signal = max(float(np.std(ys)), noise)
        mu, sd = gp_predict(self.xs[:kept], ys, x, self.params['length_mm'], signal, noise)
        return (y - mu) / sd

    def _block(self, x, y, t):
        p = self.params
        self.score = self._surprise(x, y)
        if self.state == 'outer_cortical':
            self.outer_level = max(self.outer_level, y)
            if self.score < -p['z'] and y < p['cancellous_ratio'] * self.outer_level:
                self.state, self.xs, self.ys = 'cancellous', [], []
        elif self.state == 'cancellous':
            rises = self.score > p['z'] and y > p['inner_ratio'] * self.outer_level
            self.above = self.above + 1 if rises else 0
            if self.above >= p['confirm']:
                self.state, self.stopped_at = 'inner_cortical', t
                return
            if rises:
                return  # a surprise is not learned as the cancellous bone's level
        self.xs.append(x)
        self.ys.append(y)
        del self.xs[:-p['window']], self.ys[:-p['window']]

    def stop_reason(self):
        return ('inner cortical layer reached (GaussianProcessRecognizer): %d block means more '
                'than %.3g predictive sds above the online GP, at t=%.3f s' % (
                    self.params['confirm'], self.params['z'], self.stopped_at or 0.0))


class ForceDropRecognizer(Recognizer):
    """Transient force-drop detector on the F/T thrust (Zhu et al. 2026): a moving average of
    `window` raw samples; a transient drop is the average falling by more than `drop_ratio` of
    its running peak (a peak above `contact_n`) within `drop_time_s` of that peak. The first
    drop that the average then stays below for `hold` samples is the outer cortex's breakthrough
    into the cancellous bone (a shorter dip is the compensated drill's ripple in the outer
    cortex, not a layer). `stop_on`: `drop` stops
    at the next drop, the inner cortex's breakthrough (the detector as published: a
    breakthrough detector, late for this task's stop layer); `recovery` stops when the average
    after the first drop recovers to `recovery_ratio` x the first drop's peak for `confirm`
    consecutive samples (the inner cortex's entry). Moving-average values are published every
    `window` samples."""

    PARAMETERS = {
        'window': (int, 15, at_least(1)),
        'contact_n': (float, 0.3, positive),
        'drop_ratio': (float, 0.3, fraction),
        'drop_time_s': (float, 1.0, positive),
        'hold': (int, 150, at_least(1)),
        'stop_on': (str, 'recovery', lambda v: v in ('drop', 'recovery')),
        'recovery_ratio': (float, 0.8, lambda v: math.isfinite(v) and 0 < v <= 2),
        'confirm': (int, 30, at_least(1)),
    }

    def reset(self):
        self.buffer = []
        self.sum = 0.0
        self.samples = 0
        self.state = 'idle'
        self.peak, self.peak_t = 0.0, None
        self.first_peak = None
        self.drop_peak = None  # the peak of a first drop not yet held for `hold` samples
        self.below = 0
        self.above = 0
        self.average = 0.0
        self.stopped_at = None

    def push(self, t, raw_force):
        p = self.params
        self.buffer.append(raw_force)
        self.sum += raw_force
        if len(self.buffer) > p['window']:
            self.sum -= self.buffer.pop(0)
        self.samples += 1
        if len(self.buffer) < p['window'] or self.state == 'inner_cortical':
            return {}
        self.average = self.sum / len(self.buffer)
        self._sample(t, self.average)
        if self.samples % p['window'] and self.state != 'inner_cortical':
            return {}
        return {'new_average': True, 'averaged_force': self.average, 'state': self.state,
                'layer_state': self.state, 'last_key_point': KEY_POINTS[self.state],
                'stop': self.state == 'inner_cortical'}

    def _dropped(self, t, average):
        """Tracks the running peak; true at a transient drop (the peak then restarts)."""
        if average >= self.peak:
            self.peak, self.peak_t = average, t
            return False
        if (self.peak > self.params['contact_n']
                and average < (1.0 - self.params['drop_ratio']) * self.peak
                and t - self.peak_t <= self.params['drop_time_s']):
            return True
        if t - self.peak_t > self.params['drop_time_s']:
            # The peak is too old for a transient drop: it decays to the level of the window.
            self.peak, self.peak_t = average, t
        return False

    def _sample(self, t, average):
        p = self.params
        if self.state == 'idle' and average > p['contact_n']:
            self.state = 'outer_cortical'
        if self.state == 'outer_cortical':
            self._first_drop(t, average)
        elif self.state == 'cancellous':
            if p['stop_on'] == 'drop':
                done = self._dropped(t, average) and self.peak > p['recovery_ratio'] * \
                    self.first_peak
            else:
                self.above = self.above + 1 if average > p['recovery_ratio'] * \
                    self.first_peak else 0
                done = self.above >= p['confirm']
            if done:
                self.state, self.stopped_at = 'inner_cortical', t

    def _first_drop(self, t, average):
        """The outer cortex: a transient drop, then `hold` samples below its level."""
        if self.drop_peak is not None:
            if average < (1.0 - self.params['drop_ratio']) * self.drop_peak:
                self.below += 1
            else:
                self.drop_peak = None  # a dip, not the cancellous bone: the peak goes on
        else:
            peak = self.peak
            if self._dropped(t, average):
                self.drop_peak, self.below = peak, 1
        if self.drop_peak is not None and self.below >= self.params['hold']:
            self.state, self.first_peak = 'cancellous', self.drop_peak
            self.peak, self.peak_t = average, t

    def stop_reason(self):
        what = ('a second transient force drop (the inner cortex\'s breakthrough)'
                if self.params['stop_on'] == 'drop' else
                'the thrust back at %.2f x the first drop\'s peak %.3g N'
                % (self.params['recovery_ratio'], self.first_peak or 0.0))
        return 'inner cortical layer reached (ForceDropRecognizer): %s, at t=%.3f s' % (
            what, self.stopped_at or 0.0)
