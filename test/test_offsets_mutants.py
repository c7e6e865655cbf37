"""core/offsets.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values are closed forms (sinusoids, the triangle sweep, ``Rz(az) Ry(el)`` from
scipy.spatial.transform) or 40-digit mpmath products rounded once to float64.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strapdown_ros.core.offsets import (
    OffsetModel,
    RandomBending,
    RasterScan,
    SegmentsScan,
    Sinusoids,
    SweepScan,
    _axis_rotation,
    bending_sinusoids,
)

mpmath.mp.dps = 40


def _one_term(amplitude=(1.0, 2.0, 3.0), frequency=1.0, phase=0.0) -> Sinusoids:
    return Sinusoids(
        np.array([amplitude], dtype=float), np.full((1, 3), frequency), np.full((1, 3), phase)
    )


# -- Sinusoids, bending_sinusoids ----------------------------------------------------------------


def test_sinusoids_take_times_of_any_shape_as_one_row_each():
    s = _one_term()
    # t = 1/4 s at 1 Hz: sin(pi/2) = 1, the amplitude itself
    np.testing.assert_allclose(s(0.25), [[1.0, 2.0, 3.0]], rtol=1e-15)
    t = np.array([[0.0, 0.25], [0.5, 0.75]])
    expected = np.sin(2 * np.pi * t.reshape(-1))[:, None] * [1.0, 2.0, 3.0]
    np.testing.assert_allclose(s(t), expected, rtol=0, atol=1e-15)


def test_sinusoids_with_unequal_term_counts_are_rejected():
    bad = Sinusoids(np.ones((2, 3)), np.ones((1, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        bad(np.zeros(3))


def test_no_bending_is_zero_terms_of_three_axes():
    b = bending_sinusoids()
    assert b.amplitude.shape == b.frequency.shape == b.phase.shape == (0, 3)
    assert np.array_equal(OffsetModel(lever_arm=np.array([1.0, 2.0, 3.0])).lever_arm_at([0.5]),
                          [[1.0, 2.0, 3.0]])  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1, 7])
def test_random_bending_one_frequency_per_sub_band_and_phases_in_a_turn(seed):
    """Component k has its frequency in (k B/K, (k+1) B/K] and a phase in [0, 2π)."""
    K, B = 16, 5.0
    b = bending_sinusoids(random=RandomBending(np.array([1.0, 2.0, 3.0]), B, seed, K))
    k = np.arange(K)[:, None]
    assert np.all(b.frequency > k * B / K) and np.all(b.frequency <= (k + 1) * B / K)
    assert np.all(b.phase >= 0.0) and np.all(b.phase < 2 * np.pi)
    # 48 uniform phases: some in each half turn (all below π: probability 2^-48)
    assert b.phase.min() < np.pi < b.phase.max()
    np.testing.assert_allclose(b.amplitude, np.tile([1.0, 2.0, 3.0], (K, 1)) * math.sqrt(2 / K),
                               rtol=1e-15)  # fmt: skip


# -- rotations evaluated in long double, rounded once -------------------------------------------


def _mp_axis_rotation(axis, angle):
    u = [mpmath.mpf(float(a)) for a in axis]
    n = mpmath.sqrt(sum(x * x for x in u))
    u = [x / n for x in u]
    s, c1 = mpmath.sin(mpmath.mpf(float(angle))), 1 - mpmath.cos(mpmath.mpf(float(angle)))
    k = [[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]]
    return mpmath.matrix(
        [[int(i == j) + s * k[i][j] + c1 * (u[i] * u[j] - int(i == j)) for j in range(3)]
         for i in range(3)]
    )  # fmt: skip


def _rounded(m) -> np.ndarray:
    return np.array([[float(m[i, j]) for j in range(3)] for i in range(3)])


@pytest.mark.skipif(np.finfo(np.longdouble).eps >= 1e-18, reason="long double is float64 here")
def test_axis_rotation_is_rounded_once_from_extended_precision():
    """Elements equal the correctly rounded Rodrigues matrix except in rare ties.

    Measured: 1 and 3 of 2709 elements differ by one ulp (axes below); evaluating sin θ or the
    unit axis in float64 makes about 40 % of them differ.
    """
    angles = np.linspace(-3.14, 3.14, 301)
    for axis in ([1.0, 2.0, 3.0], [0.3, -0.7, 0.2]):
        c = _axis_rotation(np.array(axis), angles).astype(np.float64)
        exact = np.array([_rounded(_mp_axis_rotation(axis, a)) for a in angles])
        assert np.sum(c != exact) <= 10  # 3x the measured 3


@pytest.mark.skipif(np.finfo(np.longdouble).eps >= 1e-18, reason="long double is float64 here")
def test_mounted_segment_scan_is_rounded_once():
    """``C_mount C_scan`` is formed in long double and rounded once (not the scan first)."""
    rph = np.array([0.3, -0.2, 1.1])
    rate = np.array([0.0, 0.0, 0.7])
    model = OffsetModel(mounting_rph=rph, scan=SegmentsScan(np.array([100.0]), rate[None, :]))
    period, cycles = 0.01, 200
    c = model.history(period, cycles).c_bvar_bref
    x, y, z = np.eye(3)
    mount = (_mp_axis_rotation(z, rph[2]) * _mp_axis_rotation(y, rph[1])
             * _mp_axis_rotation(x, rph[0]))  # fmt: skip
    speed = float(np.linalg.norm(rate))
    t = np.arange(cycles + 1) * period
    exact = np.array([_rounded(mount * _mp_axis_rotation(z, tm * speed)) for tm in t])
    # measured: 3 of 1809 elements; rounding the scan to float64 before the product: 421
    assert np.sum(c != exact) <= 10


def test_segments_with_unequal_lengths_are_rejected():
    scan = SegmentsScan(np.array([1.0, 2.0]), np.array([[0.0, 0.0, 0.1]]))
    with pytest.raises(ValueError):
        scan(np.linspace(0.0, 3.0, 4))


def test_zero_sweep_axis_message():
    with pytest.raises(ValueError, match=r"^axis: must not be zero$"):
        SweepScan(np.zeros(3), 0.1, 0.1)


# -- RasterScan ---------------------------------------------------------------------------------


def _rz_ry(az, el) -> np.ndarray:
    return Rotation.from_euler("ZY", np.column_stack([az, el])).as_matrix()


def _assert_scan(scan, t, az, el, atol=1e-15):
    c = scan(np.asarray(t, dtype=float)).astype(np.float64)
    np.testing.assert_allclose(c, _rz_ry(np.asarray(az, float), np.asarray(el, float)), atol=atol)


def test_one_row_raster_is_the_azimuth_sweep():
    # A = 0.3 rad at 0.2 rad/s: 0 -> +A in 1.5 s, back to -A at 4.5 s (no elevation step)
    t = [0.0, 1.0, 2.5, 4.0, 6.0]
    az = [0.0, 0.2, 0.1, -0.2, 0.0]
    _assert_scan(RasterScan(0.3, 0.2, 0.05, 1, 1.0, 0.0), t, az, np.zeros(5))


def test_zero_step_raster_is_the_azimuth_sweep():
    # A = 0.5 rad at 0.25 rad/s: +A at 2 s (exactly the end of the first half sweep), -A at 6 s
    t = [0.0, 1.0, 2.0, 3.0, 6.0, 8.0]
    az = [0.0, 0.25, 0.5, 0.25, -0.5, 0.0]
    _assert_scan(RasterScan(0.5, 0.25, 0.0, 3, 1.0, 0.0), t, az, np.zeros(6))


def test_raster_first_half_sweep_after_its_start():
    """Identity before ``start``; then az = r (t - start) at zero elevation up to +A."""
    start = 0.5
    scan = RasterScan(0.3, 0.2, 0.05, 3, 1.0, start)
    t = [0.0, 0.3, 0.5, 0.75, 1.5]
    _assert_scan(scan, t, [0.0, 0.0, 0.0, 0.05, 0.2], np.zeros(5))


def test_raster_first_units_shorter_than_a_second():
    """A = 0.1 rad at 1 rad/s, steps of 0.05 rad at 1 rad/s: one step + sweep lasts 0.25 s.

    Half sweep to +A by 0.1 s; step 0 -> 0.05 rad over 0.1..0.15 s at az = +A; sweep +A -> -A
    over 0.15..0.35 s; step 0.05 -> 0.1 over 0.35..0.4 s at az = -A.
    """
    scan = RasterScan(0.1, 1.0, 0.05, 3, 1.0, 0.0)
    t = [0.05, 0.125, 0.15, 0.25, 0.375, 0.4]
    az = [0.05, 0.1, 0.1, 0.0, -0.1, -0.1]
    el = [0.0, 0.025, 0.05, 0.05, 0.075, 0.1]
    _assert_scan(scan, t, az, el, atol=1e-15)


# -- OffsetModel.history ------------------------------------------------------------------------


@pytest.mark.parametrize("cycles", [True, 2.0, -1])
def test_history_cycles_must_be_a_non_negative_integer(cycles):
    with pytest.raises(ValueError, match=r"^cycles: must be an integer >= 0, got "):
        OffsetModel().history(0.01, cycles)


def test_history_of_zero_cycles_is_the_initial_offsets():
    h = OffsetModel(lever_arm=np.array([1.0, 2.0, 3.0])).history(0.01, 0)
    assert h.lever_arm.shape == (1, 3) and h.c_bvar_bref.shape == (1, 3, 3)
    assert np.array_equal(h.lever_arm, [[1.0, 2.0, 3.0]])


def test_lag_compensation_without_filter_is_the_raw_scan():
    scan = SweepScan(np.array([0.0, 0.0, 1.0]), 0.5, 0.1)
    plain = OffsetModel(scan=scan).history(0.01, 50).c_bvar_bref
    lagged = OffsetModel(scan=scan, lag_compensation=True).history(0.01, 50).c_bvar_bref
    assert np.array_equal(plain, lagged)
    np.testing.assert_allclose(plain, _rz_ry(0.1 * np.arange(51) * 0.01, np.zeros(51)),
                               atol=1e-15)  # fmt: skip
