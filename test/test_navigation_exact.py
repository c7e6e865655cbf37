"""High-accuracy (``exact``) mode of the multirate navigator, streaming use, vertical damping.

The exact mode's fast layer is checked against an independent product of Savage 2020's
``G_C``, ``G_V``, ``G_R`` matrices (``core.exact_update.g_matrices``); the whole navigator
against the truth of exact reference streams (docs/interface.md §3), where its only errors are
rounding and
the gravity quadrature; and the paper mode against its known first-order behaviour.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.core.exact_update import g_matrices
from strapdown_ros.core.navigation import (
    MultirateNavigator,
    NavState,
    SimultaneousNavigator,
    VerticalDamping,
    _kernels,
    navigate_multirate,
    navigate_simultaneous,
    state_from_stream,
    truth_navigation,
)
from strapdown_ros.core.navigation.errors import navigation_errors
from strapdown_ros.core.stream import Stream
from strapdown_ros.stages.trajectory import generate_reference

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"


def _reference(name: str, duration_s: float, overrides: list[str] | None = None) -> Stream:
    return generate_reference(
        load_scenario(SCENARIOS / f"{name}.yaml", overrides or [], duration_s)
    )


@pytest.fixture(scope="module")
def default_60() -> Stream:
    return _reference("default", 60.0)


def _max_errors(stream: Stream, n: int, p: int, mode: str = "exact") -> dict[str, float]:
    """Largest errors of the multirate navigator (N, P, ``mode``) started on and run through
    ``stream`` against its truth: horizontal, vertical (m), velocity (m/s), attitude (rad)."""
    sol = navigate_multirate(
        state_from_stream(stream), stream.dalpha, stream.dv, stream.period, n, p, mode=mode
    )
    e = navigation_errors(sol, stream)
    return {
        "horizontal": float(e.horizontal.max()),
        "vertical": float(np.abs(e.position_ned[:, 2]).max()),
        "velocity": float(np.abs(e.velocity_ned).max()),
        "attitude": float(np.abs(e.attitude_young).max()),
    }


def test_fast_layer_equals_matrix_product() -> None:
    """Γ, W, S of one cycle equal the explicit products of G_C, G_V, G_R (eqs. (2)-(4))."""
    rng = np.random.default_rng(3)
    n, t = 17, 0.01
    da = rng.normal(scale=0.3, size=(n, 3))  # large angles: the series and closed forms both
    da[3] *= 12.0  # one rotation above the series switch (2 rad)
    dv = rng.normal(scale=2.0, size=(n, 3))
    gc, gv, gr = g_matrices(da)
    gam, w, s = np.eye(3), np.zeros(3), np.zeros(3)
    for j in range(n):
        s = s + w * t + gam @ gr[j] @ dv[j] * t
        w = w + gam @ gv[j] @ dv[j]
        gam = gam @ gc[j]
    out = np.empty((3, 3)), np.empty(3), np.empty(3)
    for kernel in (
        _kernels.exact_fast_kernel,
        getattr(_kernels.exact_fast_kernel, "py_func", None),
    ):
        if kernel is None:
            continue
        kernel(da, dv, 0, n, t, *out)
        np.testing.assert_allclose(out[0], gam, rtol=0, atol=1e-14)
        np.testing.assert_allclose(out[1], w, rtol=0, atol=1e-13)
        np.testing.assert_allclose(out[2], s, rtol=0, atol=1e-14)


def test_rotation_coefficients_scalar_match_series() -> None:
    from strapdown_ros.core.series import rotation_coefficients

    x = np.array([0.0, 1e-8, 0.3, 1.999999, 2.0, 2.5, 3.1, 7.0])
    ref = rotation_coefficients(x)
    for i, xi in enumerate(x):
        got = _kernels.rotation_coefficients_scalar(float(xi))
        for k in range(4):
            assert got[k] == pytest.approx(ref[k][i], rel=2e-16, abs=1e-300)


#: Measured maximum errors over the 60 s (horizontal, vertical m; velocity m/s; attitude rad);
#: the test's limits are 10 times these. Without the compensated summation of R and V in the
#: kernel, N=1 reaches 4.3e-8 m horizontal (16 times its figure).
EXACT_60S = {
    (1, 1): (2.7e-9, 2.7e-9, 1.6e-11, 1.3e-13),
    (10, 2): (9.6e-9, 6.0e-8, 2.0e-9, 6.5e-15),
    (12, 4): (3.1e-9, 2.0e-8, 6.6e-10, 5.7e-15),
    (20, 1): (1.6e-7, 9.8e-7, 3.3e-8, 2.1e-14),
}


@pytest.mark.parametrize(("n", "p"), list(EXACT_60S))
def test_exact_mode_on_maneuvering_aircraft(default_60: Stream, n: int, p: int) -> None:
    """60 s of default.yaml at 200 Hz: errors at rounding/quadrature level (:data:`EXACT_60S`),
    against 0.29 m for the paper mode at N=10."""
    err = _max_errors(default_60, n, p)
    limits = dict(zip(("horizontal", "vertical", "velocity", "attitude"), EXACT_60S[n, p],
                      strict=True))  # fmt: skip
    for key, measured in limits.items():
        assert err[key] < 10 * measured, (key, err[key], measured)


def test_exact_mode_beats_paper_mode_by_orders(default_60: Stream) -> None:
    exact = _max_errors(default_60, 10, 2, "exact")
    paper = _max_errors(default_60, 10, 2, "paper")
    for key in exact:
        assert exact[key] * 1e4 < paper[key], (key, exact[key], paper[key])


def test_exact_mode_at_rest_holds_position() -> None:
    """static.yaml (IMU at rest on the rotating Earth) for 10 min at N = 20 (measured: 2.4e-7 m
    horizontal, 2.3e-7 m vertical, 8.3e-10 m/s; limits 10 times these)."""
    ref = _reference("static", 600.0)
    err = _max_errors(ref, 20, 4)
    assert err["horizontal"] < 2.4e-6
    assert err["vertical"] < 2.3e-6
    assert err["velocity"] < 8.3e-9


def test_exact_engines_agree(default_60: Stream) -> None:
    st = state_from_stream(default_60)
    m = 2000
    args = (st, default_60.dalpha[:m], default_60.dv[:m], default_60.period, 10, 3)
    nb = navigate_multirate(*args, mode="exact", engine="numba" if _kernels.HAVE_NUMBA else None)
    py = navigate_multirate(*args, mode="exact", engine="python")
    np.testing.assert_allclose(nb.lat, py.lat, rtol=0, atol=1e-15)
    np.testing.assert_allclose(nb.alt, py.alt, rtol=0, atol=1e-8)
    np.testing.assert_allclose(nb.v_ned, py.v_ned, rtol=0, atol=1e-11)
    np.testing.assert_allclose(nb.q_b_n, py.q_b_n, rtol=0, atol=1e-14)


@pytest.mark.parametrize(
    ("mode", "kind"), [("exact", "multirate"), ("paper", "multirate"), ("paper", "simultaneous")]
)
def test_streaming_equals_one_call_bit_for_bit(default_60: Stream, mode: str, kind: str) -> None:
    """The node feeds increments as they arrive; the outputs must equal the offline run's bits."""
    st = state_from_stream(default_60)
    m = 3001
    da, dv, t = default_60.dalpha[:m], default_60.dv[:m], default_60.period

    def make():
        if kind == "simultaneous":
            return SimultaneousNavigator(st, t, 10)
        return MultirateNavigator(st, t, 10, 2, mode=mode)

    whole = make().run(da, dv)
    nav = make()
    parts = []
    rng = np.random.default_rng(0)
    i = 0
    while i < m:
        k = int(rng.integers(1, 40))
        parts.append(nav.run(da[i : i + k], dv[i : i + k]))
        i += k
    assert nav.pending == m % 10
    for name in ("t", "lat", "lon", "alt", "v_ned", "q_b_n"):
        got = np.concatenate([getattr(p, name) for p in parts])
        assert got.tobytes() == getattr(whole, name).tobytes(), name
    assert nav.state.lat == whole.lat[-1]


def test_offline_functions_prepend_initial(default_60: Stream) -> None:
    st = state_from_stream(default_60)
    da, dv = default_60.dalpha[:95], default_60.dv[:95]
    sol = navigate_multirate(st, da, dv, default_60.period, 10, 2, mode="exact")
    assert sol.t.size == 10 and sol.lat[0] == st.lat
    sim = navigate_simultaneous(st, da, dv, default_60.period, 10)
    assert sim.t.size == 10 and np.array_equal(sim.q_b_n[0], st.q_b_n)


def test_bad_arguments() -> None:
    st = NavState(0.0, 0.7, 0.1, 100.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="mode"):
        MultirateNavigator(st, 0.01, 10, 2, mode="rk4")
    with pytest.raises(ValueError, match="T_gyr"):
        MultirateNavigator(st, float("nan"), 10, 2)
    with pytest.raises(ValueError, match="damping"):
        MultirateNavigator(st, 0.01, 10, 2, mode="exact", damping=VerticalDamping())
    nav = MultirateNavigator(st, 0.01, 10, 2, damping=VerticalDamping())
    with pytest.raises(ValueError, match="h_aux"):
        nav.run(np.zeros((10, 3)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="h_aux has 2 values for 1 cycles"):
        nav.run(np.zeros((10, 3)), np.zeros((10, 3)), h_aux=[1.0, 2.0])


# ---------------------------------------------------------------------------------------------
# Vertical channel damping (Table 1, s' and s'')
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def static_300() -> Stream:
    return _reference("static", 300.0)


def _with_altitude_error(st: NavState, dh: float) -> NavState:
    return NavState(st.t, st.lat, st.lon, st.alt + dh, st.v_ned, st.q_b_n)


def _altitude_errors(ref: Stream, algorithm: str, damping: VerticalDamping | None) -> np.ndarray:
    st = _with_altitude_error(state_from_stream(ref), 10.0)
    n = 20
    cycles = ref.cycles // n
    _, _, _, h_true, _, _ = truth_navigation(ref, np.arange(cycles) * n)
    h_aux = h_true if damping is not None else None
    if algorithm == "multirate":
        sol = navigate_multirate(st, ref.dalpha, ref.dv, ref.period, n, 2, damping=damping,
                                 h_aux=h_aux)  # fmt: skip
    else:
        sol = navigate_simultaneous(st, ref.dalpha, ref.dv, ref.period, n, damping=damping,
                                    h_aux=h_aux)  # fmt: skip
    return sol.alt - truth_navigation(ref, np.arange(sol.t.size) * n)[3]


@pytest.mark.parametrize("algorithm", ["multirate", "simultaneous"])
def test_vertical_damping_stabilizes_altitude(static_300: Stream, algorithm: str) -> None:
    """A 10 m initial altitude error: the free channel diverges (instability, time constant
    √(R/2g) ≈ 570 s), the damped loop (k1 = k2 = 1) pulls it to the auxiliary altitude, and
    Table 1's printed signs blow up (δḧ − δḣ − δh = 0)."""
    free = _altitude_errors(static_300, algorithm, None)
    damped = _altitude_errors(static_300, algorithm, VerticalDamping())
    assert free[-1] > 10.5  # grows without damping (free-inertial instability)
    assert abs(damped[-1]) < 0.05 < 10.0  # converged to the aux altitude within the b-l error
    with np.errstate(all="ignore"):
        paper = _altitude_errors(static_300, algorithm, VerticalDamping(paper_signs=True))
    assert not np.isfinite(paper[-1]) or abs(paper[-1]) > 1e6
