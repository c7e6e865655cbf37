"""Savage 2020 eqs. (2)-(4) against an independent integration of the continuous eqs. (1)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from strapdown_ros.core import exact_update as ex
from strapdown_ros.core.rotations import dcm_from_rotvec, orthonormality_error, skew


def continuous_solution(c0, v0, r0, omega, f, g0, g1, period):
    """Integrate dC/dt = C (ω×), dV/dt = C f + g(t), dR/dt = V with g linear in time (eq. (1))."""
    w = skew(omega)

    def rhs(t, y):
        c = y[:9].reshape(3, 3)
        v = y[9:12]
        g = g0 + (g1 - g0) * t / period
        return np.concatenate([(c @ w).ravel(), c @ f + g, v])

    # Position is integrated relative to r0 so the reference keeps full precision in R - R0.
    y0 = np.concatenate([c0.ravel(), v0, np.zeros(3)])
    sol = solve_ivp(rhs, (0.0, period), y0, method="DOP853", rtol=1e-13, atol=1e-15)
    assert sol.success
    y = sol.y[:, -1]
    return y[:9].reshape(3, 3), y[9:12], y[12:15]


CASES = [
    # omega (rad/s), f (m/s^2), period (s)
    (np.array([0.0, 0.0, 0.0]), np.array([1.0, -2.0, 9.8]), 0.01),
    (np.array([1e-9, -2e-9, 3e-9]), np.array([0.5, 0.1, -9.8]), 0.005),
    (np.array([0.3, -0.2, 0.5]), np.array([3.0, -1.0, -9.8]), 0.01),
    (np.array([1.0, 2.0, -0.5]), np.array([30.0, 5.0, -20.0]), 0.5),  # |Δα| ≈ 1.1 rad
    (np.array([3.0, -1.0, 2.0]), np.array([10.0, 40.0, -9.8]), 0.8),  # |Δα| ≈ 3.0 rad
    (np.array([0.0, 0.0, np.pi - 1e-9]), np.array([1.0, 1.0, 1.0]), 1.0),  # near pi
    (np.array([5.0, 1.0, 0.0]), np.array([0.0, 50.0, -9.8]), 1.0),  # beyond pi
]


@pytest.mark.parametrize("omega,f,period", CASES)
def test_update_matches_continuous_integration(omega, f, period):
    rng = np.random.default_rng(0)
    c0 = dcm_from_rotvec(rng.normal(size=3))
    v0 = np.array([200.0, -100.0, 50.0])
    r0 = np.zeros(3)  # gravity is given, so R0 only offsets R; keep R - R0 at full precision
    g0 = np.array([-6.0, -1.5, -7.2])
    g1 = g0 + np.array([1e-3, -2e-3, 5e-4])  # linearly varying gravity (Appendix A)
    c_ref, v_ref, dr_ref = continuous_solution(c0, v0, r0, omega, f, g0, g1, period)
    c, v, r = ex.exact_update(c0, v0, r0, omega * period, f * period, g0, g1, period)
    assert np.max(np.abs(c - c_ref)) < 1e-13
    assert np.max(np.abs(v - v_ref)) < 1e-12 * max(1.0, np.linalg.norm(f) * period)
    assert np.max(np.abs(r - dr_ref)) < 1e-12 * max(1.0, np.linalg.norm(v0) * period)


def test_vectorized_equals_single_cycle_form():
    rng = np.random.default_rng(1)
    n = 200
    c = dcm_from_rotvec(rng.normal(size=(n, 3)))
    v, r = rng.normal(size=(n, 3)) * 100, rng.normal(size=(n, 3)) * 6e6
    da = rng.normal(size=(n, 3)) * np.logspace(-12, 0.5, n)[:, None]
    dv = rng.normal(size=(n, 3))
    g0, g1 = rng.normal(size=(2, n, 3)) * 9.8
    cv, vv, rv = ex.exact_update(c, v, r, da, dv, g0, g1, 0.01)
    for i in range(n):
        cs, vs, rs = ex.exact_update_single(c[i], v[i], r[i], da[i], dv[i], g0[i], g1[i], 0.01)
        np.testing.assert_allclose(cv[i], cs, rtol=0, atol=4e-15)
        np.testing.assert_allclose(vv[i], vs, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rv[i], rs, rtol=0, atol=1e-8)


def test_two_half_cycles_equal_one_cycle_without_gravity():
    """With constant rate and specific force, splitting a cycle in two changes nothing."""
    omega, f, period = np.array([0.7, -1.3, 2.1]), np.array([5.0, -3.0, 12.0]), 0.4
    c0, v0, r0, z = np.eye(3), np.array([1.0, 2.0, 3.0]), np.zeros(3), np.zeros(3)
    c1, v1, r1 = ex.exact_update(c0, v0, r0, omega * period, f * period, z, z, period)
    h = period / 2
    ch, vh, rh = ex.exact_update(c0, v0, r0, omega * h, f * h, z, z, h)
    c2, v2, r2 = ex.exact_update(ch, vh, rh, omega * h, f * h, z, z, h)
    np.testing.assert_allclose(c2, c1, atol=1e-15)
    np.testing.assert_allclose(v2, v1, atol=1e-14)
    np.testing.assert_allclose(r2, r1, atol=1e-14)


def test_g_matrices_properties():
    rng = np.random.default_rng(2)
    da = rng.normal(size=(100, 3))
    gc, gv, gr = ex.g_matrices(da)
    assert np.max(orthonormality_error(gc)) < 2e-15
    np.testing.assert_allclose(gc, dcm_from_rotvec(da), atol=1e-15)
    zero = ex.g_matrices(np.zeros(3))
    np.testing.assert_array_equal(zero[0], np.eye(3))
    np.testing.assert_array_equal(zero[1], np.eye(3))
    np.testing.assert_array_equal(zero[2], 0.5 * np.eye(3))
    np.testing.assert_array_equal(ex.g_c(da), gc)
    np.testing.assert_array_equal(ex.g_v(da), gv)
    np.testing.assert_array_equal(ex.g_r(da), gr)


def spherical_gravity(r):
    r = np.asarray(r)
    return -3.986004418e14 * r / np.linalg.norm(r, axis=-1, keepdims=True) ** 3


def test_integrate_then_residuals_are_at_rounding_level():
    rng = np.random.default_rng(3)
    n, period = 2000, 0.01
    t = np.arange(n) * period
    omega = np.column_stack([0.2 * np.sin(t), 0.1 * np.cos(2 * t), 0.05 + 0 * t])
    f = np.column_stack([1 + np.sin(3 * t), 0.2 + 0 * t, -9.8 + 0.1 * np.cos(t)])
    da, dv = omega * period, f * period
    c0 = dcm_from_rotvec(rng.normal(size=3))
    r0 = np.array([6378137.0, 0.0, 0.0])
    v0 = np.array([0.0, 465.0, 0.0])
    c, v, r = ex.integrate(c0, v0, r0, da, dv, period, spherical_gravity)
    res = ex.one_step_residuals(c, v, r, da, dv, spherical_gravity(r), period)
    assert res.within_spec()
    assert res.max_attitude < 1e-14
    assert res.max_velocity < 1e-11
    assert res.max_position < 1e-8
    # A corrupted increment is caught as a defect.
    dv_bad = dv.copy()
    dv_bad[500, 1] += 1e-8
    bad = ex.one_step_residuals(c, v, r, da, dv_bad, spherical_gravity(r), period)
    assert not bad.within_spec()
    assert np.argmax(bad.velocity) == 500


def test_integrate_matches_continuous_solution_over_many_cycles():
    """Chained cycles equal a single continuous integration under constant ω, f and g."""
    omega, f, period, n = np.array([0.05, -0.02, 0.3]), np.array([0.3, 0.1, -9.81]), 0.02, 100
    g = np.array([0.0, 0.0, 9.81])
    c, v, r = ex.integrate(
        np.eye(3),
        np.zeros(3),
        np.zeros(3),
        np.tile(omega * period, (n, 1)),
        np.tile(f * period, (n, 1)),
        period,
        lambda r: np.broadcast_to(g, r.shape),
    )
    c_ref, v_ref, r_ref = continuous_solution(
        np.eye(3), np.zeros(3), np.zeros(3), omega, f, g, g, n * period
    )
    np.testing.assert_allclose(c[-1], c_ref, atol=1e-13)
    np.testing.assert_allclose(v[-1], v_ref, atol=1e-12)
    np.testing.assert_allclose(r[-1], r_ref, atol=1e-12)
