"""core/allan.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the overlapping Allan variance from its definition with cluster averages
(IEEE Std 952 / 1554: ``σ²(τ) = Σ (ȳ_{k+m} − ȳ_k)² / (2 (M − 2m + 1))``) written as loops here,
cluster-size grids from ``10^(k/10)`` rounded by hand, and log-log interpolation on a hand-built
piecewise power law read at geometric midpoints (``√(σ_a σ_b)``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from strapdown_ros.core.allan import (
    default_cluster_sizes,
    overlapping_allan_deviation,
    rate_random_walk,
    white_noise_coefficient,
)


def _adev_definition(y: np.ndarray, m: int) -> float:
    """Overlapping Allan deviation of rate samples y (float64 loops over cluster averages)."""
    y = np.asarray(y, dtype=np.float64)
    avg = [math.fsum(y[k : k + m]) / m for k in range(y.size - m + 1)]
    terms = [(avg[k + m] - avg[k]) ** 2 for k in range(y.size - 2 * m + 1)]
    return math.sqrt(math.fsum(terms) / (2 * len(terms)))


def test_default_cluster_sizes_ten_per_decade_to_a_third():
    """M = 300: 21 points ``10^(k/10)``, k = 0..20, rounded and made distinct."""
    expected = [1, 2, 3, 4, 5, 6, 8, 10, 13, 16, 20, 25, 32, 40, 50, 63, 79, 100]
    got = default_cluster_sizes(300)
    assert got.dtype == np.int64
    assert got.tolist() == expected
    # the fraction is capped at 1/2: M = 20 with 0.9 gives m_max = 10 (10^(k/10), k = 0..10)
    assert default_cluster_sizes(20, max_fraction=0.9).tolist() == [1, 2, 3, 4, 5, 6, 8, 10]
    assert default_cluster_sizes(3).tolist() == [1]
    empty = default_cluster_sizes(2)
    assert empty.shape == (0,) and empty.dtype == np.int64


def test_overlapping_adev_is_the_cluster_average_definition_for_float32_rates():
    """float32 rates are taken in float64 (a float32 running sum would lose ~1e-7)."""
    rng = np.random.default_rng(5)
    y = (0.3 + rng.standard_normal(400)).astype(np.float32)
    taus, adev = overlapping_allan_deviation(y, 0.01, [1, 7, 50, 200])
    np.testing.assert_allclose(taus, [0.01, 0.07, 0.5, 2.0], rtol=1e-15)
    for got, m in zip(adev, [1, 7, 50, 200], strict=True):
        assert abs(got / _adev_definition(y, m) - 1) < 1e-10, m


def test_overlapping_adev_cluster_size_bounds_and_messages():
    y = np.random.default_rng(2).standard_normal(10)
    taus, adev = overlapping_allan_deviation(y, 1.0, [5])  # M // 2: the largest allowed
    assert abs(adev[0] / _adev_definition(y, 5) - 1) < 1e-12
    taus, adev = overlapping_allan_deviation(y, 1.0, 2)  # a single size as a scalar
    assert taus.tolist() == [2.0] and abs(adev[0] / _adev_definition(y, 2) - 1) < 1e-12
    with pytest.raises(ValueError) as err:
        overlapping_allan_deviation(np.zeros(11), 1.0, [6])
    assert str(err.value) == "cluster sizes must be within 1..5 for M = 11"
    with pytest.raises(ValueError) as err:
        overlapping_allan_deviation(np.zeros((2, 2, 2)), 1.0)
    assert str(err.value) == "rate must have shape (M,) or (M, k), got (2, 2, 2)"


TAUS = np.array([1.0, 3.0, 10.0, 30.0, 100.0])
ADEV = np.array([4.0, 2.0, 1.0, 2.0, 8.0])  # slopes change at every point


def test_white_noise_coefficient_reads_at_one_second_by_default():
    assert white_noise_coefficient(TAUS, ADEV) == pytest.approx(4.0, rel=1e-15)  # τ = t[0]
    # float32 values are interpolated in float64
    n = white_noise_coefficient(TAUS, ADEV.astype(np.float32), tau_s=math.sqrt(3.0))
    assert abs(n / (math.sqrt(8.0) * 3.0**0.25) - 1) < 1e-14


def test_rate_random_walk_reads_at_three_seconds_by_default_and_scales_by_root_three_over_tau():
    assert rate_random_walk(TAUS, ADEV) == pytest.approx(2.0, rel=1e-15)
    # at t[-1] = 100 s: σ √(3/100)
    k = rate_random_walk(TAUS, ADEV, tau_s=100.0)
    assert k == pytest.approx(8.0 * math.sqrt(0.03), rel=1e-14)


@pytest.mark.parametrize("segment", range(4))
def test_log_interp_at_geometric_midpoints_of_each_segment(segment):
    """On a piecewise power law the value at ``√(τ_a τ_b)`` is ``√(σ_a σ_b)``."""
    tau = math.sqrt(TAUS[segment] * TAUS[segment + 1])
    want = math.sqrt(ADEV[segment] * ADEV[segment + 1]) * math.sqrt(tau)
    assert abs(white_noise_coefficient(TAUS, ADEV, tau_s=tau) / want - 1) < 1e-14


def test_log_interp_range_and_message():
    with pytest.raises(ValueError) as err:
        white_noise_coefficient(TAUS, ADEV, tau_s=0.5)
    assert str(err.value) == "τ = 0.5 s is outside the computed range [1.0, 100.0] s"
