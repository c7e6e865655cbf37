"""Variation offsets and Savage 2020 Appendix D smoothing (eqs. (D-2)-(D-11))."""

import numpy as np
import pytest

from strapdown_ros.core.offsets import offset_history
from strapdown_ros.core.rotations import dcm_from_rotvec, orthonormality_error, rotation_angle
from strapdown_ros.core.scan_filter import (
    LinearFilter,
    attitude_offset_increments,
    smooth_attitude_offset,
)

T = 0.005


def constant_rate_scan(n_rest, n_rate, n_after, rate):
    """C at rest, then a constant rate about a fixed axis, then at rest again."""
    steps = np.concatenate([np.zeros(n_rest), np.ones(n_rate), np.zeros(n_after)])
    angle = np.concatenate([[0.0], np.cumsum(steps)]) * rate * T
    return dcm_from_rotvec(angle[:, None] * np.array([0.0, 0.6, 0.8]))


def test_d3_constraint_is_enforced():
    with pytest.raises(ValueError, match=r"\(D-3\)"):
        LinearFilter([0.5, 0.4])
    LinearFilter([0.3, 0.2], [0.5])  # 0.3 + 0.2 + 0.5 = 1


@pytest.mark.parametrize("filt", [LinearFilter.walking_window(21), LinearFilter([0.2], [0.8]),
                                  LinearFilter([0.1, 0.1, 0.1], [0.4, 0.3])])  # fmt: skip
def test_steady_state_lag_matches_d7_and_returns_exactly_when_stopped(filt):
    # 20 deg/s for 4.5 s: a 90 deg scan (near 180 deg the Rodrigues form itself, like scipy's
    # matrices, reaches 1-2e-15 of orthonormality error from rounding alone)
    c = constant_rate_scan(50, 900, 2000, rate=np.radians(20.0))
    smooth = smooth_attitude_offset(c, filt)
    dbeta = attitude_offset_increments(c)
    tau = filt.response_time(T)
    # during steady rotation C_filt lags C by the angle rate * tau (eq. (D-7))
    lag = rotation_angle(np.swapaxes(c, -1, -2) @ smooth)
    expected = np.linalg.norm(dbeta[700]) / T * tau
    assert abs(lag[700] - expected) < 1e-9 * max(expected, 1e-3)
    # after the rotation stops and transients decay, C_filt equals C (gamma -> 0)
    assert lag[-1] < 1e-14
    assert np.max(orthonormality_error(smooth)) <= 1e-15


def test_walking_window_response_time_is_d8():
    for n in (1, 2, 21, 40):
        assert LinearFilter.walking_window(n).response_time(T) == pytest.approx((n - 1) / 2 * T)


def test_smoothing_removes_the_rate_step():
    c = constant_rate_scan(100, 400, 100, rate=np.radians(30.0))
    raw = attitude_offset_increments(c)
    smooth = attitude_offset_increments(smooth_attitude_offset(c, LinearFilter.walking_window(21)))
    step_raw = np.max(np.linalg.norm(np.diff(raw, axis=0), axis=1))
    step_smooth = np.max(np.linalg.norm(np.diff(smooth, axis=0), axis=1))
    assert step_smooth < step_raw / 15


def test_lag_compensation_removes_the_steady_lag():
    c = constant_rate_scan(50, 900, 500, rate=np.radians(20.0))
    comp = smooth_attitude_offset(c, LinearFilter.walking_window(21), lag_compensation=True)
    lag = rotation_angle(np.swapaxes(c, -1, -2) @ comp)
    assert lag[700] < 1e-12
    with pytest.raises(ValueError, match="whole-cycle"):
        smooth_attitude_offset(c, LinearFilter.walking_window(20), lag_compensation=True)


def test_orthonormal_over_a_long_scan():
    h = offset_history(
        {"scan": {"kind": "raster", "amplitude_deg": 30, "rate_dps": 25,
                  "elevation_step_deg": 4, "rows": 4}}, T, 100_000)  # fmt: skip
    assert np.max(orthonormality_error(h.c_bvar_bref)) <= 1e-15


def test_sweep_reaches_amplitude_and_turns_on_time():
    h = offset_history({"scan": {"kind": "sweep", "amplitude_deg": 30, "rate_dps": 20},
                        "filter": {"kind": "none"}}, T, 4000)  # fmt: skip
    yaw = np.arctan2(h.c_bvar_bref[:, 1, 0], h.c_bvar_bref[:, 0, 0])
    assert np.degrees(yaw.max()) == pytest.approx(30.0, abs=1e-9)
    assert np.degrees(yaw.min()) == pytest.approx(-30.0, abs=1e-9)
    assert np.argmax(yaw) * T == pytest.approx(1.5)  # 30 deg at 20 deg/s


def test_bending_sinusoid_and_random():
    h = offset_history({"lever_arm_m": [1, 2, 3], "bending": {"sinusoids": [
        {"amplitude_m": [0, 0, 0.05], "frequency_hz": 4.0}]}}, T, 2000)  # fmt: skip
    z = h.lever_arm[:, 2] - 3
    spectrum = np.abs(np.fft.rfft(z))
    assert np.fft.rfftfreq(z.size, T)[np.argmax(spectrum)] == pytest.approx(4.0, abs=0.1)
    assert np.max(np.abs(z)) == pytest.approx(0.05, rel=3e-3)  # sampled at 200 Hz
    cfg = {"bending": {"random": {"sigma_m": [0.01, 0.02, 0.03], "bandwidth_hz": 2, "seed": 7}}}
    a = offset_history(cfg, T, 400_000).lever_arm
    assert np.allclose(a.std(axis=0), [0.01, 0.02, 0.03], rtol=0.1)
    spec = np.abs(np.fft.rfft(a[:, 2])) ** 2
    freq = np.fft.rfftfreq(a.shape[0], T)
    assert spec[freq > 2.5].sum() < 1e-3 * spec.sum()  # band-limited
    np.testing.assert_array_equal(offset_history(cfg, T, 1000).lever_arm, a[:1001])
    cfg["bending"]["random"]["seed"] = 8
    assert not np.array_equal(offset_history(cfg, T, 1000).lever_arm, a[:1001])


@pytest.mark.parametrize("cfg,key", [
    ({"lever": [1, 2, 3]}, "variation.lever"),
    ({"lever_arm_m": [1, 2]}, "variation.lever_arm_m"),
    ({"bending": {"random": {"sigma_m": [1, 1, 1], "bandwidth_hz": -1}}},
     "variation.bending.random.bandwidth_hz"),
    ({"scan": {"kind": "spiral"}}, "variation.scan.kind"),
    ({"scan": {"kind": "sweep", "amplitude_deg": 10}}, "variation.scan.rate_dps"),
    ({"filter": {"kind": "general", "a": [0.5]}}, "variation.filter"),
    ({"method": 3}, "variation.method"),
])  # fmt: skip
def test_bad_keys_are_named(cfg, key):
    with pytest.raises(ValueError) as info:
        offset_history(cfg, T, 10)
    assert str(info.value).startswith(key), str(info.value)
