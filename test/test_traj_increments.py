"""Savage's constant-rate segments (the ``increments`` kind): exactness and a physical check."""

import math
import re

import numpy as np
import pytest

from strapdown_ros.config import ScenarioError, parse_scenario
from strapdown_ros.config.trajectory import core_initial
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ned_to_ecef,
    e0_state_to_ecef,
    geodetic_to_ecef,
)
from strapdown_ros.core.exact_update import one_step_residuals
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.rotations import dcm_from_euler, rotation_angle
from strapdown_ros.core.trajectory.base import TrajectoryError
from strapdown_ros.core.trajectory.increments import (
    IncrementSegment,
    generate_increments_stream,
    whole_cycles,
)

INITIAL = {
    "latitude_deg": 45.0,
    "longitude_deg": 7.0,
    "altitude_m": 300.0,
    "velocity_ned_mps": [0.0, 0.0, 0.0],
    "attitude_rph_deg": [10.0, -5.0, 30.0],
}


def stream(initial, segments, rate_hz, t0_ns, gravity_model="j2"):
    """The stream of a scenario's ``initial`` and ``trajectory.segments`` (typed model)."""
    scenario = parse_scenario(
        {
            "rate_hz": rate_hz,
            "initial": initial,
            "trajectory": {"kind": "increments", "segments": segments},
        }
    )
    return generate_increments_stream(
        *core_initial(scenario.initial),
        scenario.trajectory.core_segments(),
        scenario.period_ns,
        t0_ns,
        gravity_model=gravity_model,
    )


MANEUVER = [
    {"duration_s": 0.5, "omega_dps": [0, 0, 0], "specific_force_mps2": [0, 0, -9.8]},
    {"duration_s": 1.0, "omega_dps": [30, -20, 90], "specific_force_mps2": [5, 1, -12]},
    {"duration_s": 0.25, "omega_dps": [400, 0, -200], "specific_force_mps2": [-3, 20, -9.8]},
]


def test_increments_are_constant_rate_times_period():
    s = stream(INITIAL, MANEUVER, 200.0, 1_700_000_000_000_000_000)
    assert s.period_ns == 5_000_000 and s.cycles == 100 + 200 + 50
    assert s.t0_ns == 1_700_000_000_000_000_000 and s.gravity_model == "j2"
    np.testing.assert_allclose(s.dalpha[150], np.radians([30, -20, 90]) * 0.005, rtol=1e-15)
    np.testing.assert_allclose(s.dv[-1], np.array([-3, 20, -9.8]) * 0.005, rtol=1e-15)


@pytest.mark.parametrize("model", ["j2", "spherical"])
def test_stream_meets_the_exactness_rule(model):
    """interface.md §3 one-step residuals with gravity of the stream's model at the published R."""
    s = stream(INITIAL, MANEUVER, 200.0, 0, gravity_model=model)
    assert s.gravity_model == model
    res = one_step_residuals(
        s.c_b_e0, s.v_e0, s.r_e0, s.dalpha, s.dv, gravitation(s.r_e0, model), s.period
    )
    assert res.within_spec(), (res.max_attitude, res.max_velocity, res.max_position)
    # With the other model's gravity the residuals are far out of spec: the check can fail.
    other = "spherical" if model == "j2" else "j2"
    bad = one_step_residuals(
        s.c_b_e0, s.v_e0, s.r_e0, s.dalpha, s.dv, gravitation(s.r_e0, other), s.period
    )
    assert not bad.within_spec()


def test_initial_state_is_the_scenario_initial():
    s = stream(dict(INITIAL, velocity_ned_mps=[10.0, -5.0, 1.0]), MANEUVER[:1], 100.0, 0)
    lat, lon = math.radians(45.0), math.radians(7.0)
    r_e, v_e, c_b_e = e0_state_to_ecef(0.0, s.r_e0[0], s.v_e0[0], s.c_b_e0[0])
    np.testing.assert_allclose(r_e, geodetic_to_ecef(lat, lon, 300.0), atol=1e-9)
    np.testing.assert_allclose(v_e, dcm_ned_to_ecef(lat, lon) @ [10.0, -5.0, 1.0], atol=1e-12)
    c_expected = dcm_ned_to_ecef(lat, lon) @ dcm_from_euler(*np.radians([10.0, -5.0, 30.0]))
    np.testing.assert_allclose(c_b_e, c_expected, atol=1e-15)


def test_stationary_body_on_the_rotating_earth_stays_put():
    """A body fixed to the Earth has constant ω_ib^B = C_E^B ω_ie and f^B = C_E^B (ω×(ω×R) - g).

    Fed these exact constant inputs for 60 s at 100 Hz, the truth stays at the start in ECEF.
    Bounds: the only modelling error is Savage's gravity linear in time over a cycle, which
    shortens the rotating g by ≈ g (ω_ie T)²/12 ≈ 4e-13 m/s² (< 1e-9 m in 60 s); the rest is
    float64 rounding of |R| ≈ 6.4e6 m (ε|R| ≈ 7e-10 m per step, ~√6000 · 7e-10 ≈ 5e-8 m as a
    random walk) and of |V| ≈ 330 m/s (ε|V| ≈ 4e-14 m/s per step, < 3e-10 m/s even if all add
    up). Vertical-channel divergence (time constant √(R/2g) ≈ 570 s) amplifies by < 1.2. A
    wrong Earth rate, E0 velocity or gravity term would miss these bounds by many orders (e.g.
    plumb-bob instead of mass gravitation: ½ · 0.03 m/s² · 60² ≈ 50 m).
    """
    lat, lon, alt = math.radians(45.0), math.radians(7.0), 300.0
    r_e = geodetic_to_ecef(lat, lon, alt)
    c_b_e = dcm_ned_to_ecef(lat, lon) @ dcm_from_euler(*np.radians([10.0, -5.0, 30.0]))
    w = OMEGA_IE_VEC
    omega_b = c_b_e.T @ w
    f_b = c_b_e.T @ (np.cross(w, np.cross(w, r_e)) - gravitation(r_e))
    segs = [
        {
            "duration_s": 60.0,
            "omega_dps": np.degrees(omega_b).tolist(),
            "specific_force_mps2": f_b.tolist(),
        }
    ]
    s = stream(INITIAL, segs, 100.0, 0)
    re, ve, cbe = e0_state_to_ecef(s.t, s.r_e0, s.v_e0, s.c_b_e0)
    assert np.linalg.norm(re - r_e, axis=-1).max() < 1e-6
    assert np.linalg.norm(ve, axis=-1).max() < 1e-8
    assert rotation_angle(np.swapaxes(cbe, -1, -2) @ c_b_e).max() < 1e-11
    # Sanity: in E0 the body really moved (≈ 330 m/s · 60 s along the parallel).
    assert np.linalg.norm(s.r_e0[-1] - s.r_e0[0]) > 1.9e4


@pytest.mark.parametrize(
    ("segments", "rate", "key"),
    [
        ([{"duration_s": 0.015}], 100.0, r"trajectory\.segments\[0\].duration_s"),
        ([{"duration_s": 1.0}, {"duration_s": 0}], 100.0, r"trajectory\.segments\[1\].duration_s"),
        ([{"duration_s": 1.0, "omega_dps": [1, 2]}], 100.0, r"trajectory\.segments\[0\].omega_dps"),
        (
            [{"duration_s": 1.0, "specific_force_mps2": [1, 2, "x"]}],
            100.0,
            r"trajectory\.segments\[0\].specific_force_mps2\[2\]",
        ),
        ([{"duration_s": 1.0, "accel_mps2": 1}], 100.0, r"trajectory\.segments\[0\].accel_mps2"),
        ([{"duration_s": 1.0}], 300.0, "rate_hz"),
        ([], 100.0, r"trajectory\.segments"),
    ],
)
def test_bad_values_name_the_key(segments, rate, key):
    with pytest.raises(ScenarioError) as info:
        stream(INITIAL, segments, rate, 0)
    assert re.fullmatch(key, info.value.key), str(info.value)


def test_whole_cycles_follow_the_generation_period():
    """A segment must be a whole number of T / oversample cycles (a cross-field rule)."""
    doc = {
        "rate_hz": 100,
        "initial": INITIAL,
        "trajectory": {"kind": "increments", "segments": [{"duration_s": 0.015}]},
    }
    with pytest.raises(ScenarioError) as info:
        parse_scenario(doc)
    assert info.value.key == "trajectory.segments[0].duration_s"
    assert "not a whole number of cycles of 0.01 s" in info.value.problem
    parse_scenario({**doc, "oversample": 2})  # 5 ms generation cycles: 3 of them
    assert whole_cycles(0.015, 5_000_000) == 3 and whole_cycles(0.015, 10_000_000) is None


def test_core_rejects_a_partial_cycle_with_its_location():
    segments = [IncrementSegment(duration=1.0), IncrementSegment(duration=0.0125)]
    with pytest.raises(TrajectoryError) as info:
        generate_increments_stream(0.7, 0.1, 0.0, [0, 0, 0], [0, 0, 0], segments, 10_000_000, 0)
    assert info.value.where == ("segments", 1, "duration")
