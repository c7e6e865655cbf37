"""core/aiding/common.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the sampled Gauss–Markov recursion of docs/aiding.md written out here
(``x_0 = σ ξ_init``, ``x_{k+1} = φ x_k + σ √(1 − φ²) ξ_k``, ``φ = e^{−P/τ}``) in float64 from the
given parameters, hand-built epoch stamps, and the functions' exact error messages.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from strapdown_ros.core.aiding.common import GaussMarkov, check_period, epoch_mask, sensor_rng


def _recursion(sigma: float, tau: float, period: float, x0: float, xi: np.ndarray) -> np.ndarray:
    phi = math.exp(-period / tau)
    x, out = sigma * x0, []
    for k in range(len(xi)):
        out.append(x)
        x = phi * x + sigma * math.sqrt(1.0 - phi**2) * xi[k]
    return np.array(out)


def test_gauss_markov_values_are_the_documented_recursion():
    """First value ``σ ξ_init`` (not ``σ / ξ_init``); τ below 1 s; a float32 τ taken in float64."""
    sigma, period, init = np.array([1.5, 0.25]), 0.1, np.array([0.8, -1.3])
    xi = np.random.default_rng(1).standard_normal((6, 2))
    for tau in (np.array([0.3, 7.0]), np.array([0.3, 7.0], dtype=np.float32)):
        out = GaussMarkov(sigma, tau, period, init).take(xi)
        for j in range(2):
            expected = _recursion(sigma[j], float(tau[j]), period, init[j], xi[:, j])
            np.testing.assert_allclose(out[:, j], expected, rtol=0, atol=1e-14)


def test_gauss_markov_float32_sigma_variance_in_float64():
    s = np.array([0.1, 0.2], dtype=np.float32)
    var = GaussMarkov(s, [1.0, 1.0], 0.5, [0.0, 0.0]).variance
    assert var.dtype == np.float64
    np.testing.assert_array_equal(var, s.astype(np.float64) ** 2)


def test_gauss_markov_zero_sigma_needs_no_tau_and_tau_checked_where_sigma_positive():
    out = GaussMarkov([0.0, 1.0], [0.0, 2.0], 1.0, [0.5, 0.5]).take(np.ones((3, 2)))
    assert np.all(out[:, 0] == 0) and out[0, 1] == 0.5
    with pytest.raises(ValueError) as err:
        GaussMarkov([1.0], [0.0], 1.0, [0.0])
    assert str(err.value) == "a Gauss–Markov process with sigma > 0 needs tau > 0"


def test_gauss_markov_take_of_no_epoch_leaves_the_state():
    gm = GaussMarkov([2.0], [5.0], 1.0, [0.75])
    assert gm.take(np.zeros((0, 1))).shape == (0, 1)
    assert gm.take(np.zeros((1, 1)))[0, 0] == 1.5


def test_check_period_bounds_and_message():
    assert check_period(0.25) == 0.25
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError) as err:
            check_period(bad)
        assert str(err.value) == f"period_s must be finite and > 0, got {bad}"


def test_sensor_rng_rejects_a_negative_seed():
    with pytest.raises(ValueError) as err:
        sensor_rng(-1, "gnss")
    assert str(err.value) == "seed must be >= 0, got -1"


def test_epoch_mask_marks_multiples_of_the_period():
    stamps = [1_700_000_000_000_000_000, 1_700_000_000_250_000_000, 1_700_000_000_500_000_001,
              1_700_000_001_000_000_000, 1_700_000_000_750_000_000]  # fmt: skip
    np.testing.assert_array_equal(epoch_mask(stamps, 250_000_000), [1, 1, 0, 1, 1])
    np.testing.assert_array_equal(epoch_mask(stamps, 500_000_000), [1, 0, 0, 1, 0])
