"""The noise estimate and the trimming of a release's dead tail."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hystdisc.data import (
    Run,
    estimate_noise,
    trim_release,
)
from hystdisc.errors import HystdiscError


def test_estimate_noise_gaussian_within_10_percent():
    t = np.arange(6000) / 1000.0
    signal = 0.2 * np.exp(-0.5 * t) * np.cos(2 * np.pi * 1.5 * t)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        est = estimate_noise(signal + rng.normal(0, 1e-3, t.size), 1000.0)
        assert est == pytest.approx(1e-3, rel=0.10)


def test_estimate_noise_quantized_signal():
    t = np.arange(6000) / 1000.0
    q = 1e-3
    theta = np.round(np.exp(-0.3 * t) * np.cos(2 * np.pi * 1.5 * t) / q) * q
    assert estimate_noise(theta, 1000.0) == pytest.approx(q / math.sqrt(12), rel=0.15)


def test_estimate_noise_ignores_spikes_and_noiseless_is_zero():
    rng = np.random.default_rng(5)
    t = np.arange(5000) / 1000.0
    x = np.sin(2 * np.pi * t) + rng.normal(0, 1e-3, t.size)
    x[rng.integers(0, t.size, 5)] += 0.5
    assert estimate_noise(x, 1000.0) == pytest.approx(1e-3, rel=0.10)
    assert estimate_noise(1 + 2 * t + 0.5 * t**2) < 1e-12
    with pytest.raises(HystdiscError, match="too few"):
        estimate_noise(np.zeros(5))


def test_trim_release_cuts_dead_tail():
    rng = np.random.default_rng(1)
    t = np.arange(10000) / 1000.0
    theta = np.exp(-2.0 * t) * np.cos(2 * np.pi * 2 * t) + rng.normal(0, 1e-3, t.size)
    run = Run("0", t, theta, 0.0, theta_dot=np.zeros(t.size))
    short = trim_release(run, 1e-3)
    dies = math.log(1 / 3e-3) / 2.0  # amplitude reaches 3 noise std
    assert dies - 0.3 < short.duration < dies + 1.0
    assert short.theta_dot.size == short.n and run.n == 10000  # input untouched
    # a record that never settles is kept whole; a dead one keeps min_samples
    assert trim_release(Run("1", t, np.sin(t * 6) + theta, 0.0), 1e-3).n == 10000
    assert trim_release(Run("2", t, rng.normal(0, 1e-3, t.size), 0.0), 1e-3).n == 200
