"""The two 2026 baselines (pd_campaign.detectors): the online Gaussian-process detector and the
transient force-drop detector on synthetic force profiles: a stop inside the inner cortex (the
force-drop detector as published: just after the inner cortex's drop), none on a flat
cancellous profile; their parameters are declared and checked by name."""
import math

import numpy as np
import pytest

from pd_campaign.baselines import ForceDropRecognizer, GaussianProcessRecognizer
from pd_campaign.detectors import gp_predict
from pd_campaign.offline import configured, offline_stop

RATE_HZ = 1000.0 / 3.0  # the simulated DAQ's rate
FEED_MM_S = 0.5


def layered_profile(scale, rng, noise=0.05):
    """(t, force, layer): 2 s of air, 2 mm of outer cortex (3 N x scale), 4 mm of cancellous
    bone (1 N x scale with a slow 15 % wobble), 2 mm of inner cortex (2.9 N x scale), then the
    canal (0 N), at 0.5 mm/s, with short ramps between the layers and white noise."""
    pieces = [(2.0, 0, 0.0), (2.0 / FEED_MM_S, 1, 3.0), (4.0 / FEED_MM_S, 2, 1.0),
              (2.0 / FEED_MM_S, 3, 2.9), (2.0, 4, 0.0)]
    level, layer = [], []
    for seconds, label, force in pieces:
        n = int(round(seconds * RATE_HZ))
        level.append(np.full(n, scale * force))
        layer.append(np.full(n, label))
    level, layer = np.concatenate(level), np.concatenate(layer)
    t = np.arange(len(level)) / RATE_HZ
    wobble = 1.0 + 0.15 * np.sin(2.0 * math.pi * t / 2.5) * (layer == 2)
    kernel = np.ones(60) / 60.0  # 0.18 s ramps after each boundary: the cone crossing it
    smooth = np.convolve(np.pad(level, (59, 0), mode='edge'), kernel, mode='valid')
    return t, smooth * wobble + rng.normal(0.0, noise, len(t)), layer


def flat_profile(rng, seconds=25.0, noise=0.05):
    """Contact, then a flat cancellous-like thrust of 1 N with its wobble: no inner cortex."""
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    force = np.where(t < 1.0, 0.0, 1.0 + 0.15 * np.sin(2.0 * math.pi * t / 2.5))
    return t, force + rng.normal(0.0, noise, len(t))


def stop_of(cls, settings, t, force):
    return offline_stop(configured(cls, settings), t, force)


@pytest.mark.parametrize('scale', [0.6, 1.0, 1.4])
def test_the_gaussian_process_detector_stops_in_the_inner_cortex(scale):
    t, force, layer = layered_profile(scale, np.random.default_rng(1))
    stop = stop_of(GaussianProcessRecognizer, {}, t, force)
    assert stop is not None and layer[stop] == 3
    # Within the first millimetre of the inner cortex.
    entry = int(np.argmax(layer == 3))
    assert t[stop] - t[entry] < 1.0 / FEED_MM_S


@pytest.mark.parametrize('scale', [0.6, 1.0, 1.4])
def test_the_force_drop_detector_stops_after_the_drop_or_at_the_recovery(scale):
    t, force, layer = layered_profile(scale, np.random.default_rng(2))
    # As published: the second transient drop, the inner cortex's breakthrough; a stop just
    # after it (within 0.5 s: 0.25 mm of feed).
    stop = stop_of(ForceDropRecognizer, {'stop_on': 'drop'}, t, force)
    exit_ = int(np.argmax(layer == 4))
    assert stop is not None and layer[stop] == 4 and t[stop] - t[exit_] < 0.5
    # Adapted: the recovery after the first drop, the inner cortex's entry.
    stop = stop_of(ForceDropRecognizer, {'stop_on': 'recovery'}, t, force)
    assert stop is not None and layer[stop] == 3


@pytest.mark.parametrize('cls,settings', [
    (GaussianProcessRecognizer, {}), (ForceDropRecognizer, {'stop_on': 'drop'}),
    (ForceDropRecognizer, {'stop_on': 'recovery'})])
def test_no_stop_on_a_flat_cancellous_profile(cls, settings):
    for seed in range(3):
        t, force = flat_profile(np.random.default_rng(seed))
        assert stop_of(cls, settings, t, force) is None


def test_the_outputs_follow_the_contract_and_reset_starts_a_trial():
    t, force, layer = layered_profile(1.0, np.random.default_rng(3))
    for recognizer in (GaussianProcessRecognizer(), ForceDropRecognizer()):
        first = offline_stop(recognizer, t, force)
        second = offline_stop(recognizer, t, force)
        assert first == second is not None
        out = recognizer.push(t[-1], force[-1])
        assert set(out) <= {'state', 'layer_state', 'new_average', 'averaged_force', 'feature',
                            'last_key_point', 'stop'}
        assert 'inner cortical layer reached' in recognizer.stop_reason()


def test_parameters_are_declared_and_refused_by_name():
    assert 'length_mm' in GaussianProcessRecognizer().parameter_names()
    with pytest.raises(ValueError, match='^z:'):
        configured(GaussianProcessRecognizer, {'z': '-1'})
    with pytest.raises(ValueError, match='^stop_on:'):
        configured(ForceDropRecognizer, {'stop_on': 'later'})
    with pytest.raises(ValueError, match='^nope:'):
        configured(ForceDropRecognizer, {'nope': '1'})


def test_the_gaussian_process_interpolates_and_widens_away_from_its_data():
    x = np.linspace(0.0, 1.0, 11)
    y = np.sin(x)
    mu, sd = gp_predict(x, y, 0.5, 0.3, 0.5, 0.01)
    assert abs(mu - math.sin(0.5)) < 0.01 and sd < 0.05
    _, far = gp_predict(x, y, 3.0, 0.3, 0.5, 0.01)
    assert far > 0.4
