"""Savage 2020 Appendix D: smoothing of a specified attitude offset (eqs. (D-2)-(D-11))."""

import numpy as np
import pytest

from strapdown_ros.core.exact_update import g_c
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_rotvec,
    orthonormality_error,
    rot_z,
    rotation_angle,
)
from strapdown_ros.core.scan_filter import (
    LinearFilter,
    attitude_offset_increments,
    smooth_attitude_offset,
    smoothing_terms,
)

T = 0.005
AXIS = np.array([0.0, 0.0, 1.0])  # rotation axis in Bvar
MOUNT = dcm_from_euler(0.3, -0.5, 1.2)  # so that C is a general rotation

FILTERS = {
    "window21": LinearFilter.walking_window(21),
    "window20": LinearFilter.walking_window(20),
    "first_order": LinearFilter([0.2], [0.8]),
    "second_order": LinearFilter([0.1, 0.1, 0.1], [0.4, 0.3]),
    "lead": LinearFilter([2.0, -1.0]),  # tau = -T: compensation delays the input by 1 cycle
}


def rate_profile(*pieces):
    """C = MOUNT Rz(θ_m), m = 0..N-1, for consecutive (cycles, rate rad/s) pieces of θ."""
    steps = np.concatenate([np.full(n, rate) for n, rate in pieces])
    angle = np.concatenate([[0.0], np.cumsum(steps)]) * T
    return MOUNT @ rot_z(angle)


def test_d2_increments_of_a_constant_rate():
    c = rate_profile((10, 0.0), (50, np.radians(30.0)))
    dbeta = attitude_offset_increments(c)
    assert dbeta.shape == (60, 3)
    np.testing.assert_allclose(dbeta[:10], 0.0, atol=1e-18)
    # exact extraction: rounding of the matrix elements only (~1e-16 rad absolute)
    np.testing.assert_allclose(dbeta[10:] - np.radians(30.0) * T * AXIS, 0.0, atol=2e-16)


def test_d3_constraint_is_enforced():
    with pytest.raises(ValueError, match=r"a=\[0\.5, 0\.4\], b=\[\].*\(D-3\)"):
        LinearFilter([0.5, 0.4])
    with pytest.raises(ValueError, match=r"\(D-3\)"):
        LinearFilter([0.3, 0.2], [0.5 + 1e-11])
    LinearFilter([0.3, 0.2], [0.5 + 1e-13])  # within 1e-12
    with pytest.raises(ValueError, match="unstable"):
        LinearFilter([-1.0], [2.0])  # obeys (D-3), pole at z = 2: γ would diverge
    with pytest.raises(ValueError, match="window"):
        LinearFilter.walking_window(0)


def test_response_time_formula_and_d8():
    for n in (1, 2, 21, 40):  # r_a = n - 1: tau = r_a T / 2 (D-8)
        assert LinearFilter.walking_window(n).response_time(T) == pytest.approx((n - 1) / 2 * T)
    # (D-7): (sum i a_i + sum i b_i) / sum a_i * T
    assert FILTERS["first_order"].response_time(T) == pytest.approx(0.8 / 0.2 * T)
    assert FILTERS["second_order"].response_time(T) == pytest.approx((0.3 + 1.0) / 0.3 * T)


@pytest.mark.parametrize("name", sorted(FILTERS) + ["window1", "window2", "window40"])
def test_steady_state_gamma_is_minus_tau_over_t_times_dbeta(name):
    filt = FILTERS.get(name) or LinearFilter.walking_window(int(name[6:]))
    c = rate_profile((30, 0.0), (1500, np.radians(20.0)), (3000, 0.0))
    terms = smoothing_terms(c, filt)
    m = 1000  # steady rotation, transients decayed
    dbeta = np.radians(20.0) * T * AXIS  # nominal Δβ; (D-2) extraction adds ~3e-17 rad noise
    np.testing.assert_allclose(terms.dbeta[m - 1], dbeta, rtol=0, atol=1e-16)  # [i] is m = i+1
    # filtered increments equal the input ones in steady state (D-3)
    gain = np.abs(filt.a).sum() + np.abs(filt.b).sum()  # of the extraction noise
    np.testing.assert_allclose(terms.dbeta_flt[m - 1], dbeta, rtol=0, atol=1e-16 * gain)
    # γ = -(τ_Flt / T) Δβ, (D-6)/(D-7); for the walking window τ_Flt = r_a T / 2 (D-8)
    cycles = filt.response_time(T) / T
    np.testing.assert_allclose(
        terms.gamma[m], -cycles * dbeta, rtol=0, atol=1e-16 * (1 + abs(cycles))
    )
    if name.startswith("window"):
        r_a = filt.a.size - 1
        np.testing.assert_allclose(terms.gamma[m], -r_a / 2 * dbeta, rtol=0, atol=1e-16 * (1 + r_a))
    # C_filt lags C by |Δβ|/T τ_Flt (text after (D-11))
    smooth = smooth_attitude_offset(c, filt)
    lag = rotation_angle(np.swapaxes(c[m], -1, -2) @ smooth[m])
    assert lag == pytest.approx(np.linalg.norm(dbeta) / T * abs(filt.response_time(T)), rel=1e-9)


@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("lag", [False, True])
def test_gamma_equals_the_d11_recursion(name, lag):
    rng = np.random.default_rng(3)
    c = rate_profile((5, 0.0), (200, 0.3), (100, -0.7), *((1, r) for r in rng.normal(size=80)))
    terms = smoothing_terms(c, FILTERS[name], lag)
    recursion = terms.gamma[0] + np.cumsum(terms.dbeta_flt - terms.dbeta, axis=0)  # (D-11)
    np.testing.assert_allclose(terms.gamma[1:], recursion, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_filtered_offset_returns_to_the_specified_one_when_the_scan_stops(name):
    filt = FILTERS[name]
    # 100 000 cycles: 40 deg/s, -25 deg/s, then at rest
    c = rate_profile((100, 0.0), (60_000, np.radians(40.0)), (20_000, np.radians(-25.0)),
                     (19_900, 0.0))  # fmt: skip
    terms = smoothing_terms(c, filt)
    smooth = smooth_attitude_offset(c, filt)
    assert np.max(np.abs(terms.gamma[-1])) <= 1e-15
    assert rotation_angle(c[-1].T @ smooth[-1]) <= 1e-15
    if not filt.b.size:  # finite response: exactly C again r_a cycles after the stop
        r_a = filt.a.size - 1
        stop = 100 + 60_000 + 20_000
        assert np.all(terms.gamma[stop + r_a :] == 0.0)
        assert np.array_equal(smooth[stop + r_a :], c[stop + r_a :])
    assert np.max(orthonormality_error(smooth)) <= 1e-15


def test_smoothing_removes_the_rate_step():
    c = rate_profile((100, 0.0), (400, np.radians(30.0)), (100, np.radians(-10.0)), (100, 0.0))
    raw = attitude_offset_increments(c)
    smooth = attitude_offset_increments(smooth_attitude_offset(c, FILTERS["window21"]))
    step_raw = np.max(np.linalg.norm(np.diff(raw, axis=0), axis=1))
    step_smooth = np.max(np.linalg.norm(np.diff(smooth, axis=0), axis=1))
    assert step_smooth < step_raw / 20  # 21-cycle ramps instead of steps
    # the smoothed increments are the (D-4) output
    terms = smoothing_terms(c, FILTERS["window21"])
    np.testing.assert_allclose(smooth, terms.dbeta_flt, rtol=0, atol=2e-16)


def test_lag_compensation_removes_the_steady_lag():
    c = rate_profile((50, 0.0), (900, np.radians(20.0)), (500, 0.0))
    dbeta = np.radians(20.0) * T * AXIS
    # odd walking window: shift (n - 1)/2 cycles, centred window, no lag
    terms = smoothing_terms(c, FILTERS["window21"], lag_compensation=True)
    assert terms.shift == 10
    assert np.max(np.abs(terms.gamma[100:900])) <= 1e-15
    comp = smooth_attitude_offset(c, FILTERS["window21"], lag_compensation=True)
    assert np.max(rotation_angle(np.swapaxes(c, -1, -2) @ comp)[100:900]) <= 1e-15
    # the filtered rotation starts k cycles before the specified one (anticipation)
    flt = np.linalg.norm(terms.dbeta_flt, axis=1)
    assert flt[39] == 0.0 and flt[40] > 0.0  # Δβ_Flt,41 is the first nonzero (x_41 = Δβ_51)
    # even window: tau = 9.5 cycles, shift rounds to 10, residual lead of half a cycle
    terms = smoothing_terms(c, FILTERS["window20"], lag_compensation=True)
    assert terms.shift == 10
    np.testing.assert_allclose(terms.gamma[500], 0.5 * dbeta, rtol=0, atol=1e-16)
    # recursive filter with a whole-cycle tau (4 cycles)
    terms = smoothing_terms(c, FILTERS["first_order"], lag_compensation=True)
    assert terms.shift == 4
    assert np.max(np.abs(terms.gamma[500:900])) <= 1e-15
    # lead filter (tau = -T): the input is delayed by one cycle, again no steady error
    terms = smoothing_terms(c, FILTERS["lead"], lag_compensation=True)
    assert terms.shift == -1
    assert np.max(np.abs(terms.gamma[100:900])) <= 1e-15
    # every case returns to the specified offset once at rest
    for filt in FILTERS.values():
        g = smoothing_terms(c, filt, lag_compensation=True).gamma
        assert np.max(np.abs(g[-1])) <= 1e-15


def test_lag_compensation_anticipates_a_motion_at_the_start():
    c = rate_profile((300, np.radians(20.0)), (300, 0.0))  # moving from cycle 1 on
    terms = smoothing_terms(c, FILTERS["window21"], lag_compensation=True)
    # γ_0 is the filtered rotation accrued before t0: 10 ramp-up cycles of 1..10 / 21 Δβ
    dbeta = np.radians(20.0) * T * AXIS
    np.testing.assert_allclose(terms.gamma[0], sum(range(1, 11)) / 21 * dbeta, rtol=0, atol=1e-16)
    assert np.max(np.abs(terms.gamma[20:280])) <= 1e-15
    assert np.all(terms.gamma[-(300 - 10) :] == 0.0)


def test_g_c_form_is_the_exact_update_one():
    gamma = np.random.default_rng(0).normal(size=(1000, 3)) * np.logspace(-9, 0, 1000)[:, None]
    assert np.array_equal(dcm_from_rotvec(gamma), g_c(gamma))  # (D-9) is the eq. (2) G_C
