"""Waldmann §6 coning trajectory: body rate w.r.t. the local level, CM at rest / sinusoids."""

import math

import numpy as np
import pytest
from truth_checks import velocity_and_position_derivative

from strapdown_ros.config import ScenarioError, parse_scenario
from strapdown_ros.core.earth import dcm_ned_to_ecef, geodetic_to_ecef
from strapdown_ros.core.exact_update import one_step_residuals
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.method2 import method2
from strapdown_ros.core.rotations import rotvec_from_dcm
from strapdown_ros.core.trajectory.base import local_to_e0
from strapdown_ros.core.trajectory.coning import ConingTrajectory, lowest_altitude
from strapdown_ros.plan import build_trajectory

INITIAL = {
    "latitude_deg": -23.2,
    "longitude_deg": -45.9,
    "altitude_m": 600.0,
    "velocity_ned_mps": [0.0, 0.0, 0.0],
    "attitude_rph_deg": [0.0, 0.0, 0.0],
}


def build(initial, coning) -> ConingTrajectory:
    """The trajectory of a scenario's ``initial`` and ``trajectory.coning`` (typed model)."""
    scenario = parse_scenario(
        {"rate_hz": 100, "initial": initial, "trajectory": {"kind": "coning", "coning": coning}}
    )
    return build_trajectory(scenario)


def fd_body_rate(traj, t, d=1e-4):
    """ω_b^bl from the attitude: rotvec(C(t-d)ᵀ C(t+d)) / 2d (error O(d² |ω|³))."""
    c_minus = traj.attitude(t - d)
    c_plus = traj.attitude(t + d)
    return rotvec_from_dcm(np.swapaxes(c_minus, -1, -2) @ c_plus) / (2 * d)


def test_paper_defaults():
    traj = build(INITIAL, {})
    assert traj.theta == math.pi / 2 and traj.precession_rate == math.pi / 6
    assert traj.duration == 300.0 and traj.cm_motion == "rest"


@pytest.mark.parametrize(
    ("params", "rph"),
    [
        ({}, [0.0, 0.0, 0.0]),  # Table 3: θ = π/2, Ω_p = π/6
        ({"theta_deg": 30.0, "precession_rate_radps": 2.0}, [0.0, 0.0, 0.0]),
        ({"theta_rad": 1.0, "precession_rate_dps": -45.0}, [10.0, -20.0, 135.0]),
    ],
)
def test_body_rate_is_the_papers(params, rph):
    """Numerical derivative of the attitude equals §6's ω_b^bl for any initial attitude."""
    traj = build(dict(INITIAL, attitude_rph_deg=rph), params)
    t = np.linspace(0.001, traj.duration - 0.001, 997)
    measured = fd_body_rate(traj, t)
    w, th = traj.precession_rate, traj.theta
    a = w * t
    paper = np.stack(
        [
            -w * math.sin(th) * np.cos(a),
            -w * math.sin(th) * np.sin(a),
            np.full_like(t, w * (math.cos(th) - 1)),
        ],
        axis=-1,
    )
    np.testing.assert_allclose(measured, paper, rtol=0, atol=1e-8 * abs(w))
    np.testing.assert_allclose(traj.omega_bl_b(t), paper, rtol=0, atol=1e-15)
    # |ω| = 2 Ω_p sin(θ/2): √2 π/6 ≈ 0.7405 rad/s for Table 3.
    np.testing.assert_allclose(
        np.linalg.norm(measured, axis=-1), 2 * abs(w) * math.sin(th / 2), rtol=1e-8
    )


def test_body_z_axis_precesses_about_the_vertical():
    traj = build(INITIAL, {"theta_deg": 20.0})
    t = np.linspace(0.0, 12.0, 49)  # one precession period 2π/Ω_p = 12 s
    z_b = traj.attitude(t)[:, :, 2]  # body z axis in NED
    np.testing.assert_allclose(z_b[:, 2], math.cos(math.radians(20.0)), atol=1e-15)
    azimuth = np.unwrap(np.arctan2(z_b[:, 1], z_b[:, 0]))
    np.testing.assert_allclose(azimuth, math.pi / 6 * t, atol=1e-12)


def test_cm_at_rest():
    traj = build(INITIAL, {"cm_motion": "rest"})
    lt = traj.local_truth(np.linspace(0.0, 300.0, 3001))
    assert np.all(lt.lat == math.radians(-23.2)) and np.all(lt.lon == math.radians(-45.9))
    assert np.all(lt.alt == 600.0) and np.all(lt.v_ned == 0.0)


def test_sinusoid_profile_matches_section_6():
    traj = build(INITIAL, {"cm_motion": "sinusoids"})
    t = np.linspace(0.0, 300.0, 1201)
    lt = traj.local_truth(t)
    np.testing.assert_allclose(lt.v_ned[:, 0], 200 * np.sin(2 * np.pi * t / 1200), atol=1e-12)
    np.testing.assert_allclose(lt.v_ned[:, 1], 150 * np.sin(2 * np.pi * t / 1200), atol=1e-12)
    np.testing.assert_allclose(lt.v_ned[:, 2], 5 * np.sin(2 * np.pi * t / 300), atol=1e-13)
    # h = h0 - ∫ V_D: a full period of V_D in 300 s brings the CM back to its altitude.
    np.testing.assert_allclose(
        lt.alt, 600.0 - 5 * 300 / (2 * np.pi) * (1 - np.cos(2 * np.pi * t / 300)), atol=1e-9
    )
    assert lt.alt[-1] == pytest.approx(600.0, abs=1e-9)
    # Ground track: ∫ V_N over 300 s = 200·1200/(2π) ≈ 38.2 km north.
    r = geodetic_to_ecef(lt.lat, lt.lon, lt.alt)
    c_e_n = np.swapaxes(dcm_ned_to_ecef(lt.lat[0], lt.lon[0]), -1, -2)
    north, east = (c_e_n @ (r[-1] - r[0]))[:2]
    assert north == pytest.approx(200 * 1200 / (2 * np.pi), rel=2e-3)  # curvature: ~1e-3
    assert east == pytest.approx(150 * 1200 / (2 * np.pi), rel=2e-3)


def test_sinusoid_velocity_is_derivative_of_position():
    traj = build(INITIAL, {"cm_motion": "sinusoids"})
    t = np.linspace(1.0, 299.0, 1500)
    h = 0.01

    v_e, fd = velocity_and_position_derivative(traj, t, h)
    assert np.abs(fd - v_e).max() < 1e-6


def test_regenerated_stream_is_exact():
    """The CM truth feeds Method 2 (zero offsets) into a stream that meets docs/interface.md §3."""
    traj = build(INITIAL, {"cm_motion": "sinusoids", "duration_s": 4.0})
    period = 0.01
    truth = local_to_e0(traj.local_truth(np.arange(401) * period))
    sol = method2(truth.c_b_e0, truth.r_e0, truth.v_e0, period, lambda r: gravitation(r, "j2"))
    res = one_step_residuals(
        sol.c_b_e0, sol.v_e0, sol.r_e0, sol.dalpha, sol.dv, gravitation(sol.r_e0, "j2"), period
    )
    assert res.within_spec(), (res.max_attitude, res.max_velocity, res.max_position)
    # Gyro increments ≈ (ω_bl + ω_in in body) T: dominated by the §6 coning rate.
    np.testing.assert_allclose(
        np.linalg.norm(sol.dalpha, axis=-1) / period, math.sqrt(2) * math.pi / 6, rtol=1e-3
    )


@pytest.mark.parametrize(
    ("params", "key"),
    [
        ({"theta_deg": 30, "theta_rad": 0.5}, "theta_deg"),
        ({"theta_rad": 4.0}, "theta_rad"),
        ({"precession_rate_radps": "fast"}, "precession_rate_radps"),
        ({"cm_motion": "orbit"}, "cm_motion"),
        ({"velocity_period_ned_s": [1200, 0, 300]}, "velocity_period_ned_s"),
        ({"velocity_amplitude_ned_mps": [1, 2]}, "velocity_amplitude_ned_mps"),
        ({"duration_s": 0}, "duration_s"),
        ({"spin": 1}, "spin"),
        (
            {"cm_motion": "sinusoids", "velocity_amplitude_ned_mps": [0, 0, 200]},
            "velocity_amplitude_ned_mps",
        ),
    ],
)
def test_bad_values_name_the_key(params, key):
    with pytest.raises(ScenarioError) as info:
        build(INITIAL, params)
    assert info.value.key.startswith(f"trajectory.coning.{key}"), str(info.value)


def test_moving_initial_velocity_is_rejected():
    with pytest.raises(ScenarioError) as info:
        build(dict(INITIAL, velocity_ned_mps=[1, 0, 0]), {})
    assert info.value.key == "initial.velocity_ned_mps"


def test_latitude_limit_of_the_coning_kind():
    """The CM path integrates the geodetic rates: |latitude| <= 89.9° for this kind."""
    with pytest.raises(ScenarioError) as info:
        build(dict(INITIAL, latitude_deg=-89.95), {})
    assert info.value.key == "initial.latitude_deg" and "89.9" in info.value.problem
    assert build(dict(INITIAL, latitude_deg=-89.85), {}).lat0 == math.radians(-89.85)


def test_lowest_altitude():
    """h0 - A_D P_D/(2π) (1 - cos(2π t/P_D)): lowest at P_D/2, or at the end if shorter."""
    assert lowest_altitude(600.0, 5.0, 300.0, 300.0) == pytest.approx(600 - 5 * 300 / math.pi)
    assert lowest_altitude(600.0, 5.0, 300.0, 75.0) == pytest.approx(600 - 5 * 300 / (2 * math.pi))
    assert lowest_altitude(600.0, -5.0, 300.0, 300.0) == 600.0


def test_defaults_of_the_model():
    spec = parse_scenario(
        {"rate_hz": 100, "initial": INITIAL, "trajectory": {"kind": "coning"}}
    ).trajectory
    assert spec.coning.theta == math.pi / 2 and spec.coning.precession_rate == math.pi / 6
    assert spec.coning.cm_motion == "rest" and spec.natural_duration == 300.0
    assert spec.coning.velocity_amplitude_ned_mps == (200.0, 150.0, 5.0)
    assert spec.coning.velocity_period_ned_s == (1200.0, 1200.0, 300.0)
