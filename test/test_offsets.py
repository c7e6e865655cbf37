"""Offset history of a variation (Savage 2020 eqs. (5)-(7) inputs) from the scenario keys.

The keys are the typed ``variation`` section (:class:`~strapdown_ros.config.variation.
VariationSpec`); the history is evaluated by the ROS-free :class:`~strapdown_ros.core.offsets.
OffsetModel` it builds.
"""

import numpy as np
import pytest

from strapdown_ros.config import ScenarioError, parse_scenario
from strapdown_ros.config.base import validate_section
from strapdown_ros.config.variation import DEFAULT_WINDOW, VariationSpec
from strapdown_ros.core.offsets import OffsetModel, SweepScan
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_rotvec,
    orthonormality_error,
    rot_y,
    rot_z,
    rotation_angle,
)
from strapdown_ros.core.scan_filter import attitude_offset_increments

T = 0.005
NONE = {"kind": "none"}
SCENARIO = {"rate_hz": 200, "initial": {"latitude_deg": 45.0, "longitude_deg": 7.0},
            "trajectory": {"kind": "segments", "segments": [{"duration_s": 1.0}]}}
RASTER = {"kind": "raster", "amplitude_deg": 30, "rate_dps": 25, "elevation_step_deg": 4,
          "rows": 4}  # fmt: skip


def spec(cfg) -> VariationSpec:
    """The validated section (errors as ScenarioError named ``variation.…``)."""
    return validate_section(VariationSpec, cfg, "variation")


def offset_history(cfg, period, cycles):
    return spec(cfg).offset_model().history(period, cycles)


def az_el(c):
    """Azimuth (about z) and elevation (about y) of C = Rz(az) Ry(el), degrees."""
    return np.degrees(np.arctan2(c[:, 1, 0], c[:, 0, 0])), np.degrees(-np.arcsin(c[:, 2, 0]))


def test_defaults_are_zero_offsets():
    for cfg in (None, {}, {"filter": {"kind": "walking_window", "window": 5}}):
        h = offset_history(cfg, T, 10)
        assert h.lever_arm.shape == h.displacement.shape == (11, 3)
        assert np.all(h.lever_arm == 0) and np.all(h.displacement == 0)
        assert np.array_equal(h.c_bvar_bref, np.tile(np.eye(3), (11, 1, 1)))


def test_constant_offsets_and_mounting():
    cfg = {"lever_arm_m": [1, -2, 3], "displacement_m": [0.1, 0.2, -0.3],
           "mounting_rph_deg": [10, -20, 30]}  # fmt: skip
    h = offset_history(cfg, T, 5)
    assert np.all(h.lever_arm == [1, -2, 3]) and np.all(h.displacement == [0.1, 0.2, -0.3])
    mount = dcm_from_euler(*np.radians([10, -20, 30]))
    np.testing.assert_allclose(h.c_bvar_bref, np.tile(mount, (6, 1, 1)), rtol=0, atol=2e-16)
    assert np.all(h.c_bvar_bref == h.c_bvar_bref[0])


def test_scan_is_applied_after_the_mounting():
    cfg = {"mounting_rph_deg": [0, 90, 0], "filter": NONE,
           "scan": {"kind": "sweep", "amplitude_deg": 40, "rate_dps": 20}}  # fmt: skip
    h = offset_history(cfg, T, 200)  # 1 s: yaw 20 deg about the *mounted* z axis
    expected = rot_y(np.pi / 2) @ rot_z(np.radians(20.0))
    assert rotation_angle(h.c_bvar_bref[-1].T @ expected) < 1e-14


def test_segments_rates_about_bvar_axes_then_hold():
    rates = [[0, 0, 0], [10, 0, 0], [0, -20, 5]]
    cfg = {"filter": NONE, "scan": {"kind": "segments", "segments": [
        {"duration_s": 0.5, "rate_dps": r} for r in rates]}}  # fmt: skip
    h = offset_history(cfg, T, 600)  # 3 s: the last segment ends at 1.5 s
    dbeta = attitude_offset_increments(h.c_bvar_bref)  # dbeta[i]: cycle i + 1
    for k, r in enumerate(rates):  # inside each segment Δβ = ω T (Bvar axes)
        inner = dbeta[100 * k + 5 : 100 * (k + 1) - 5]
        np.testing.assert_allclose(inner - np.radians(r) * T, 0.0, rtol=0, atol=2e-16)
    assert np.all(dbeta[301:] == 0.0)  # held after the last segment
    expected = dcm_from_rotvec(np.radians([5, 0, 0])) @ dcm_from_rotvec(np.radians([0, -10, 2.5]))
    assert rotation_angle(h.c_bvar_bref[-1].T @ expected) < 1e-14


def test_sweep_reaches_amplitude_and_turns_on_time():
    cfg = {"scan": {"kind": "sweep", "amplitude_deg": 30, "rate_dps": 20}, "filter": NONE}
    h = offset_history(cfg, T, 2400)  # 12 s: period 4A/R = 6 s
    yaw, _ = az_el(h.c_bvar_bref)
    assert yaw.max() == pytest.approx(30.0, abs=1e-9)
    assert yaw.min() == pytest.approx(-30.0, abs=1e-9)
    assert np.argmax(yaw[:1000]) * T == pytest.approx(1.5)  # A/R
    assert np.argmin(yaw[:1000]) * T == pytest.approx(4.5)  # 3A/R
    assert np.argmax(yaw[1000:]) * T + 5.0 == pytest.approx(7.5)
    np.testing.assert_allclose(np.abs(np.diff(yaw)), 20.0 * T, rtol=1e-9)  # constant rate
    # another axis and a delayed start
    cfg["scan"] |= {"axis": [0, 2, 0], "start_s": 1.0}
    c = offset_history(cfg, T, 400).c_bvar_bref
    assert np.all(c[:201] == np.eye(3))
    pitch = np.degrees(-np.arcsin(c[:, 2, 0]))
    assert pitch[-1] == pytest.approx(20.0, abs=1e-9)


def test_raster_pattern():
    cfg = {"scan": RASTER | {"rows": 3, "elevation_rate_dps": 10}, "filter": NONE}
    h = offset_history(cfg, T, 6000)
    az, el = az_el(h.c_bvar_bref)
    t = np.arange(az.size) * T
    step, sweep = 0.4, 2.4  # 4 deg at 10 deg/s; 60 deg at 25 deg/s
    # first half sweep, then elevation steps (azimuth held at ±A) and full sweeps
    assert az[np.searchsorted(t, 1.2)] == pytest.approx(30.0, abs=1e-9)
    starts = 1.2 + np.arange(8) * (step + sweep)
    rows = [1, 2, 1, 0, 1, 2, 1, 0]
    for k, (t0, row) in enumerate(zip(starts, rows, strict=True)):
        i0, i1 = np.searchsorted(t, t0 + 1e-9), np.searchsorted(t, t0 + step - 1e-9)
        side = 30.0 if k % 2 == 0 else -30.0
        np.testing.assert_allclose(az[i0:i1], side, atol=1e-9)  # azimuth holds while stepping
        j = np.searchsorted(t, t0 + step + 1e-9)
        assert el[j] == pytest.approx(4.0 * row, abs=1e-9)
        assert az[np.searchsorted(t, t0 + step + sweep / 2)] == pytest.approx(0.0, abs=0.2)
    # continuous, rates never above the configured ones
    assert np.max(np.abs(np.diff(az))) <= 25.0 * T * (1 + 1e-9)
    assert np.max(np.abs(np.diff(el))) <= 10.0 * T * (1 + 1e-9)
    assert el.min() == pytest.approx(0.0, abs=1e-9) and el.max() == pytest.approx(8.0, abs=1e-9)


def test_smoothed_scan_orthonormal_over_1e5_cycles_and_lag_compensated():
    for cfg in (
        {"scan": RASTER, "mounting_rph_deg": [3, -4, 50]},
        {"scan": {"kind": "segments", "segments": [
            {"duration_s": 100, "rate_dps": [0, 0, 30]},
            {"duration_s": 200, "rate_dps": [5, -10, 15]},
            {"duration_s": 100, "rate_dps": [0, 0, 0]}]},
         "filter": {"kind": "general", "a": [0.1, 0.1, 0.1], "b": [0.4, 0.3]}},
    ):  # fmt: skip
        for lag in (False, True):
            c = offset_history(cfg | {"lag_compensation": lag}, T, 100_000).c_bvar_bref
            assert np.max(orthonormality_error(c)) <= 1e-15, (cfg, lag)
    # with the centred window the smoothed raster follows the specified one between corners
    raw = offset_history({"scan": RASTER, "filter": NONE}, T, 20_000).c_bvar_bref
    comp = offset_history({"scan": RASTER, "lag_compensation": True}, T, 20_000).c_bvar_bref
    lag = offset_history({"scan": RASTER}, T, 20_000).c_bvar_bref
    i = np.searchsorted(np.arange(20_001) * T, 1.2 + 0.16 + 1.2)  # middle of the first sweep
    assert rotation_angle(raw[i].T @ comp[i]) < 1e-14
    # without compensation: 10 cycles behind at 25 deg/s (D-7), (D-8)
    assert rotation_angle(raw[i].T @ lag[i]) == pytest.approx(np.radians(25 * 10 * T), rel=1e-9)


def test_history_is_a_bit_reproducible_prefix():
    random = {"sigma_m": [0.01, 0.01, 0.01], "bandwidth_hz": 3, "seed": 5}
    cfg = {"scan": RASTER, "lag_compensation": True, "lever_arm_m": [1, 0, 0],
           "bending": {"random": random}}  # fmt: skip
    long = offset_history(cfg, T, 5000)
    short = offset_history(cfg, T, 1234)
    for a, b in zip(
        (short.lever_arm, short.displacement, short.c_bvar_bref),
        (long.lever_arm, long.displacement, long.c_bvar_bref),
        strict=True,
    ):
        assert np.array_equal(a, b[: a.shape[0]])


def test_bending_sinusoid_amplitude_frequency_phase():
    cfg = {"lever_arm_m": [1, 2, 3], "bending": {"sinusoids": [
        {"amplitude_m": [0, 0.02, 0.05], "frequency_hz": 4.0, "phase_deg": 30},
        {"amplitude_m": [0.01, 0, 0], "frequency_hz": 7.5}]}}  # fmt: skip
    h = offset_history(cfg, T, 2000)  # 10 s
    t = np.arange(2001) * T
    # least-squares fit of sin / cos at the configured frequencies
    basis = np.stack([np.sin(2 * np.pi * 4 * t), np.cos(2 * np.pi * 4 * t),
                      np.sin(2 * np.pi * 7.5 * t), np.cos(2 * np.pi * 7.5 * t),
                      np.ones_like(t)], axis=1)  # fmt: skip
    coef, *_ = np.linalg.lstsq(basis, h.lever_arm, rcond=None)
    amp4 = np.hypot(coef[0], coef[1])
    np.testing.assert_allclose(amp4, [0, 0.02, 0.05], atol=1e-12)
    np.testing.assert_allclose(np.hypot(coef[2], coef[3]), [0.01, 0, 0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(np.arctan2(coef[1, 2], coef[0, 2])), 30.0, atol=1e-9)
    np.testing.assert_allclose(coef[4], [1, 2, 3], atol=1e-12)
    spectrum = np.abs(np.fft.rfft(h.lever_arm[:-1, 2] - 3))
    assert np.fft.rfftfreq(2000, T)[np.argmax(spectrum)] == pytest.approx(4.0)


def test_random_bending_sigma_bandwidth_and_seed():
    cfg = {"bending": {"random": {"sigma_m": [0.01, 0.02, 0.03], "bandwidth_hz": 2, "seed": 7}}}
    period = 0.01
    a = offset_history(cfg, period, 200_000).lever_arm  # 2000 s
    np.testing.assert_allclose(a.std(axis=0), [0.01, 0.02, 0.03], rtol=0.1)
    assert np.all(np.abs(a.mean(axis=0)) < 0.1 * np.array([0.01, 0.02, 0.03]))
    freq = np.fft.rfftfreq(a.shape[0], period)
    window = np.hanning(a.shape[0])  # sharp leakage skirts
    for axis in range(3):
        power = np.abs(np.fft.rfft((a[:, axis] - a[:, axis].mean()) * window)) ** 2
        assert power[freq > 2.05].sum() < 1e-10 * power.sum()  # band-limited to 2 Hz
        low, high = power[freq <= 1.0].sum(), power[(freq > 1.0) & (freq <= 2.05)].sum()
        assert low == pytest.approx(high, rel=0.2)  # fills the band evenly
    # seed: same bits, different seed -> different motion
    np.testing.assert_array_equal(offset_history(cfg, period, 1000).lever_arm, a[:1001])
    model = spec(cfg).offset_model()
    np.testing.assert_array_equal(model.lever_arm_at(np.arange(1001) * period), a[:1001])
    cfg["bending"]["random"]["seed"] = 8
    assert not np.array_equal(offset_history(cfg, period, 1000).lever_arm, a[:1001])


def test_settings_and_passthrough_keys():
    cfg = {"method": 1, "gravity": "first_order", "topics": {"imu": "/x"}, "lever_arm_m": [1, 0, 0]}
    s = spec(cfg)
    assert (s.method, s.gravity, s.topics) == (1, "first_order", {"imu": "/x"})
    d = spec({})
    assert (d.method, d.gravity, d.topics, d.lag_compensation) == (2, "full", None, False)
    assert d.filter.kind == "walking_window" and d.filter.window == DEFAULT_WINDOW == 21
    assert d.scan is None and d.bending is None
    # null means the default, as it always did; a filter without kind is a walking window
    n = spec({"scan": None, "filter": {"window": 5}, "lever_arm_m": None})
    assert n.scan is None and n.filter.kind == "walking_window" and n.filter.window == 5
    r = spec({"scan": RASTER})
    assert r.scan.elevation_rate_dps is None and r.scan.start_s == 0.0
    b = spec({"bending": {"random": {"sigma_m": [1, 1, 1], "bandwidth_hz": 2}}})
    assert (b.bending.random.seed, b.bending.random.components) == (0, 64)


@pytest.mark.parametrize(
    ("cfg", "message"),
    [
        ([1, 2], "variation: must be a mapping"),
        ({"method": 3}, "variation.method: must be 1 or 2, got 3"),
        ({"method": True}, "variation.method: must be 1 or 2, got True"),
        ({"gravity": "flat"}, "variation.gravity: must be one of"),
        ({"lever": [1, 2, 3]},
         "variation.lever: unknown key (did you mean 'lever_arm_m'?); expected one of: "
         "lever_arm_m"),
        ({"lever_arm_m": [1, 2]}, "variation.lever_arm_m: must be a list of 3"),
        ({"displacement_m": [1, 2, "x"]},
         "variation.displacement_m[2]: must be a number, got str 'x'"),
        ({"mounting_rph_deg": [0, float("nan"), 0]},
         "variation.mounting_rph_deg[1]: must be finite, got nan"),
        ({"lag_compensation": 1}, "variation.lag_compensation: must be true or false"),
        ({"bending": {"wobble": 1}}, "variation.bending.wobble: unknown key"),
        ({"bending": {"sinusoids": {"amplitude_m": [1, 1, 1]}}},
         "variation.bending.sinusoids: must be a list"),
        ({"bending": {"sinusoids": [{"amplitude_m": [1, 1, 1]}]}},
         "variation.bending.sinusoids[0].frequency_hz: is required"),
        ({"bending": {"sinusoids": [{"amplitude_m": [1, 1, 1], "frequency_hz": 0}]}},
         "variation.bending.sinusoids[0].frequency_hz: must be > 0.0, got 0"),
        ({"bending": {"random": {"sigma_m": [1, 1, 1], "bandwidth_hz": -1}}},
         "variation.bending.random.bandwidth_hz: must be > 0.0, got -1"),
        ({"bending": {"random": {"sigma_m": [1, -1, 1], "bandwidth_hz": 1}}},
         "variation.bending.random.sigma_m: must be >= 0"),
        ({"bending": {"random": {"sigma_m": [1, 1, 1], "bandwidth_hz": 1, "seed": 1.5}}},
         "variation.bending.random.seed: must be an integer, got float 1.5"),
        ({"bending": {"random": {"sigma_m": [1, 1, 1], "bandwidth_hz": 1, "components": 0}}},
         "variation.bending.random.components: must be >= 1, got 0"),
        ({"scan": {"kind": "spiral"}},
         "variation.scan: kind must be one of: 'segments', 'sweep', 'raster'; got 'spiral'"),
        ({"scan": {"amplitude_deg": 3}}, "variation.scan: is missing its 'kind'"),
        ({"scan": "sweep"}, "variation.scan: must be a mapping"),
        ({"scan": {"kind": "sweep", "amplitude_deg": 10}}, "variation.scan.rate_dps: is required"),
        ({"scan": {"kind": "sweep", "amplitude_deg": 10, "rate_dps": -5}},
         "variation.scan.rate_dps: must be > 0.0, got -5"),
        ({"scan": {"kind": "sweep", "amplitude_deg": 10, "rate_dps": 5, "axis": [0, 0, 0]}},
         "variation.scan.axis: must not be zero"),
        ({"scan": {"kind": "sweep", "amplitude_deg": 10, "rate_dps": 5, "rows": 2}},
         "variation.scan.rows: unknown key; expected one of: kind, axis"),
        ({"scan": {"kind": "sweep", "amplitude_deg": 10, "rate_dps": 5, "start_s": -1}},
         "variation.scan.start_s: must be >= 0"),
        ({"scan": RASTER | {"rows": 0}}, "variation.scan.rows: must be >= 1, got 0"),
        ({"scan": {k: v for k, v in RASTER.items() if k != "rows"}},
         "variation.scan.rows: is required"),
        ({"scan": RASTER | {"elevation_rate_dps": 0}},
         "variation.scan.elevation_rate_dps: must be > 0"),
        ({"scan": {"kind": "segments"}}, "variation.scan.segments: is required"),
        ({"scan": {"kind": "segments", "segments": []}},
         "variation.scan.segments: must be a non-empty list"),
        ({"scan": {"kind": "segments", "segments": [{"duration_s": 0, "rate_dps": [1, 0, 0]}]}},
         "variation.scan.segments[0].duration_s: must be > 0"),
        ({"scan": {"kind": "segments", "segments": [
            {"duration_s": 1, "rate_dps": [1, 0, 0], "rate": 1}]}},
         "variation.scan.segments[0].rate: unknown key (did you mean 'rate_dps'?); "
         "expected one of: duration_s, rate_dps"),
        ({"filter": {"kind": "kalman"}},
         "variation.filter: kind must be one of: 'walking_window', 'general', 'none'"),
        ({"filter": {"kind": "walking_window", "window": 0}},
         "variation.filter.window: must be >= 1, got 0"),
        ({"filter": {"kind": "walking_window", "window": 2.5}}, "variation.filter.window: must"),
        ({"filter": {"kind": "none", "window": 3}}, "variation.filter.window: unknown key"),
        ({"filter": {"kind": "general"}}, "variation.filter.a: is required"),
        ({"filter": {"kind": "general", "a": [0.5, "x"]}},
         "variation.filter.a[1]: must be a number, got str 'x'"),
        ({"filter": {"kind": "general", "a": [0.5]}},
         r"variation.filter: coefficients a=[0.5], b=[] violate Savage eq. (D-3)"),
        ({"filter": {"kind": "general", "a": [-1.0], "b": [2.0]}},
         "variation.filter.b: the recursion with b=[2.0] is unstable"),
    ],
)  # fmt: skip
def test_bad_keys_are_named(cfg, message):
    with pytest.raises(ScenarioError) as info:
        spec(cfg)
    assert str(info.value).startswith(message), str(info.value)
    # the scenario names the same key with the same message (validate and generate use it)
    doc = SCENARIO | {"variation": cfg}
    with pytest.raises(ScenarioError) as whole:
        parse_scenario(doc)
    assert str(whole.value) == str(info.value)


def test_scan_faster_than_half_a_turn_per_cycle_is_rejected():
    doc = SCENARIO | {"rate_hz": 100}
    sweep = {"kind": "sweep", "amplitude_deg": 30}
    parse_scenario(doc | {"variation": {"scan": sweep | {"rate_dps": 17_999}}})
    with pytest.raises(ScenarioError, match=r"^variation\.scan\.rate_dps: the scan turns 18000"):
        parse_scenario(doc | {"variation": {"scan": sweep | {"rate_dps": 18_000}}})
    raster = RASTER | {"elevation_rate_dps": 20_000}
    with pytest.raises(ScenarioError, match=r"^variation\.scan\.elevation_rate_dps: "):
        parse_scenario(doc | {"variation": {"scan": raster}})
    segments = {"kind": "segments", "segments": [{"duration_s": 1, "rate_dps": [0, 0, 1]},
                                                 {"duration_s": 1, "rate_dps": [0, 2e4, 0]}]}
    with pytest.raises(ScenarioError, match=r"^variation\.scan\.segments: "):
        parse_scenario(doc | {"variation": {"scan": segments}})


def test_core_model_takes_plain_arguments():
    model = OffsetModel()  # no offsets
    h = model.history(T, 3)
    assert np.all(h.lever_arm == 0) and np.array_equal(h.c_bvar_bref, np.tile(np.eye(3), (4, 1, 1)))
    assert np.array_equal(SweepScan(np.array([0.0, 2.0, 0.0]), 0.1, 0.2).axis, [0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="axis"):
        SweepScan(np.zeros(3), 0.1, 0.2)
    with pytest.raises(ValueError, match="period_s"):
        model.history(0.0, 3)
    with pytest.raises(ValueError, match="cycles"):
        model.history(T, -1)
    assert set(VariationSpec.model_fields) == {
        "lever_arm_m", "bending", "displacement_m", "mounting_rph_deg", "scan", "filter",
        "lag_compensation", "method", "gravity", "topics",
    }  # fmt: skip
