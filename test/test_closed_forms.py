"""Closed forms of a stationary free-inertial navigator, one error source at a time, against the
navigator's errors read back from bags (static.yaml: level, north-facing, 48.137° N).

The closed forms (strapdown_ros.analysis.closed_forms, docs/error_analysis.md): the psi-angle
turning about the Earth's axis (24-hour terms), the Schuler oscillator with Foucault coupling
(84.4-min period) driven by g ψ and the accelerometer bias, φ = ψ + δθ. The navigator is the
paper mode with vertical damping on the truth altitude (the closed forms have no vertical
channel). Agreement is ``max_t |closed - actual| / max_t |actual|`` on the horizontal position,
velocity and Young-angle vectors; the target is 1 %.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from strapdown_ros.analysis import closed_forms as cf
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset

SITE = cf.StaticSite(np.radians(48.137), 520.0)
DPH = np.radians(1.0) / 3600.0
MG = 9.80665e-3
TOPICS = ("/navigator/error/position", "/navigator/error/velocity", "/navigator/error/attitude")


def static_run(tmp_path, duration_s, rate_hz, n, errors):
    """Generate static.yaml with the IMU errors ``errors`` (an imu_errors mapping in YAML flow
    style) on the reference IMU; return the scenario and (t, position, velocity, θ) from disk."""
    overrides = [
        f"rate_hz={rate_hz}",
        f"trajectory.segments.0.duration_s={duration_s}",
        f"imu_errors={{input_topic: /reference/imu, {errors}}}",
        "navigator.imu_topic=/variation/imu_measured",
        "navigator.truth_topic=/reference/odom",
        "navigator.mode=paper",
        "navigator.vertical_damping=true",
        f"navigator.n={n}",
        "navigator.p=1",
    ]
    scenario = load_scenario("config/scenarios/static.yaml", overrides, duration_s=duration_s)
    generate_dataset(scenario, tmp_path / "bag")
    bag = read_bag(tmp_path / "bag", TOPICS)
    p, v, a = (bag[k] for k in TOPICS)
    t = (p.stamps_ns - p.stamps_ns[0]) * 1e-9
    return scenario, (t, p.vector[:, :2], v.vector[:, :2], a.vector)


def closed(scenario, t):
    params = scenario.imu_errors[0].parameters()
    return cf.static_errors(t, SITE, accel_ned=params.accel.bias, gyro_ned=params.gyro.bias)


def rel(pred, act):
    return np.linalg.norm(pred - act, axis=1).max() / np.linalg.norm(act, axis=1).max()


def agreement(scenario, data, baseline=None):
    t, pos, vel, theta = data
    if baseline is not None:
        pos, vel, theta = pos - baseline[1], vel - baseline[2], theta - baseline[3]
    c = closed(scenario, t)
    return (
        rel(c.position_ned[:, :2], pos),
        rel(c.velocity_ned[:, :2], vel),
        rel(c.theta_young, theta),
    )


# -- the closed forms themselves --------------------------------------------------------------


def test_horizontal_frequencies():
    """The roots of (s² + ω_N²)(s² + ω_E²) + 4Ω_z² s² are the 4×4 system's eigenvalues; with
    ω_N = ω_E they are √(ω_s² + Ω_z²) ± Ω_z (Schuler 84.4 min, Foucault)."""
    w1, w2 = cf.horizontal_frequencies(SITE)
    wn2, we2, wz = SITE.g / SITE.r_n, SITE.g / SITE.r_e, SITE.omega_z
    a = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-wn2, 0, 0, -2 * wz], [0, -we2, 2 * wz, 0]])
    got = np.sort(np.abs(np.linalg.eigvals(a).imag))
    np.testing.assert_allclose(got, [w2, w2, w1, w1], rtol=1e-12)
    ws = np.sqrt(SITE.g / np.sqrt(SITE.r_n * SITE.r_e))
    assert abs(2 * np.pi / ws / 60 - 84.4) < 0.3  # the Schuler period, min
    wf = np.sqrt(ws**2 + wz**2)
    np.testing.assert_allclose([w1, w2], [wf + wz, wf - wz], rtol=2e-3)  # R_N ≠ R_E: 0.1 %


def linear_model(t, accel, gyro):
    """The psi-angle equations integrated numerically: ψ̇ = -Ω × ψ - ε, horizontal δr̈ with
    per-channel ω², Coriolis 2Ω_z and forcing (g ψ_E, -g ψ_N) + ∇."""
    om, wz, g = SITE.earth_rate_ned, SITE.omega_z, SITE.g

    def rhs(_, y):
        psi, r, v = y[:3], y[3:5], y[5:7]
        dv = [-SITE.g / SITE.r_n * r[0] - 2 * wz * v[1] + g * psi[1] + accel[0],
              -SITE.g / SITE.r_e * r[1] + 2 * wz * v[0] - g * psi[0] + accel[1]]  # fmt: skip
        return np.concatenate([-np.cross(om, psi) - gyro, v, dv])

    sol = solve_ivp(rhs, (0, t[-1]), np.zeros(7), "DOP853", t_eval=t, rtol=1e-12, atol=1e-15)
    return sol.y.T


SLOW = pytest.mark.slow


@pytest.mark.parametrize(
    "accel, gyro",
    [pytest.param((MG, 0, 0), (0, 0, 0), marks=SLOW),  # ~4.5 s each; the third has both
     pytest.param((0, 0, 0), (0, 0, 0.1 * DPH), marks=SLOW),
     ((0, -MG, 0), (0.03 * DPH, -0.05 * DPH, 0.02 * DPH))],
)  # fmt: skip
def test_closed_form_solves_the_linear_equations(accel, gyro):
    """Over 30 h, to 1e-10 of the largest value (measured 1.4e-11, the integrator's)."""
    t = np.linspace(0, 30 * 3600.0, 2001)
    num = linear_model(t, np.array(accel), np.array(gyro))
    c = cf.static_errors(t, SITE, accel_ned=accel, gyro_ned=gyro)
    for got, ref in ((c.psi_ned, num[:, :3]), (c.position_ned[:, :2], num[:, 3:5]),
                     (c.velocity_ned[:, :2], num[:, 5:7])):  # fmt: skip
        err = np.linalg.norm(got - ref, axis=1).max()
        assert err <= 1e-10 * np.linalg.norm(ref, axis=1).max()


def test_textbook_limits():
    """Short spans: the single-channel Schuler forms of Titterton & Weston §12.3 / Groves §14.2
    (δr_N = b/ω²(1 - cos ωt), θ2 = -b/g (1 - cos ωt); east gyro δr_N = -Rε(t - sin ωt/ω),
    θ2 = -ε sin(ωt)/ω) within 1 % of their maxima over the first 20 minutes (Foucault and
    24-hour terms are that small then)."""
    t = np.linspace(0, 1200.0, 601)
    wn = np.sqrt(SITE.g / SITE.r_n)
    c = cf.static_errors(t, SITE, accel_ned=(MG, 0, 0))
    expect = MG / wn**2 * (1 - np.cos(wn * t))
    assert np.max(np.abs(c.position_ned[:, 0] - expect)) < 0.01 * expect.max()
    tilt = -MG / SITE.g * (1 - np.cos(wn * t))
    assert np.max(np.abs(c.theta_young[:, 1] - tilt)) < 0.01 * np.abs(tilt).max()
    eps = 0.1 * DPH
    c = cf.static_errors(t, SITE, gyro_ned=(0, eps, 0))
    expect = -SITE.r_n * eps * (t - np.sin(wn * t) / wn)
    assert np.max(np.abs(c.position_ned[:, 0] - expect)) < 0.01 * np.abs(expect).max()
    tilt = -eps * np.sin(wn * t) / wn
    assert np.max(np.abs(c.theta_young[:, 1] - tilt)) < 0.01 * np.abs(tilt).max()


# -- against the navigator --------------------------------------------------------------------


def test_accelerometer_bias_schuler_30_min(tmp_path):
    """North accelerometer bias 1 mg, 30 min at 5 Hz: measured position 3e-5, velocity 9e-5,
    attitude 4e-4 of the maxima."""
    scenario, data = static_run(tmp_path, 1800, 5, 1, "accel_bias_mg: [1, 0, 0]")
    for r in agreement(scenario, data):
        assert r < 0.01
    t, pos, _, theta = data
    wn = np.sqrt(SITE.g / SITE.r_n)
    textbook = MG / wn**2 * (1 - np.cos(wn * t))  # δr_N, single channel
    assert np.max(np.abs(pos[:, 0] - textbook)) < 0.01 * textbook.max()
    assert np.max(np.abs(theta[:, 1] + MG / SITE.g * (1 - np.cos(wn * t)))) < 0.01 * 2 * MG / SITE.g


ONE_HOUR = [
    ("accel_bias_mg: [1, 0, 0]", (1e-4, 1e-3, 2e-3)),
    ("accel_bias_mg: [0, 1, 0]", (1e-4, 5e-3, 5e-3)),
    ("gyro_bias_dph: [0.1, 0, 0]", (1e-4, 5e-3, 3e-3)),
    ("gyro_bias_dph: [0, 0.1, 0]", (1e-3, 2e-3, 5e-3)),
    ("gyro_bias_dph: [0, 0, 0.1]", (2e-3, 3e-3, 2e-4)),
]


@pytest.mark.slow
@pytest.mark.parametrize("errors, tol", ONE_HOUR)
def test_one_source_one_hour(tmp_path, errors, tol):
    """One hour at 10 Hz (T_nav = 0.1 s). Measured (position, velocity, attitude), of the
    maxima: north accel 3.4e-5, 1.9e-4, 3.8e-4; east accel 3.3e-5, 1.4e-3, 1.5e-3; north gyro
    1.5e-5, 1.7e-3, 5.6e-4; east gyro 1.1e-4, 4.0e-4, 2.1e-3; down gyro 3.7e-4, 5.9e-4, 3.7e-5.
    Tolerances about 3x those, all under the 1 % target."""
    scenario, data = static_run(tmp_path, 3600, 10, 1, errors)
    got = agreement(scenario, data)
    assert all(r < min(t, 0.01) for r, t in zip(got, tol, strict=True)), got


@pytest.fixture(scope="module")
def day_baseline(tmp_path_factory):
    """24 h with ideal data: the paper mode's own error (248 m, 0.15 m/s, 5.8e-5 rad at 5 Hz,
    T_nav = 1 s), subtracted from the runs below (first-order superposition)."""
    return static_run(tmp_path_factory.mktemp("day"), 86400, 5, 5, "gyro_bias_dph: 0.0")[1]


@pytest.mark.slow
@pytest.mark.parametrize(
    "errors", ["gyro_bias_dph: [0.01, 0, 0]", "gyro_bias_dph: [0, 0, 0.01]",
               "accel_bias_mg: [0.1, 0, 0]"],
)  # fmt: skip
def test_earth_rate_terms_over_a_day(tmp_path, day_baseline, errors):
    """24 h: the 24-hour terms of ψ (north gyro: the unbounded longitude error and the 24-h
    latitude error; down gyro: azimuth drift coupling through Ω cos L), Foucault turning the
    Schuler plane by 2π sin L. Measured (position, velocity, attitude) with the ideal run
    subtracted: north gyro 1.4e-3, 1.6e-3, 2.6e-3; down gyro 1.3e-3, 2.1e-3, 3.1e-3; north accel
    1.2e-3, 2.5e-3, 1.2e-3 (at 0.1°/h second-order terms reach 1-3 %)."""
    scenario, data = static_run(tmp_path, 86400, 5, 5, errors)
    got = agreement(scenario, data, day_baseline)
    assert all(r < 0.01 for r in got), got
    assert not all(r < 0.01 for r in agreement(scenario, data))  # the baseline matters
