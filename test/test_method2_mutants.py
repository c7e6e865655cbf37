"""core/method2.py against references that do not use its code (found by mutation testing).

Expected values: scipy's rotation vectors (Savage 2020 eq. (8)), the exact update of eqs.
(2)-(4) in core/exact_update.py (a separate implementation: ``one_step_residuals``,
``exact_update``), Simpson's rule being exact on cubics, and ``np.linalg.inv``. Each runs on both
the compiled kernels and the numpy formulation (``PairSystem``), which is what runs without numba.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strapdown_ros.core import _compiled
from strapdown_ros.core import method2 as m2
from strapdown_ros.core.exact_update import exact_update, g_matrices, one_step_residuals
from strapdown_ros.core.rotations import dcm_from_rotvec

GM = 3.986004418e14


def spherical(r):
    r = np.asarray(r, dtype=np.float64)
    return -GM * r / np.linalg.norm(r, axis=-1, keepdims=True) ** 3


def truth(t):
    """Smooth motion near the Earth's surface (E0): C_B^E0, V (m/s), R (m)."""
    t = np.asarray(t, dtype=np.float64)
    center = np.array([4.0e6, 1.2e6, 4.8e6])
    r = center + np.column_stack([150.0 * t + 2.0 * t**2, 40.0 * np.sin(0.3 * t), 5.0 * t])
    v = np.column_stack([150.0 + 4.0 * t, 12.0 * np.cos(0.3 * t), np.full_like(t, 5.0)])
    phi = np.column_stack([0.4 * np.sin(0.9 * t), 0.3 * np.cos(0.5 * t), 0.8 * t])
    return dcm_from_rotvec(phi), v, r


PATHS = ["compiled", "numpy"]


@pytest.fixture(params=PATHS)
def path(request, monkeypatch):
    """Which formulation method2 runs: the numba kernels or PairSystem."""
    if request.param == "numpy":
        monkeypatch.setattr(_compiled, "HAVE_NUMBA", False)
    elif not _compiled.HAVE_NUMBA:
        pytest.skip("numba not installed")
    return request.param


def test_attitude_increments_are_scipy_rotation_vectors():
    """Eq. (8): Δα_m = rotation vector of C_{m-1}ᵀ C_m, up to angles near π."""
    rng = np.random.default_rng(3)
    steps = rng.normal(size=(60, 3))
    steps *= (rng.uniform(0.0, 3.1, size=60) / np.linalg.norm(steps, axis=1))[:, None]
    c = [np.eye(3)]
    for s in steps:
        c.append(c[-1] @ Rotation.from_rotvec(s).as_matrix())
    da = m2.attitude_increments(np.array(c))
    assert da.shape == (60, 3)
    # measured: 5e-15 rad; 10x margin
    np.testing.assert_allclose(da, steps, rtol=0, atol=5e-14)


def _residuals(sol, g, period):
    return one_step_residuals(sol.c_b_e0, sol.v_e0, sol.r_e0, sol.dalpha, sol.dv, g, period)


@pytest.mark.parametrize("cycles", [1, 2, 7, 40, 41])
def test_solution_obeys_the_exact_update_and_the_constraints(path, cycles):
    """Eqs. (2)-(4) reproduce every published state from the previous one; even cycles and, for
    odd M, the last (eq. (9)) position are the constraints, bit for bit."""
    period = 0.01
    c, v, r = truth(np.arange(cycles + 1) * period)
    sol = m2.method2(c, r, v, period, spherical)
    assert sol.dalpha.shape == sol.dv.shape == (cycles, 3)
    res = _residuals(sol, spherical(sol.r_e0), period)
    # measured: position <= 2e-9 m, velocity <= 3e-12 m/s, attitude <= 2e-16 rad; margins 5-10x
    assert res.max_position < 1e-8 and res.max_velocity < 3e-11 and res.max_attitude < 2e-15
    np.testing.assert_array_equal(sol.r_e0[0::2], r[0::2])
    np.testing.assert_array_equal(sol.v_e0[0::2], v[0::2])
    np.testing.assert_array_equal(sol.r_e0[-1], r[-1])
    np.testing.assert_array_equal(sol.c_b_e0, c)
    np.testing.assert_array_equal(sol.g_e0, spherical(sol.r_e0))
    # the free (odd-cycle) states stay on the smooth motion: measured 1e-6 m, 1e-4 m/s
    np.testing.assert_allclose(sol.r_e0, r, rtol=0, atol=1e-4)
    np.testing.assert_allclose(sol.v_e0, v, rtol=0, atol=1e-2)


def test_cycle_gravity_is_called_with_the_cycle_index(path):
    """A model depending on the cycle (eq. (C-12)): the published g is g(R_m, m) at every m and
    the exact update holds with it; a model that ignored m would miss by 1e-4 m/s² per cycle."""
    period, cycles = 0.01, 21
    c, v, r = truth(np.arange(cycles + 1) * period)
    seen = []

    def cycle_gravity(x, m):
        m = np.asarray(m)
        seen.append(np.atleast_1d(m).copy())
        return spherical(x) + 1e-4 * np.multiply.outer(m, [1.0, -2.0, 0.5])

    sol = m2.method2(c, r, v, period, spherical, cycle_gravity=cycle_gravity)
    g = spherical(sol.r_e0) + 1e-4 * np.outer(np.arange(cycles + 1), [1.0, -2.0, 0.5])
    np.testing.assert_allclose(sol.g_e0, g, rtol=1e-15, atol=0)
    res = _residuals(sol, g, period)
    assert res.max_position < 1e-8 and res.max_velocity < 3e-11
    assert np.array_equal(np.unique(np.concatenate(seen)), np.arange(cycles + 1))


def test_final_single_cycle_uses_the_gravity_at_both_of_its_ends(path):
    """Odd M: the last cycle alone meets eq. (9) with g_{M-1} and g_M. A gravity that jumps by
    ~1 m/s² per cycle makes any other cycle's g visible: using g_{M-2} would leave
    (g_{M-1} - g_{M-2}) T²/3 ≈ 8e-5 m in the exact update's position of that cycle."""
    period, cycles = 0.01, 21
    c, v, r = truth(np.arange(cycles + 1) * period)
    step = np.array([1.0, -2.0, 0.5])

    def cycle_gravity(x, m):
        return spherical(x) + np.multiply.outer(np.asarray(m, dtype=np.float64), step)

    sol = m2.method2(c, r, v, period, spherical, cycle_gravity=cycle_gravity)
    g = spherical(sol.r_e0) + np.outer(np.arange(cycles + 1), step)
    res = one_step_residuals(sol.c_b_e0[-2:], sol.v_e0[-2:], sol.r_e0[-2:], sol.dalpha[-1:],
                             sol.dv[-1:], g[-2:], period)  # fmt: skip
    # measured: 2.3e-10 m, 0 m/s (round-off of 6e6 m); the g_{M-2} mutant: ~8e-5 m
    assert res.max_position < 5e-9 and res.max_velocity < 3e-12
    np.testing.assert_array_equal(sol.r_e0[-1], r[-1])


def test_displacement_replaces_the_difference_of_positions(path):
    """With ``displacement`` = exact difference + δ, the even positions reached by eqs. (2)-(4)
    miss the published constraints by exactly δ (the odd cycles are unaffected)."""
    period, cycles = 0.01, 20
    c, v, r = truth(np.arange(cycles + 1) * period)
    delta = np.array([1e-3, -2e-3, 5e-4])
    disp = (r[2::2] - r[:-2:2]) + delta
    sol = m2.method2(c, r, v, period, spherical, displacement=disp)
    res = _residuals(sol, spherical(sol.r_e0), period)
    np.testing.assert_allclose(res.position[1::2], np.linalg.norm(delta), rtol=1e-6)
    assert np.max(res.position[0::2]) < 1e-8
    with pytest.raises(ValueError, match=r"displacement must have shape \(10, 3\), got \(9, 3\)"):
        m2.method2(c, r, v, period, spherical, displacement=disp[:-1])


def test_odd_states_are_the_exact_update_of_the_odd_increment():
    """PairSystem.odd_state is eqs. (3)-(4) over cycle 2n-1; solve meets eqs. (16), (19)."""
    rng = np.random.default_rng(5)
    n, t = 30, 0.02
    c0, c1 = dcm_from_rotvec(rng.normal(size=(2, n, 3)))
    da1, da2 = rng.normal(size=(2, n, 3)) * 0.4
    _, gv1, gr1 = g_matrices(da1)
    _, gv2, gr2 = g_matrices(da2)
    r0, r2 = rng.normal(size=(2, n, 3)) * 10 + 6e6
    v0, v2 = rng.normal(size=(2, n, 3)) * 10
    g0, g1, g2 = rng.normal(size=(3, n, 3))
    system = m2.PairSystem(c0, c1, gv1, gr1, gv2, gr2, r0, r2, v0, v2, g0, g2, t)
    dv1, dv2 = system.solve(g1)
    v_odd, r_odd = system.odd_state(dv1, g1)
    _, v_ref, r_ref = exact_update(c0, v0, r0, da1, dv1, g0, g1, t)
    np.testing.assert_allclose(v_odd, v_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r_odd, r_ref, rtol=0, atol=1e-8)
    # the second cycle from the odd state reaches the constraints
    _, v_end, r_end = exact_update(c1, v_ref, r_ref, da2, dv2, g1, g2, t)
    np.testing.assert_allclose(v_end, v2, rtol=0, atol=1e-11)
    np.testing.assert_allclose(r_end, r2, rtol=0, atol=1e-8)


def test_inverse_by_adjugate_is_the_inverse():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(4, 5, 3, 3)) + 2.0 * np.eye(3)
    np.testing.assert_allclose(m2._inv3(a), np.linalg.inv(a), rtol=1e-12, atol=1e-12)


def test_pair_displacement_is_exact_on_cubic_velocity():
    """Simpson's rule (T/3)(V_{2n-2} + 4 V_{2n-1} + V_{2n}) integrates cubics exactly."""
    period, cycles = 0.25, 9  # odd M: the last single cycle has no pair
    t = np.arange(cycles + 1) * period
    a, b, cc, d = np.array([[1.0, -2.0, 3.0], [0.5, 4.0, -1.0], [2.0, 0.0, 1.5], [-1.0, 3.0, 0.2]])

    def pos(x):
        x = x[:, None]
        return a * x + b * x**2 / 2 + cc * x**3 / 3 + d * x**4 / 4

    v = a + b * t[:, None] + cc * t[:, None] ** 2 + d * t[:, None] ** 3
    disp = m2.pair_displacement(v, period)
    assert disp.shape == (4, 3)
    np.testing.assert_allclose(disp, pos(t[2:-1:2]) - pos(t[0:-3:2]), rtol=1e-13, atol=1e-14)


def test_odd_positions_are_only_the_gravity_guess(path):
    """Odd entries of ``r_e0`` start the odd-cycle gravity fixed point and nothing else: a guess
    1e5 m off (0.3 m/s² of gravity) is corrected by the second pass; one pass leaves
    ~|δg| T / 2 in the velocity residual (measured 1.6e-3 m/s at T = 0.01 s)."""
    period, cycles = 0.01, 20
    c, v, r = truth(np.arange(cycles + 1) * period)
    bad = r.copy()
    bad[1::2] += 1e5 * np.array([0.6, 0.0, 0.8])
    two = m2.method2(c, bad, v, period, spherical, iterations=2)
    res = _residuals(two, spherical(two.r_e0), period)
    assert res.max_position < 1e-8 and res.max_velocity < 3e-11
    np.testing.assert_allclose(two.r_e0, r, rtol=0, atol=1e-4)
    one = m2.method2(c, bad, v, period, spherical, iterations=1)
    res1 = _residuals(one, spherical(one.r_e0), period)
    assert 1e-4 < res1.max_velocity < 1e-2
    # iterations < 1 still makes one pass
    zero = m2.method2(c, bad, v, period, spherical, iterations=0)
    np.testing.assert_array_equal(zero.dv, one.dv)


def test_integer_inputs_are_taken_as_floats(path):
    """Whole-number attitudes and constraints (e.g. read from a table) give float outputs and the
    same solution as float inputs (an integer working array would truncate the odd states)."""
    period, cycles = 0.01, 6
    c = np.tile(np.eye(3, dtype=np.int64), (cycles + 1, 1, 1))
    r = np.tile(np.array([6378137, 0, 0], dtype=np.int64), (cycles + 1, 1))
    r[:, 1] = 3 * np.arange(cycles + 1)  # 300 m/s along y, whole metres every cycle
    v = np.tile(np.array([0, 0, 0], dtype=np.int64), (cycles + 1, 1))
    v[:, 1] = 100 * np.arange(cycles + 1)  # unequal end velocities: odd R off the chord
    sol = m2.method2(c, r, v, period, spherical)
    ref = m2.method2(c.astype(float), r.astype(float), v.astype(float), period, spherical)
    for a, b in zip(
        (sol.c_b_e0, sol.r_e0, sol.v_e0, sol.dv),
        (ref.c_b_e0, ref.r_e0, ref.v_e0, ref.dv),
        strict=True,
    ):
        assert a.dtype == np.float64
        np.testing.assert_array_equal(a, b)
    assert np.all(sol.r_e0[1::2, 1] % 1.0 != 0.0)  # the odd states are not whole metres


def test_error_messages_are_exact():
    c = np.tile(np.eye(3), (5, 1, 1))
    z = np.zeros((5, 3))
    with pytest.raises(
        ValueError, match=r"^Method 2 needs at least one cycle \(two attitude samples\)$"
    ):
        m2.method2(c[:1], z[:1], z[:1], 0.01, spherical)
    with pytest.raises(ValueError, match=r"^r_e0 and v_e0 must have one row per attitude sample$"):
        m2.method2(c, z[:4], z, 0.01, spherical)
    with pytest.raises(ValueError, match=r"^r_e0 and v_e0 must have one row per attitude sample$"):
        m2.method2(c, z, z[:, :2], 0.01, spherical)
