"""core/imu_errors.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the discretizations and the random-number layout of docs/theory/imu_errors.md
(Gauss–Markov and rate random walk over the first cycles, from the documented PCG64 draws), the
closed form of ``rate_noise_variance``, and ``skip`` against ``apply`` on the same draws.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from strapdown_ros.core.imu_errors import (
    NORMALS_PER_SAMPLE,
    ImuErrorModel,
    ImuErrorParameters,
    SensorErrors,
)

T = 0.01


def _gyro(**kw) -> ImuErrorParameters:
    z = SensorErrors.zero()
    return ImuErrorParameters(SensorErrors(**(z.__dict__ | kw)), SensorErrors.zero(), seed=11)


def _draws(seed: int, cycles: int):
    """The documented layout: a (2, 15) block at construction, then 30 normals per cycle."""
    rng = np.random.Generator(np.random.PCG64(seed))
    unit = rng.standard_normal((2, 15))
    return unit, rng.standard_normal((cycles, NORMALS_PER_SAMPLE))


def test_gauss_markov_first_cycles_follow_the_documented_discretization():
    sigma, tau = np.array([1e-4, 2e-4, 3e-4]), np.array([0.05, 1.0, 20.0])
    p = _gyro(bias_instability=np.ones(3), correlation_time_s=tau)
    scale = p.gyro.gauss_markov_sigma  # σ per unit B
    p = _gyro(bias_instability=sigma / scale, correlation_time_s=tau)
    out, _ = ImuErrorModel(p, T).apply(np.zeros((2, 3)), np.zeros((2, 3)))
    unit, z = _draws(11, 2)
    x = T / tau
    phi = math.e ** -x
    var1 = sigma**2 * (1 - phi**2)
    cov = sigma**2 * tau * (1 - phi) ** 2
    # the bracket cancels for small x: evaluated in 40-digit arithmetic
    mpmath.mp.dps = 40
    h = np.array([float(xi - 2 * (1 - mpmath.exp(-xi)) + (1 - mpmath.exp(-2 * xi)) / 2)
                  for xi in map(mpmath.mpf, x)])  # fmt: skip
    var2 = 2 * sigma**2 * tau**2 * h
    b = sigma * unit[0, 12:15]
    for k in range(2):
        xi1, xi2 = z[k, 3:6], z[k, 6:9]
        eta = [np.linalg.cholesky([[var1[i], cov[i]], [cov[i], var2[i]]]) @ [xi1[i], xi2[i]]
               for i in range(3)]  # fmt: skip
        eta1, eta2 = np.array(eta).T
        # measured: 3.8e-12 relative (the model's series below x = 1e-3); bound 10x
        np.testing.assert_allclose(out[k], tau * (1 - phi) * b + eta2, rtol=4e-11, atol=0)
        b = phi * b + eta1


def test_rate_random_walk_first_cycles_follow_the_documented_discretization():
    k_rw = np.array([1e-3, 2e-3, 5e-3])
    out, _ = ImuErrorModel(_gyro(random_walk=k_rw), T).apply(np.zeros((3, 3)), np.zeros((3, 3)))
    _, z = _draws(11, 3)
    b = np.zeros(3)
    for k in range(3):
        xi1, xi2 = z[k, 9:12], z[k, 12:15]
        expected = b * T + k_rw * T**1.5 * (xi1 / 2 + xi2 / (2 * math.sqrt(3)))
        np.testing.assert_allclose(out[k], expected, rtol=6e-15, atol=0)  # measured 6.3e-16
        b = b + k_rw * math.sqrt(T) * xi1


def test_rate_noise_variance_closed_form():
    """``N²/T + q²/(6 T²)`` per axis, gyros then accelerometers."""
    zero = SensorErrors.zero()
    gyro = SensorErrors(**(zero.__dict__ | {"white": np.array([1e-3, 2e-3, 3e-3]),
                                            "quantum": np.array([1e-6, 0.0, 2e-6])}))  # fmt: skip
    accel = SensorErrors(**(zero.__dict__ | {"white": np.array([0.01, 0.0, 0.02]),
                                             "quantum": np.array([0.0, 1e-3, 1e-3])}))  # fmt: skip
    g, a = ImuErrorModel(ImuErrorParameters(gyro, accel), 0.005).rate_noise_variance()
    np.testing.assert_allclose(g, [1e-6 / 0.005 + 1e-12 / 1.5e-4, 4e-6 / 0.005,
                                   9e-6 / 0.005 + 4e-12 / 1.5e-4], rtol=1e-14)  # fmt: skip
    np.testing.assert_allclose(a, [1e-4 / 0.005, 1e-6 / 1.5e-4, 4e-4 / 0.005 + 1e-6 / 1.5e-4],
                               rtol=1e-14)  # fmt: skip


def test_perfect_parameters_keep_the_seed():
    assert ImuErrorParameters.perfect().seed == 0
    assert ImuErrorParameters.perfect(5).seed == 5


def test_skip_gives_later_cycles_the_noise_they_would_have_had():
    p = _gyro(white=np.array([1e-3, 2e-3, 3e-3]), random_walk=np.array([1e-3, 0.0, 1e-3]))
    ideal = np.tile([1e-3, -2e-3, 3e-3], (4, 1))
    whole, _ = ImuErrorModel(p, T).apply(ideal, ideal)
    m = ImuErrorModel(p, T)
    first, _ = m.apply(ideal[:1], ideal[:1])
    m.skip(0)  # nothing
    m.skip(1)
    assert m.cycles == 2
    m.skip(0)
    last, _ = m.apply(ideal[2:], ideal[2:])
    assert m.cycles == 4
    assert np.array_equal(np.concatenate([first, last]), whole[[0, 2, 3]])


def test_skip_of_a_negative_count_is_refused():
    with pytest.raises(ValueError, match=r"^n must be >= 0, got -1$"):
        ImuErrorModel(ImuErrorParameters.perfect(), T).skip(-1)


def test_per_run_constants_follow_the_documented_draws():
    """Turn-on bias, scale factor and misalignment: fixed + σ × the construction draws."""
    sig = np.array([1e-3, 2e-3, 3e-3])
    p = _gyro(bias=np.array([0.1, 0.0, -0.1]), turn_on_bias_sigma=sig,
              scale_factor=np.array([1e-4, 0.0, 0.0]), scale_factor_sigma=2 * sig,
              misalignment_sigma=np.full((3, 3), 1e-3))  # fmt: skip
    m = ImuErrorModel(p, T)
    unit, _ = _draws(11, 0)
    np.testing.assert_allclose(m.gyro_bias, [0.1, 0.0, -0.1] + sig * unit[0, 0:3], rtol=1e-15)
    mis = np.zeros((3, 3))
    for k, (i, j) in enumerate([(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]):
        mis[i, j] = 1e-3 * unit[0, 6 + k]
    expected = np.diag([1e-4, 0.0, 0.0] + 2 * sig * unit[0, 3:6]) + mis
    np.testing.assert_allclose(m.gyro_error_matrix, expected, rtol=0, atol=1e-18)


@pytest.mark.parametrize("da,dv", [((2, 3), (2, 2)), ((2, 4), (2, 4)), ((3,), (3,))])
def test_increments_of_other_shapes_are_refused(da, dv):
    m = ImuErrorModel(ImuErrorParameters.perfect(), T)
    with pytest.raises(ValueError, match=r"^dalpha and dv must both have shape \(n, 3\), got "):
        m.apply(np.zeros(da), np.zeros(dv))


@pytest.mark.parametrize("period", [0.0, -0.01, math.inf, math.nan])
def test_period_must_be_finite_and_positive(period):
    with pytest.raises(ValueError, match=r"^period_s must be finite and > 0, got "):
        ImuErrorModel(ImuErrorParameters.perfect(), period)


def test_misalignment_matrix_needs_six_values():
    from strapdown_ros.core.imu_errors import misalignment_matrix

    with pytest.raises(ValueError, match=r"^expected 6 values, got shape \(5,\)$"):
        misalignment_matrix(np.zeros(5))


def test_range_below_one_saturates_only_its_axis():
    """x axis limited to 0.5 rad/s, y and z unlimited (range 0): 2 rad/s in on every axis."""
    p = _gyro(range=np.array([0.5, 0.0, 0.0]))
    out, _ = ImuErrorModel(p, T).apply(np.full((2, 3), 2.0 * T), np.zeros((2, 3)))
    np.testing.assert_allclose(out, np.tile([0.5 * T, 2.0 * T, 2.0 * T], (2, 1)), rtol=1e-15)


def test_gauss_markov_on_one_axis_leaves_the_others_exact():
    p = _gyro(bias_instability=np.array([1e-4, 0.0, 0.0]), correlation_time_s=np.ones(3))
    out, _ = ImuErrorModel(p, T).apply(np.zeros((3, 3)), np.zeros((3, 3)))
    assert np.all(out[:, 0] != 0) and np.all(out[:, 1:] == 0)


def test_gauss_markov_integral_factor_series_against_mpmath():
    """``h(x) = x − 2(1 − e^{−x}) + (1 − e^{−2x})/2`` in 40-digit arithmetic, on the series side
    of the switch (x < 1e-3: measured 9.1e-11 relative at x = 9e-4, the x⁶ term left out)
    and on the direct side."""
    from strapdown_ros.core.imu_errors import _gm_integral_factor

    mpmath.mp.dps = 40
    for x, rtol in ((1e-5, 1e-14), (3e-4, 1e-10), (9e-4, 1e-9), (2e-3, 1e-9), (0.1, 1e-13)):
        xm = mpmath.mpf(x)
        ref = float(xm - 2 * (1 - mpmath.exp(-xm)) + (1 - mpmath.exp(-2 * xm)) / 2)
        got = float(_gm_integral_factor(np.array([x]))[0])
        assert abs(got / ref - 1) < rtol, (x, got / ref - 1)


def test_g_sensitivity_of_all_ones_is_applied():
    """Gyro error ``G Δv``: with every element of G equal to 1 it is the sum of Δv's components."""
    out, _ = ImuErrorModel(_gyro(g_sensitivity=np.ones((3, 3))), T).apply(
        np.zeros((1, 3)), np.array([[1.0, 2.0, 3.0]])
    )
    np.testing.assert_array_equal(out[0], [6.0, 6.0, 6.0])
