"""Tests of the multirate b–l split navigator (Waldmann seeds/004, Table 1, eq. (33))."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.core.earth import OMEGA_IE, radii
from strapdown_ros.core.gravity import gravity_ned
from strapdown_ros.core.navigation import (
    NavSolution,
    NavState,
    fast_cycle,
    navigate_multirate,
    navigate_simultaneous,
    state_from_stream,
    truth_navigation,
)
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    quat_from_dcm,
    quat_multiply,
    skew,
)
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.young import young_error_angles
from strapdown_ros.stages.trajectory import generate_reference

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
DURATION_S = 60.0


def _reference(name: str, rate_hz: int = 200) -> Stream:
    scenario = load_scenario(SCENARIOS / f"{name}.yaml", [f"rate_hz={rate_hz}"], DURATION_S)
    return generate_reference(scenario)


@pytest.fixture(scope="module")
def static_ref() -> Stream:
    return _reference("static")


@pytest.fixture(scope="module")
def default_ref() -> Stream:
    return _reference("default")


def _errors(stream: Stream, sol: NavSolution) -> dict[str, float]:
    """Max over the T_nav outputs of horizontal, vertical, velocity and attitude errors."""
    idx = np.arange(sol.t.size) * sol.n
    t, lat, lon, alt, v, q = truth_navigation(stream, idx)
    np.testing.assert_allclose(sol.t, t, atol=1e-9)
    rn, re = radii(lat)
    dn = (sol.lat - lat) * (rn + alt)
    de = (sol.lon - lon) * (re + alt) * np.cos(lat)
    theta = young_error_angles(dcm_from_quat(sol.q_b_n), dcm_from_quat(q))
    return {
        "horizontal": float(np.hypot(dn, de).max()),
        "vertical": float(np.abs(sol.alt - alt).max()),
        "velocity": float(np.linalg.norm(sol.v_ned - v, axis=1).max()),
        "attitude": float(np.linalg.norm(theta, axis=-1).max()),
    }


def _run(stream: Stream, n: int, p: int) -> NavSolution:
    return navigate_multirate(
        state_from_stream(stream), stream.dalpha, stream.dv, stream.period, n, p, "j2"
    )


# ---------------------------------------------------------------------------------------------
# State and initialization
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["static", "default"])
def test_initial_state_matches_scenario(name: str, static_ref: Stream, default_ref: Stream) -> None:
    stream = static_ref if name == "static" else default_ref
    init = load_scenario(SCENARIOS / f"{name}.yaml", duration_s=DURATION_S).initial
    st = state_from_stream(stream)
    assert st.t == 0.0
    assert st.lat == pytest.approx(math.radians(init.latitude_deg), abs=1e-14)
    assert st.lon == pytest.approx(math.radians(init.longitude_deg), abs=1e-14)
    assert st.alt == pytest.approx(init.altitude_m, abs=1e-8)
    np.testing.assert_allclose(st.v_ned, init.velocity_ned_mps, atol=1e-9)
    c_expected = dcm_from_euler(*np.radians(init.attitude_rph_deg))
    np.testing.assert_allclose(dcm_from_quat(st.q_b_n), c_expected, atol=1e-13)


# ---------------------------------------------------------------------------------------------
# Fast boundary layer
# ---------------------------------------------------------------------------------------------


def test_fast_cycle_is_table1_eq19_and_eq33() -> None:
    """The scalar-coded fast loop equals eq. (19) and eq. (33) written with matrices."""
    rng = np.random.default_rng(4)
    n = 7
    dalpha = rng.normal(scale=1e-2, size=(n, 3))
    dv = rng.normal(scale=1e-1, size=(n, 3))
    dphi_l = rng.normal(scale=1e-5, size=3)
    q0 = quat_from_dcm(dcm_from_euler(0.3, -0.2, 2.0))
    q, v = q0.copy(), np.zeros(3)
    for k in range(n):
        v = v - skew(dalpha[k]) @ v + dv[k]  # (19)
        q = (
            q
            + 0.5 * quat_multiply(q, np.r_[0.0, dalpha[k]])
            - 0.5 * quat_multiply(np.r_[0.0, dphi_l], q)
        )  # (33), first order
    q_fast, v_fast = fast_cycle(q0, dalpha, dv, dphi_l, normalize=False)
    np.testing.assert_allclose(q_fast, q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v_fast, v, rtol=0, atol=1e-15)
    q_norm, _ = fast_cycle(q0, dalpha, dv, dphi_l, normalize=True)
    assert np.linalg.norm(q_norm) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(q_norm, q / np.linalg.norm(q), atol=1e-9)


def test_bad_arguments_rejected(static_ref: Stream) -> None:
    st = state_from_stream(static_ref)
    with pytest.raises(ValueError):
        navigate_multirate(st, static_ref.dalpha, static_ref.dv, 0.005, 0, 1)
    with pytest.raises(ValueError):
        navigate_multirate(st, static_ref.dalpha, static_ref.dv[:-1], 0.005, 1, 1)
    with pytest.raises(ValueError):
        navigate_multirate(st, static_ref.dalpha, static_ref.dv, 0.005, 1, 0)
    with pytest.raises(ValueError, match="mode"):
        navigate_multirate(st, static_ref.dalpha, static_ref.dv, 0.005, 1, 1, mode="rk4")
    with pytest.raises(ValueError):
        navigate_simultaneous(st, static_ref.dalpha, static_ref.dv, 0.005, 0)


# ---------------------------------------------------------------------------------------------
# Stationary IMU (static.yaml, 60 s)
# ---------------------------------------------------------------------------------------------


def test_static_drift_bounded_by_first_order_split_error(static_ref: Stream) -> None:
    """Static drift is the b–l split error, ∝ (N - 1) T_gyr, within a derived bound.

    Each T_nav cycle (19) sums the specific force in the end-of-cycle body frame and (32) maps it
    with the end-of-cycle ``D_l^b``, ignoring the local-level frame's rotation ``ω_il`` during
    the cycle: an acceleration error ``≈ ½ |ω_il| g (T_nav - T_gyr)``, hence a drift
    ``≤ ½ a t²``. Measured (200 Hz, 60 s): N=1: 1.4e-9 m; N=10: 1.9e-2 m; N=20: 4.1e-2 m
    (bounds 2.9e-2 m and 6.1e-2 m).
    """
    g = 9.81
    drift = {}
    for n in (1, 10, 20):
        e = _errors(static_ref, _run(static_ref, n, 1))
        bound = 0.5 * (0.5 * OMEGA_IE * g * (n - 1) * static_ref.period) * DURATION_S**2
        assert e["horizontal"] <= max(bound, 1e-6), (n, e)
        assert e["vertical"] < 1e-3 * max(n - 1, 1e-3), (n, e)
        assert e["attitude"] < 1e-8, (n, e)
        drift[n] = e["horizontal"]
    assert drift[1] < 1e-6
    assert drift[20] / drift[10] == pytest.approx(19 / 9, rel=0.05)


# ---------------------------------------------------------------------------------------------
# Maneuvering aircraft (default.yaml, 60 s)
# ---------------------------------------------------------------------------------------------


def test_default_paper_mode_is_first_order(default_ref: Stream) -> None:
    """Paper mode (Euler everywhere, Table 1) has errors ∝ T: halving T_gyr halves them.

    Measured at N=2, P=1 over 60 s: 200 Hz → horizontal 0.172 m, vertical 0.060 m,
    velocity 4.2e-3 m/s, attitude 3.6e-8 rad; 400 Hz → 0.086 m, 0.030 m, 2.1e-3 m/s, 1.8e-8 rad.
    """
    e200 = _errors(default_ref, _run(default_ref, 2, 1))
    ref400 = _reference("default", 400)
    e400 = _errors(ref400, _run(ref400, 2, 1))
    assert e200["horizontal"] < 0.25
    assert e200["vertical"] < 0.1
    assert e200["velocity"] < 6e-3
    assert e200["attitude"] < 5e-8
    for key in e200:
        assert e200[key] / e400[key] == pytest.approx(2.0, rel=0.05), (key, e200, e400)


def test_default_error_grows_with_t_nav(default_ref: Stream) -> None:
    """At fixed T_gyr a longer T_nav (larger N) increases the error; altitude error ∝ N.

    Measured (200 Hz, 60 s, P=2): N=4 vertical 0.120 m, N=10 vertical 0.301 m; horizontal
    0.199 m and 0.291 m.
    """
    e4 = _errors(default_ref, _run(default_ref, 4, 2))
    e10 = _errors(default_ref, _run(default_ref, 10, 2))
    assert e4["horizontal"] < e10["horizontal"] < 0.4
    assert e10["vertical"] / e4["vertical"] == pytest.approx(10 / 4, rel=0.05)


# ---------------------------------------------------------------------------------------------
# Exact rest at the equator, facing north
# ---------------------------------------------------------------------------------------------


def _equator_rest(n_cycles: int, t_gyr: float) -> tuple[NavState, np.ndarray, np.ndarray]:
    """A level north-facing body at rest on the equator: ω_ib^b = [Ω, 0, 0], f^b = -g^N."""
    st = NavState(0.0, 0.0, 0.3, 100.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    dalpha = np.tile([OMEGA_IE * t_gyr, 0.0, 0.0], (n_cycles, 1))
    dv = np.tile(-gravity_ned(0.0, 100.0, "j2") * t_gyr, (n_cycles, 1))
    return st, dalpha, dv


def test_equator_rest_is_a_fixed_point_at_n1() -> None:
    """With N = P = 1, Earth rate sensed about the body x axis equals Δφ_l of eq. (33), and
    ``g_l T + D_l^b Δβ = 0``: the state stays exactly at rest (to rounding)."""
    st, dalpha, dv = _equator_rest(12000, 0.005)
    sol = navigate_multirate(st, dalpha, dv, 0.005, 1, 1)
    np.testing.assert_array_equal(sol.q_b_n, np.tile(st.q_b_n, (sol.t.size, 1)))
    assert np.abs(sol.v_ned).max() < 1e-13
    assert np.abs(sol.lat).max() < 1e-18
    assert np.abs(sol.lon - st.lon).max() < 1e-16
    assert np.abs(sol.alt - st.alt).max() < 1e-9


def test_equator_rest_attitude_consistent_with_earth_rate() -> None:
    """At N = 20, P = 4 only the split error of (32) remains; the attitude stays level and
    north-facing, because the attitude and Δφ_l only see the tiny induced velocity."""
    st, dalpha, dv = _equator_rest(12000, 0.005)
    sol = navigate_multirate(st, dalpha, dv, 0.005, 20, 4)
    theta = np.linalg.norm(
        young_error_angles(dcm_from_quat(sol.q_b_n), np.eye(3)[None].repeat(sol.t.size, 0)),
        axis=-1,
    )
    # Split error: a = ½ Ω g (T_nav - T_gyr) (Ω along north at the equator, g down → east),
    # so v_E ≈ a t and the transport-rate error tilts the level frame by ∫ v_E / R dt
    # ≈ a t² / (2R). Measured: max |v_E| 1.2e-3 m/s, attitude 5.5e-9 rad (bound 9.5e-9 rad).
    a = 0.5 * OMEGA_IE * 9.78 * 19 * 0.005
    assert np.abs(sol.v_ned[:, 1]).max() < 1.1 * a * DURATION_S
    assert theta.max() < a * DURATION_S**2 / (2 * 6.378e6)
    assert theta.max() > 0.1 * a * DURATION_S**2 / (2 * 6.378e6)


# ---------------------------------------------------------------------------------------------
# Simultaneous l-frame scheme (Table 2) for comparison
# ---------------------------------------------------------------------------------------------


def test_simultaneous_scheme_is_exact_at_rest(static_ref: Stream) -> None:
    """Table 2 has no b–l split error at rest (f_l + g_l = 0 every T_nav), unlike Table 1
    (Waldmann §4.1: the forced separation "diverges from reality when the vehicle is resting").
    Measured on static.yaml, N = 20: horizontal 7.5e-10 m, velocity 3.2e-10 m/s."""
    e = _errors(
        static_ref,
        navigate_simultaneous(
            state_from_stream(static_ref), static_ref.dalpha, static_ref.dv, static_ref.period, 20
        ),
    )
    assert e["horizontal"] < 1e-6 and e["vertical"] < 1e-6
    assert e["velocity"] < 1e-8 and e["attitude"] < 1e-12
    st, dalpha, dv = _equator_rest(12000, 0.005)
    sol = navigate_simultaneous(st, dalpha, dv, 0.005, 20)
    assert np.abs(sol.v_ned).max() == 0.0
    np.testing.assert_array_equal(sol.q_b_n[-1], st.q_b_n)


def test_multirate_beats_simultaneous_when_maneuvering(default_ref: Stream) -> None:
    """With N = 20 on the maneuvering aircraft, Table 1 (f summed at T_gyr in the fast layer)
    is far more accurate in velocity than Table 2 (f sampled once per T_nav).
    Measured (200 Hz, 60 s): Table 1 (P=1) velocity 5.5e-3 m/s, vertical 0.60 m;
    Table 2 velocity 0.109 m/s, vertical 1.18 m."""
    e_multi = _errors(default_ref, _run(default_ref, 20, 1))
    e_simul = _errors(
        default_ref,
        navigate_simultaneous(
            state_from_stream(default_ref),
            default_ref.dalpha,
            default_ref.dv,
            default_ref.period,
            20,
        ),
    )
    assert e_multi["velocity"] < 0.1 * e_simul["velocity"]
    assert e_multi["vertical"] < 0.7 * e_simul["vertical"]
    assert e_simul["velocity"] < 0.2


def test_table1_radii_close_to_wgs84(default_ref: Stream) -> None:
    """Table 1's first-order radii differ from WGS-84 by O(f²) ≈ 1e-5 relative: over ~5 km of
    flight the positions differ by well under 0.1 m but not by zero (measured 3.4e-2 m)."""
    st = state_from_stream(default_ref)
    args = (st, default_ref.dalpha, default_ref.dv, default_ref.period, 10, 2)
    exact = navigate_multirate(*args)
    table1 = navigate_multirate(*args, table1_radii=True)
    rn, re = radii(exact.lat)
    d = np.hypot((table1.lat - exact.lat) * rn, (table1.lon - exact.lon) * re * np.cos(exact.lat))
    assert 1e-4 < d.max() < 0.1
