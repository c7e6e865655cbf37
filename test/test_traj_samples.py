"""Trajectory kind ``samples``: Giribet 2007 B-spline fits (Problems PV, ω, q1, q2).

Truth used throughout: a smooth curve near the Earth's surface (ECEF, 45°N 7°E, a 500 m x
800 m loop climbing at 2 m/s) and a smoothly varying attitude / body rate.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.core.earth import (
    dcm_e0_to_ecef,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
    ned_velocity_from_ecef,
)
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    quat_multiply,
    rotation_angle,
)
from strapdown_ros.core.trajectory import TrajectoryError, local_to_e0
from strapdown_ros.core.trajectory.giribet import (
    fit_spline,
    knot_vector,
    problem_pv,
)
from strapdown_ros.core.trajectory.samples import (
    FitOptions,
    SamplesTrajectory,
    SplineOptions,
    Weights,
    samples_from_arrays,
)
from strapdown_ros.inputs.samples import SamplesInputError, load_samples_csv
from strapdown_ros.plan import build_trajectory

T = 120.0
LAT0, LON0 = np.radians(45.0), np.radians(7.0)
R0 = geodetic_to_ecef(LAT0, LON0, 0.0)
C_N_E0 = dcm_ned_to_ecef(LAT0, LON0)


def truth_r(t):
    """ECEF position (m) of the truth curve."""
    w = 2 * np.pi / T
    ned = np.stack([500 * np.sin(w * t), 800 * (1 - np.cos(w * t)), -100 - 2.0 * t], -1)
    return R0 + ned @ C_N_E0.T


def truth_v(t):
    """ECEF velocity (m/s) of the truth curve."""
    w = 2 * np.pi / T
    ned = np.stack([500 * w * np.cos(w * t), 800 * w * np.sin(w * t), -2.0 + 0 * t], -1)
    return ned @ C_N_E0.T


def truth_rph(t):
    """Roll, pitch, heading (rad) of the truth attitude."""
    return 0.2 * np.sin(0.1 * t), 0.1 * np.cos(0.07 * t), 0.5 + 0.02 * t


def rate_fn(t):
    """Truth body rate ω_ib^B (rad/s) for the rate-integration tests."""
    t = np.asarray(t, dtype=float)
    return np.stack([0.5 * np.sin(0.2 * t), 0.3 + 0 * t, 0.1 * np.cos(0.3 * t)], -1)


def rms(e):
    e = np.asarray(e)
    return float(np.sqrt(np.mean(np.sum(e.reshape(e.shape[0], -1) ** 2, axis=1))))


def eq21_residual(traj, t):
    """max |q̇ − ½ q ⊗ [0, ω]| with q̇ from the spline derivative (eq. (22))."""
    q, qd, w = traj.q_b_e0(t), traj.q_dot_b_e0(t), traj.omega_ib_b(t)
    pure = np.concatenate([np.zeros((t.size, 1)), w], axis=1)
    return float(np.abs(qd - 0.5 * quat_multiply(q, pure)).max())


@pytest.fixture(scope="module")
def grid():
    return np.linspace(0.0, T, 2401)


# ------------------------------------------------------------------------------------------
# Knots (Theorem 1)
# ------------------------------------------------------------------------------------------


def test_knot_multiplicity_follows_continuity():
    """C^c at an interior breakpoint of a degree-p spline: multiplicity p − c (eq. (7))."""
    xi = knot_vector([0.0, 1.0, 2.0, 3.0], 3, [2, 0])
    assert xi.tolist() == [0.0] * 4 + [1.0] + [2.0] * 3 + [3.0] * 4
    with pytest.raises(ValueError, match="continuity"):
        knot_vector([0.0, 1.0, 2.0], 3, 3)


# ------------------------------------------------------------------------------------------
# Recovery of noisy samples
# ------------------------------------------------------------------------------------------


def test_position_fit_recovers_noisy_samples(grid):
    """Problem PV: σ = 2 m position noise at 2 Hz, knots 10 s → fit error well below noise."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, T + 1e-9, 0.5)
    sigma = 2.0
    noise = sigma * rng.standard_normal((t.size, 3))
    traj = SamplesTrajectory.from_arrays(
        t + 1000.0,
        r_ecef=truth_r(t) + noise,
        options=FitOptions(position=SplineOptions(knots=10.0)),
    )
    err = rms(traj.position_ecef(grid) - truth_r(grid))
    print(f"position fit RMS {err:.3f} m vs noise RMS {rms(noise):.3f} m")
    assert err < 0.5 * rms(noise)
    verr = rms(traj.position_ecef(grid, 1) - truth_v(grid))
    print(f"velocity (derivative) RMS {verr:.3f} m/s")
    assert verr < 0.5
    assert traj.duration == pytest.approx(T)
    assert traj.t0 == pytest.approx(1000.0)
    # velocity is the derivative of the position spline (consistent): finite difference check
    h = 1e-3
    tt = grid[1:-1]
    fd = (traj.position_ecef(tt + h) - traj.position_ecef(tt - h)) / (2 * h)
    assert np.abs(fd - traj.position_ecef(tt, 1)).max() < 1e-5


def test_velocity_samples_as_derivative_data(grid):
    """Problem PV with velocity data: noisy positions (σ 5 m) + velocities (σ 0.05 m/s)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, T + 1e-9, 1.0)
    r = truth_r(t) + 5.0 * rng.standard_normal((t.size, 3))
    v = truth_v(t) + 0.05 * rng.standard_normal((t.size, 3))
    opts = FitOptions(position=SplineOptions(knots=8.0))
    pos_only = SamplesTrajectory.from_arrays(t, r_ecef=r, options=opts)
    both = SamplesTrajectory.from_arrays(
        t,
        r_ecef=r,
        v_ecef=v,
        options=FitOptions(
            position=SplineOptions(knots=8.0),
            weights=Weights(position=1 / 25.0, velocity=1 / 0.05**2),
        ),
    )
    e_p = rms(pos_only.position_ecef(grid, 1) - truth_v(grid))
    e_pv = rms(both.position_ecef(grid, 1) - truth_v(grid))
    print(f"velocity RMS: positions only {e_p:.3f}, with velocity data {e_pv:.4f} m/s")
    assert e_pv < 0.05 and e_pv < 0.2 * e_p


def test_attitude_fit_recovers_noisy_samples(grid):
    """Attitude samples (σ 0.01 rad per angle) fitted with 5 s knots → error below noise."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, T + 1e-9, 0.5)
    sa = 0.01
    roll, pitch, heading = (a + sa * rng.standard_normal(t.size) for a in truth_rph(t))
    traj = SamplesTrajectory.from_arrays(
        t,
        r_ecef=truth_r(t),
        roll=roll,
        pitch=pitch,
        heading=heading,
        options=FitOptions(attitude=SplineOptions(knots=5.0)),
    )
    assert traj.attitude_source == "samples" and traj.attitude_method == "fit"
    lt = traj.local_truth(grid)
    ang = rotation_angle(np.swapaxes(dcm_from_euler(*truth_rph(grid)), -1, -2) @ lt.c_b_n)
    noise = rotation_angle(
        np.swapaxes(dcm_from_euler(*truth_rph(t)), -1, -2) @ dcm_from_euler(roll, pitch, heading)
    )
    print(f"attitude fit RMS {rms(ang[:, None]):.5f} rad vs noise {rms(noise[:, None]):.5f} rad")
    assert rms(ang[:, None]) < 0.5 * rms(noise[:, None])
    assert eq21_residual(traj, grid) < 1e-12


def test_rate_integration_recovers_noisy_rates():
    """Problems ω, q1, q2: noisy rates (σ 0.01 rad/s, 10 Hz), knots 2 s."""
    rng = np.random.default_rng(2)
    tend = 60.0
    t = np.arange(0.0, tend + 1e-9, 0.1)
    sol = solve_ivp(
        lambda s, q: 0.5 * quat_multiply(q, np.r_[0.0, rate_fn(s)]),
        (0, tend),
        [1.0, 0, 0, 0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
        dense_output=True,
    )
    c_b_e = dcm_e0_to_ecef(t) @ dcm_from_quat(sol.sol(t).T)
    sw = 0.01
    noise = sw * rng.standard_normal((t.size, 3))
    opts = FitOptions(attitude=SplineOptions(knots=2.0), attitude_method="integrate")
    traj = SamplesTrajectory.from_arrays(
        t, r_ecef=truth_r(t), c_b_e=c_b_e, omega_ib_b=rate_fn(t) + noise, options=opts
    )
    tt = np.linspace(0.0, tend, 3001)
    err = rms(traj.omega_ib_b(tt) - rate_fn(tt))
    print(
        f"rate fit RMS {err:.5f} rad/s vs noise {rms(noise):.5f}; eq21 "
        f"{eq21_residual(traj, tt):.2e}"
    )
    assert err < 0.5 * rms(noise)
    assert eq21_residual(traj, tt) < 1e-12
    # exact rates reproduce the attitude of the integrated truth
    exact = SamplesTrajectory.from_arrays(
        t,
        r_ecef=truth_r(t),
        c_b_e=c_b_e,
        omega_ib_b=rate_fn(t),
        options=FitOptions(attitude=SplineOptions(knots=1.0), attitude_method="integrate"),
    )
    ang = rotation_angle(
        np.swapaxes(dcm_from_quat(sol.sol(tt).T), -1, -2) @ dcm_from_quat(exact.q_b_e0(tt))
    )
    print(f"exact rates: attitude error max {ang.max():.2e} rad")
    assert ang.max() < 1e-4


# ------------------------------------------------------------------------------------------
# Consistency (eq. (21)) and derived attitude
# ------------------------------------------------------------------------------------------


def test_eq21_holds_and_qdot_is_the_derivative(grid):
    """(q, ω) satisfy eq. (21) to 1e-12; q̇ of eq. (22) matches finite differences of q."""
    t = np.arange(0.0, T + 1e-9, 1.0)
    traj = SamplesTrajectory.from_arrays(
        t,
        r_ecef=truth_r(t),
        omega_ib_b=rate_fn(t) + 0.0 * t[:, None],
        roll=truth_rph(t)[0],
        pitch=truth_rph(t)[1],
        heading=truth_rph(t)[2],
        options=FitOptions(attitude=SplineOptions(knots=6.0)),
    )
    res = eq21_residual(traj, grid)
    h = 1e-4
    tt = grid[1:-1]
    fd = (traj.q_b_e0(tt + h) - traj.q_b_e0(tt - h)) / (2 * h)
    fd_err = float(np.abs(fd - traj.q_dot_b_e0(tt)).max())
    print(f"eq21 residual {res:.2e}, |q̇ − FD| {fd_err:.2e}")
    assert res < 1e-12
    assert fd_err < 1e-8
    assert np.abs(np.linalg.norm(traj.q_b_e0(grid), axis=1) - 1).max() < 1e-14


def test_derived_attitude_follows_velocity(grid):
    """No attitude samples: heading along horizontal velocity, pitch along flight path, roll 0."""
    t = np.arange(0.0, T + 1e-9, 1.0)
    traj = SamplesTrajectory.from_arrays(t, r_ecef=truth_r(t))
    assert traj.attitude_source == "derived"
    lt = traj.local_truth(grid)
    fwd = lt.c_b_n[:, :, 0]  # body x axis in NED
    vdir = lt.v_ned / np.linalg.norm(lt.v_ned, axis=1, keepdims=True)
    ang = np.arccos(np.clip(np.sum(fwd * vdir, axis=1), -1, 1))
    right_down = lt.c_b_n[:, 2, 1]  # NED-down component of body y: 0 when roll is 0
    print(
        f"derived attitude: nose-velocity angle max {ang.max():.2e} rad, "
        f"|roll tilt| max {np.abs(right_down).max():.2e}"
    )
    assert ang.max() < 5e-3
    assert np.abs(right_down).max() < 5e-3


def test_local_truth_is_consistent_and_converts_to_e0(grid):
    """local_truth matches the ECEF splines; local_to_e0 accepts it; range is enforced."""
    t = np.arange(0.0, T + 1e-9, 1.0)
    traj = SamplesTrajectory.from_arrays(t, r_ecef=truth_r(t))
    lt = traj.local_truth(grid)
    r = traj.position_ecef(grid)
    assert np.abs(geodetic_to_ecef(lt.lat, lt.lon, lt.alt) - r).max() < 1e-6
    lat, lon, _ = ecef_to_geodetic(r)
    v = ned_velocity_from_ecef(lat, lon, traj.position_ecef(grid, 1))
    assert np.abs(lt.v_ned - v).max() < 1e-12
    e0 = local_to_e0(lt)
    assert e0.r_e0.shape == (grid.size, 3)
    with pytest.raises(ValueError, match="outside the trajectory span"):
        traj.local_truth(np.array([T + 1.0]))


# ------------------------------------------------------------------------------------------
# Continuity: corners
# ------------------------------------------------------------------------------------------


def _jump_of_derivative(f, tk, eps=1e-5):
    """|f'(tk+) − f'(tk−)| from one-sided differences of f."""
    right = (f(np.array([tk + 2 * eps])) - f(np.array([tk + eps]))) / eps
    left = (f(np.array([tk - eps])) - f(np.array([tk - 2 * eps]))) / eps
    return float(np.abs(right - left).max())


@pytest.mark.parametrize("continuity, corner", [(1, True), (2, False)])
def test_attitude_continuity_1_gives_a_rate_corner(continuity, corner):
    """Rate with a corner at 30 s: attitude C^1 there → ω has a corner; C^2 → ω' continuous."""
    tend, tk = 60.0, 30.0
    t = np.arange(0.0, tend + 1e-9, 0.1)
    w = np.zeros((t.size, 3))
    w[:, 0] = 0.1 * np.maximum(t - tk, 0.0)
    w[:, 2] = 0.2
    opts = FitOptions(attitude=SplineOptions(knots=5.0, breaks=[(tk, continuity)]))
    traj = SamplesTrajectory.from_arrays(t, r_ecef=truth_r(t), omega_ib_b=w, options=opts)
    assert traj.attitude_method == "integrate"
    jump_w = float(
        np.abs(
            traj.omega_ib_b(np.array([tk + 1e-9])) - traj.omega_ib_b(np.array([tk - 1e-9]))
        ).max()
    )
    jump_dw = _jump_of_derivative(traj.omega_ib_b, tk)
    print(f"attitude continuity {continuity}: |Δω| {jump_w:.1e}, |Δω'| {jump_dw:.2e} rad/s²")
    assert jump_w < 1e-7  # ω itself stays continuous
    if corner:
        assert jump_dw > 0.05  # true jump of ω' is 0.1 rad/s²
    else:
        assert jump_dw < 2e-3
    tt = np.linspace(0.0, tend, 1201)
    assert eq21_residual(traj, tt) < 1e-12


@pytest.mark.parametrize("continuity, corner", [(1, True), (2, False)])
def test_position_continuity_1_gives_an_acceleration_jump(continuity, corner):
    """Velocity corner at 40 s: position C^1 there → acceleration jumps; C^2 → it does not."""
    tk = 40.0
    t = np.arange(0.0, 80.0 + 1e-9, 0.5)
    ned = np.stack([10.0 * t, 0.05 * np.maximum(t - tk, 0.0) ** 2, 0 * t], -1)
    r = R0 + ned @ C_N_E0.T
    opts = FitOptions(position=SplineOptions(knots=5.0, breaks=[(tk, continuity)]))
    traj = SamplesTrajectory.from_arrays(t, r_ecef=r, options=opts)
    a = traj.position_ecef(np.array([tk - 1e-9, tk + 1e-9]), 2)
    jump = float(np.linalg.norm(a[1] - a[0]))
    vjump = float(
        np.linalg.norm(np.diff(traj.position_ecef(np.array([tk - 1e-9, tk + 1e-9]), 1), axis=0))
    )
    print(f"position continuity {continuity}: |Δa| {jump:.2e} m/s², |Δv| {vjump:.1e} m/s")
    assert vjump < 1e-6
    if corner:
        assert jump == pytest.approx(0.1, rel=1e-6)  # exact: the data lie in the spline space
    else:
        assert jump < 1e-6


def test_generic_fit_matches_scipy_make_lsq_spline():
    """fit_spline (eq. (14) by banded Cholesky) equals scipy's make_lsq_spline with weights."""
    from scipy.interpolate import make_lsq_spline

    rng = np.random.default_rng(5)
    x = np.sort(rng.uniform(0, 10, 200))
    x[0], x[-1] = 0.0, 10.0
    y = np.sin(x) + 0.1 * rng.standard_normal(x.size)
    w = rng.uniform(0.5, 2.0, x.size)
    bp = np.linspace(0, 10, 11)
    xi = knot_vector(bp, 3, [2, 2, 1, 2, 0, 2, 2, 2, 2])
    ref = make_lsq_spline(x, y, xi, k=3, w=np.sqrt(w))  # scipy minimizes Σ (w_i r_i)²
    from strapdown_ros.core.trajectory.giribet import DerivativeData

    ours = fit_spline(bp, 3, [2, 2, 1, 2, 0, 2, 2, 2, 2], [DerivativeData(0, x, y, w)])
    assert np.abs(ours.c[:, 0] - ref.c).max() < 1e-10
    # pure value data in the space are reproduced exactly, also via problem_pv offsets
    p = np.stack([x**3, 1e6 + x, -(x**2)], -1)
    spl = problem_pv(bp, 3, 2, x, p)
    assert np.abs(spl(x) - p).max() < 1e-8


# ------------------------------------------------------------------------------------------
# CSV and configuration
# ------------------------------------------------------------------------------------------


def _write_csv(path, t, header_extra=True):
    lat, lon, alt = ecef_to_geodetic(truth_r(t))
    v_ned = ned_velocity_from_ecef(lat, lon, truth_v(t))
    roll, pitch, heading = truth_rph(t)
    cols = [
        t,
        np.degrees(lat),
        np.degrees(lon),
        alt,
        v_ned[:, 0],
        v_ned[:, 1],
        v_ned[:, 2],
        np.degrees(roll),
        np.degrees(pitch),
        np.degrees(heading),
    ]
    names = "time_s,lat_deg,lon_deg,alt_m,vn_mps,ve_mps,vd_mps,roll_deg,pitch_deg,heading_deg"
    with open(path, "w") as fh:
        fh.write("# synthetic samples\n" + names + (",comment" if header_extra else "") + "\n")
        for row in np.stack(cols, -1):
            fh.write(",".join(f"{x:.12f}" for x in row) + (",x" if header_extra else "") + "\n")


def from_config(trajectory: dict, base: Path) -> SamplesTrajectory:
    """Build the ``trajectory`` section of a scenario file written in ``base``."""
    path = base / "scenario.yaml"
    path.write_text(yaml.safe_dump({"rate_hz": 100, "trajectory": trajectory}))
    return build_trajectory(load_scenario(path))


def key_of(trajectory: dict, base: Path) -> str:
    """The message of the error the scenario's trajectory section gives."""
    with pytest.raises(ScenarioError) as info:
        from_config(trajectory, base)
    return str(info.value)


def test_csv_round_trip_and_config(tmp_path, grid):
    t = np.arange(0.0, T + 1e-9, 1.0)
    _write_csv(tmp_path / "s.csv", t)
    samples = load_samples_csv(tmp_path / "s.csv")
    assert np.abs(samples.r_ecef - truth_r(t)).max() < 1e-3
    assert np.abs(samples.v_ecef - truth_v(t)).max() < 1e-9
    cfg = {
        "kind": "samples",
        "file": "s.csv",
        "knots": {"position": 6.0, "attitude": 6.0},
        "degree": 3,
        "continuity": 2,
        "breaks": [{"t_s": 60.0, "continuity": 1}],
        "weights": {"position": 1.0, "velocity": 100.0, "attitude": 1e4},
    }
    traj = from_config(cfg, tmp_path)
    assert traj.options.position.knots == 6.0 and traj.options.weights.attitude == 1e4
    assert traj.options.attitude.breaks == ((60.0, 1),) and traj.options.position.degree == 3
    assert 60.0 in traj.position_breakpoints and 60.0 in traj.attitude_breakpoints
    lt = traj.local_truth(grid)
    perr = rms(geodetic_to_ecef(lt.lat, lt.lon, lt.alt) - truth_r(grid))
    aerr = rotation_angle(np.swapaxes(dcm_from_euler(*truth_rph(grid)), -1, -2) @ lt.c_b_n)
    print(
        f"CSV round trip: position RMS {perr:.2e} m, attitude max {aerr.max():.2e} rad, "
        f"residuals {traj.residuals()}"
    )
    assert perr < 0.05 and aerr.max() < 1e-3


# ------------------------------------------------------------------------------------------
# Bad inputs
# ------------------------------------------------------------------------------------------


def test_bad_inputs_name_the_key(tmp_path):
    t = np.arange(0.0, 20.0 + 1e-9, 1.0)
    r = truth_r(t)
    with pytest.raises(ValueError, match="t: times must be strictly increasing"):
        samples_from_arrays(t[::-1], r_ecef=r)
    bad = r.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="r_ecef: NaN .* sample 3"):
        samples_from_arrays(t, r_ecef=bad)
    with pytest.raises(ValueError, match="position: missing alt"):
        samples_from_arrays(t, lat=t * 0, lon=t * 0)
    with pytest.raises(ValueError, match="attitude: missing heading"):
        samples_from_arrays(t, r_ecef=r, roll=t * 0, pitch=t * 0)
    with pytest.raises(ValueError, match="v_body: needs attitude"):
        samples_from_arrays(t, r_ecef=r, v_body=r * 0)
    with pytest.raises(ValueError, match="3 samples are too few"):
        SamplesTrajectory.from_arrays(t[:3], r_ecef=r[:3])
    with pytest.raises(ValueError, match="position.knots: .*outside the data span"):
        SamplesTrajectory.from_arrays(
            t, r_ecef=r, options=FitOptions(position=SplineOptions(knots=[0, 5, 25.0]))
        )
    with pytest.raises(ValueError, match=r"position.knots: interval .* holds"):
        SamplesTrajectory.from_arrays(
            t, r_ecef=r, options=FitOptions(position=SplineOptions(knots=1.0))
        )
    with pytest.raises(ValueError, match="position.continuity: must be >= 1"):
        SamplesTrajectory.from_arrays(
            t, r_ecef=r, options=FitOptions(position=SplineOptions(knots=5.0, continuity=0))
        )
    with pytest.raises(TrajectoryError, match=r"attitude.breaks\[0\]: t_s=30.0 outside") as info:
        SamplesTrajectory.from_arrays(
            t, r_ecef=r, options=FitOptions(attitude=SplineOptions(breaks=[(30.0, 1)]))
        )
    assert info.value.where == ("attitude", "breaks", 0)
    # CSV: missing column, NaN cell, non-increasing time
    path = tmp_path / "bad.csv"
    path.write_text("t,lat_deg,lon_deg\n0,45,7\n1,45,7\n")
    with pytest.raises(SamplesInputError, match="missing column.*alt_m"):
        load_samples_csv(path)
    path.write_text("t,x_m,y_m,z_m\n0,1,2,3\n1,1,nan,3\n")
    with pytest.raises(SamplesInputError, match="column 'y_m', data row 2"):
        load_samples_csv(path)
    path.write_text("time_s,x_m,y_m,z_m\n0,1,2,3\n0,1,2,3\n")
    with pytest.raises(
        SamplesInputError, match="column time_s: times must be strictly increasing"
    ) as err:
        load_samples_csv(path)
    assert err.value.key == "file"
    path.write_text("t,x_m,y_m,z_m,roll_deg\n0,1,2,3,0\n1,1,2,3,0\n")
    with pytest.raises(SamplesInputError, match="pitch_deg, heading_deg"):
        load_samples_csv(path)


@pytest.mark.parametrize(
    ("trajectory", "message"),
    [
        ({"knotz": 2}, r"trajectory.knotz: unknown key \(did you mean 'knots'\?\)"),
        ({"file": None}, "trajectory.file: is required"),
        ({"file": "nope.csv"}, "trajectory.file: '.*nope.csv' does not exist"),
        ({"weights": {"speed": 1}}, "trajectory.weights.speed: unknown key"),
        ({"weights": {"rate": -1}}, "trajectory.weights.rate: must be >= 0"),
        ({"degree": 2.5}, "trajectory.degree: must be an integer, got float 2.5"),
        ({"degree": {"attitude": 0}}, "trajectory.degree.attitude: must be >= 1"),
        ({"degree": 1}, "trajectory.degree: must be >= 2 for the position spline"),
        ({"knots": 0}, "trajectory.knots: must be > 0"),
        ({"knots": {"position": [0, "a"]}}, r"trajectory.knots.position\[1\]: must be a number"),
        ({"continuity": 3}, r"trajectory.continuity: .* position spline must be in \[1, "),
        ({"continuity": {"attitude": -1}}, "trajectory.continuity.attitude: .* in \\[0, "),
        ({"breaks": [{"t_s": 5}]}, r"trajectory.breaks\[0\].continuity: is required"),
        ({"breaks": {"attitude": [{"t_s": 5, "continuity": 1, "c": 1}]}},
         r"trajectory.breaks.attitude\[0\].c: unknown key"),
        ({"columns": {"lat": "latitude"}}, "trajectory.columns.lat: unknown canonical column"),
        ({"columns": {"lat_deg": 3}}, "trajectory.columns.lat_deg: must be a string"),
        ({"attitude_method": "guess"}, "trajectory.attitude_method: must be one of"),
        ({"rate_frame": "body"}, "trajectory.rate_frame: must be one of"),
        ({"q_step": -1}, "trajectory.q_step: must be > 0"),
        ({"bag": "b"}, "trajectory.bag: give either file or bag, not both"),
        ({"topic": "/odom"}, "trajectory.topic: is only used with bag"),
        # found while fitting: the key of the option, the spline named
        ({"knots": [0, 5, 50]}, "trajectory.knots: position spline: breakpoints .*outside"),
        ({"knots": {"position": 5.0, "attitude": 0.5}},
         r"trajectory.knots.attitude: interval .* holds"),
        ({"breaks": {"attitude": [{"t_s": 30.0, "continuity": 1}]}},
         r"trajectory.breaks.attitude\[0\]: t_s=30.0 outside the data span"),
    ],
)  # fmt: skip
def test_bad_trajectory_section_names_the_key(tmp_path, trajectory, message):
    t = np.arange(0.0, 20.0 + 1e-9, 1.0)
    _write_csv(tmp_path / "ok.csv", t, header_extra=False)
    doc = {"kind": "samples", "file": "ok.csv", **trajectory}
    if doc["file"] is None:
        del doc["file"]
    assert re.match(message, key_of(doc, tmp_path)), key_of(doc, tmp_path)


def test_samples_model_defaults(tmp_path):
    t = np.arange(0.0, 20.0 + 1e-9, 1.0)
    _write_csv(tmp_path / "ok.csv", t, header_extra=False)
    traj = from_config({"kind": "samples", "file": "ok.csv"}, tmp_path)
    assert traj.options == FitOptions()  # the model's defaults are the core's
