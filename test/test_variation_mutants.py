"""Savage 2020 eq. (10): the variation velocity ``v_var = v_ref + ds/dt`` of the constraints.

A reference at rest at identity attitude and a displacement quadratic in time,
``s(t) = p + q t + w t²``: both the central difference and the one-sided three-point formula
of eq. (10) are exact for a quadratic, so ``ds/dt = q + 2 w t`` in closed form (the numbers are
binary fractions: every operation is exact).

Below: the gravity at the variation point (``full`` / ``first_order``, eq. (C-12)) and
Method 1's velocity, for a variation 9.4 km from a reference at rest (closed forms, see there).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from strapdown_ros.core.variation import OffsetArrays, variation_constraints

T = 0.25  # s, cycle period
P = np.array([1.0, -2.0, 0.5])  # m
Q = np.array([0.5, 1.0, -1.5])  # m/s
W = np.array([0.25, -0.5, 2.0])  # m/s²
V_REF = np.array([3.0, -4.0, 0.75])  # m/s, constant reference velocity


def _case(n: int) -> tuple[SimpleNamespace, OffsetArrays, np.ndarray]:
    t = T * np.arange(n)
    r_ref = np.array([6.0e6, 0.0, 0.0]) + t[:, None] * V_REF
    ref = SimpleNamespace(
        c_b_e0=np.tile(np.eye(3), (n, 1, 1)),
        r_e0=r_ref,
        v_e0=np.tile(V_REF, (n, 1)),
        period=T,
        cycles=n - 1,
    )
    s = P + t[:, None] * Q + (t * t)[:, None] * W
    off = OffsetArrays(np.zeros((n, 3)), s, np.tile(np.eye(3), (n, 1, 1)))
    return ref, off, t


@pytest.mark.parametrize("lead", [0, 1])
def test_variation_velocity_is_reference_plus_displacement_rate(lead: int) -> None:
    cycles = 5
    ref, off, t = _case(lead + cycles + 2)
    con = variation_constraints(ref, off, cycles, lead=lead)  # type: ignore[arg-type]
    tm = t[lead : lead + cycles + 1]
    expected = V_REF + Q + 2.0 * tm[:, None] * W
    np.testing.assert_array_equal(con.v_e0, expected)
    np.testing.assert_array_equal(
        con.r_e0, ref.r_e0[lead : lead + cycles + 1] + P + tm[:, None] * Q + (tm * tm)[:, None] * W
    )


def test_variation_needs_one_cycle_ahead() -> None:
    ref, off, _ = _case(7)
    variation_constraints(ref, off, 5)  # type: ignore[arg-type]  # 7 = 5 + 2 samples: enough
    ref.cycles = 5  # 6 reference samples
    with pytest.raises(ValueError, match=r"needs 7 reference and offset samples .* got 6 and 7"):
        variation_constraints(ref, off, 5)  # type: ignore[arg-type]


def _rest_stream(n: int, model: str = "spherical"):
    from strapdown_ros.core.stream import Stream

    return Stream(
        5_000, 10_000_000, np.zeros((n - 1, 3)), np.zeros((n - 1, 3)),
        np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), np.tile([6378137.0, 0.0, 0.0], (n, 1)),
        gravity_model=model, e0_epoch_ns=123_456,
    )  # fmt: skip


@pytest.mark.parametrize("method", [1, 2])
def test_window_output_keeps_epoch_model_and_starts_one_period_later(method: int) -> None:
    """With ``lead`` 1 the output starts at reference sample 1 (docstring): t0 + period_ns, by
    hand 5_000 + 10_000_000 ns; E0 epoch and gravity model are the reference's own."""
    from strapdown_ros.core.variation import generate_variation

    out = generate_variation(_rest_stream(7), OffsetArrays.zero(7), method=method, lead=1)
    assert out.t0_ns == 10_005_000
    assert out.e0_epoch_ns == 123_456
    assert out.gravity_model == "spherical"


@pytest.mark.parametrize(
    "lead,cycles,message",
    [
        (5, 6, r"^lead must be 0 or 1, got 5$"),
        (0, 2, r"^a variation needs a reference of at least 3 cycles, got 2$"),
        (1, 3, r"^a variation needs a reference of at least 4 cycles, got 3$"),
    ],
)
def test_generate_variation_messages(lead: int, cycles: int, message: str) -> None:
    """The messages of generate_variation's checks, written out by hand from its docstring (a
    reference of M cycles gives M_var = M - 1 - lead rounded down to even, at least 2)."""
    from strapdown_ros.core.variation import generate_variation

    with pytest.raises(ValueError, match=message):
        generate_variation(_rest_stream(cycles + 1), OffsetArrays.zero(cycles + 1), lead=lead)


# Gravity at the variation point (Savage 2020 Appendix C) and Method 1's velocity (eqs. (3), (9)).
# The reference is at rest in E0 at R0 = (a, 0, 0) at identity attitude, with the specific force
# that holds it there: Δv = -g(R0) T (eq. (3) with V = 0; eq. (4) then gives R_m = R_{m-1}).
# Its gravity model is "spherical", not the default "j2": g(R) = -GM R / |R|³ (eq. (C-1)),
# written out here. About R0, eq. (C-12) with u = e_x, u·g_ref = -GM/a² is
# g(R0 + S) ≈ -(GM/a³) [a - 2 S_x, S_y, S_z]. At |S| ≈ 9.4 km the two differ by ~4e-5 m/s²
# (the second-order term, ~GM |S|²/a⁴), 3.2e-7 m/s in Δv over one cycle.
GM = 3.986004418e14  # m³/s², WGS-84
A = 6378137.0  # m
R0 = np.array([A, 0.0, 0.0])
T_G = 1.0 / 128.0  # s (7 812 500 ns: every t_m and s(t_m) below is exact)
P_FAR = np.array([8192.0, -4096.0, 2048.0])  # m, the offset of the variation
Q_FAR = np.array([64.0, -32.0, 16.0])  # m/s
W_FAR = np.array([4.0, 8.0, -2.0])  # m/s²


def _gravity_spherical(r: np.ndarray) -> np.ndarray:
    return -GM * r / np.linalg.norm(r, axis=-1, keepdims=True) ** 3


def _gravity_first_order(s: np.ndarray) -> np.ndarray:
    """eq. (C-12) about R0 = (a, 0, 0): g_ref + (u·g_ref)/a (S - 3 (u·S) u), by hand."""
    return -(GM / A**3) * np.stack([A - 2.0 * s[:, 0], s[:, 1], s[:, 2]], axis=-1)


def _reference_at_rest(n: int):
    from strapdown_ros.core.stream import Stream

    dv = -_gravity_spherical(R0) * T_G
    return Stream(
        0, 7_812_500, np.zeros((n - 1, 3)), np.tile(dv, (n - 1, 1)), np.tile(np.eye(3), (n, 1, 1)),
        np.zeros((n, 3)), np.tile(R0, (n, 1)), gravity_model="spherical",
    )  # fmt: skip


def _far_offsets(n: int, q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, OffsetArrays]:
    t = T_G * np.arange(n)
    s = P_FAR + t[:, None] * q + (t * t)[:, None] * w
    return t, OffsetArrays(np.zeros((n, 3)), s, np.tile(np.eye(3), (n, 1, 1)))


def _gravity_along(s: np.ndarray, gravity: str) -> np.ndarray:
    return _gravity_spherical(R0 + s) if gravity == "full" else _gravity_first_order(s)


def test_the_two_gravity_modes_differ_at_the_far_offset() -> None:
    """The tests below tell "full" from "first_order" only if the closed forms differ by far
    more than their tolerances (3e-16 and 6e-13 m/s): 3.2e-7 m/s in Δv."""
    s = P_FAR[None, :]
    diff = np.abs(_gravity_spherical(R0 + s) - _gravity_first_order(s)).max() * T_G
    assert 3.0e-7 < diff < 3.5e-7, diff


@pytest.mark.parametrize("gravity", ["full", "first_order"])
@pytest.mark.parametrize("method", [1, 2])
def test_variation_at_rest_far_off_gets_the_gravity_of_its_mode(method: int, gravity: str) -> None:
    """A constant offset S = P (9.4 km): the variation is at rest at R0 + S, so eq. (3) gives
    ``Δv = -g T`` every cycle with g the mode's gravity at R0 + S, in the stream's model: the
    spherical closed form ("full") or eq. (C-12) ("first_order"). Measured: 2.8e-17 m/s at most
    (a ulp of 0.077 m/s); the limit is 10 times that."""
    from strapdown_ros.core.variation import generate_variation

    n = 10
    _, off = _far_offsets(n, 0.0 * Q_FAR, 0.0 * W_FAR)
    out = generate_variation(_reference_at_rest(n), off, method=method, gravity=gravity)
    assert out.cycles == 8  # M = 9: the last even cycle with its look-ahead sample
    g = _gravity_along(P_FAR[None, :], gravity)[0]
    np.testing.assert_array_equal(out.r_e0, np.tile(R0 + P_FAR, (9, 1)))
    np.testing.assert_allclose(out.v_e0, 0.0, rtol=0, atol=1e-16)
    np.testing.assert_allclose(out.dv, np.tile(-g * T_G, (8, 1)), rtol=0, atol=3e-16)
    np.testing.assert_array_equal(out.dalpha, 0.0)


@pytest.mark.parametrize("gravity", ["full", "first_order"])
def test_method1_velocity_of_an_accelerated_far_offset(gravity: str) -> None:
    """Method 1 with ``S(t) = p + q t + w t²`` (the variation moves 0.5 m per cycle through the
    gravity gradient). With C = I and Δα = 0 (G_R = I/2, G_V = I), eliminating Δv between eq. (9)
    and eq. (3) leaves ``V_m + V_{m-1} = 2 (R_m - R_{m-1})/T + (g_m - g_{m-1}) T/6``, and V_0 is
    eq. (10)'s one-sided derivative, exact for a quadratic: V_0 = q. So
    ``V_m = q + 2 w t_m + e_m`` with ``e_m = -e_{m-1} + (g_m - g_{m-1}) T/6``, e_0 = 0 (the
    odd/even term, 2e-9 m/s here), and ``Δv_m = V_m - V_{m-1} - (g_m + g_{m-1}) T/2`` (eq. (3)),
    g the mode's gravity at R0 + S(t_m). Measured: 2.8e-14 m/s in V, 6.0e-14 m/s in Δv; the
    limits are 10 times those. Using g_0 for g_{m-1} misses by 3e-8 m/s, V_0 = V_1's
    constraint by 2 w T = 0.06 m/s."""
    from strapdown_ros.core.variation import generate_variation

    n = 10
    t, off = _far_offsets(n, Q_FAR, W_FAR)
    out = generate_variation(_reference_at_rest(n), off, method=1, gravity=gravity)
    m = out.cycles
    s = off.displacement[: m + 1]
    g = _gravity_along(s, gravity)
    e = np.zeros((m + 1, 3))
    for k in range(1, m + 1):
        e[k] = -e[k - 1] + (g[k] - g[k - 1]) * T_G / 6.0
    v = Q_FAR + 2.0 * t[: m + 1, None] * W_FAR + e
    np.testing.assert_array_equal(out.r_e0, R0 + s)
    np.testing.assert_allclose(out.v_e0, v, rtol=0, atol=3e-13)
    dv = v[1:] - v[:-1] - 0.5 * (g[1:] + g[:-1]) * T_G
    np.testing.assert_allclose(out.dv, dv, rtol=0, atol=6e-13)
