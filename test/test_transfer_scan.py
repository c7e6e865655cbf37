"""Transfer alignment on a scanning platform (docs/transfer_alignment.md §5): the measurement
models with a scan and a displacement against the exact ones, the resolver bias as a mounting
error, the resolver noise's R, the scenario rules and, on bags read back from disk, the
no-model-error case of `config/scenarios/transfer_alignment_scan.yaml` (default.yaml's
platform: a ±30 deg sweep about z, 0.15 m displacement, 90 deg yaw mounting)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.core.rotations import dcm_from_euler, dcm_from_rotvec
from strapdown_ros.core.transfer import measurements as tm

REPO = Path(__file__).resolve().parent.parent
SCAN_SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment_scan.yaml"
T = 0.005
#: A generic platform (the displacement not along the scan axis, so that the scan moves it).
AXIS = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
DISP = np.array([0.12, -0.08, 0.15])
LEVER = np.array([-6.0, 1.5, -0.3])
MOUNT = dcm_from_euler(0.02, -0.01, 1.5)


def _rng() -> np.random.Generator:
    return np.random.default_rng(11)


def _carried(c: np.ndarray, mount: np.ndarray, theta: float, lever: np.ndarray) -> np.ndarray:
    """``S = C_r (l + M C_scan(θ) d)`` (Savage 2020 eq. (7)), the exact model."""
    return c @ (lever + mount @ tm.scan_dcm(AXIS, theta) @ DISP)


def _masters(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    c_prev = dcm_from_euler(*rng.normal(0, 0.5, 3))
    return c_prev, dcm_from_rotvec(rng.normal(0, 0.01, 3)) @ c_prev


# -- the measurement models with a platform ------------------------------------------------------


def test_velocity_matching_on_a_platform_is_minus_h_times_the_error():
    """The exact eq. (10) velocity of the slave against ``h = V̂ − D l̂ − e``: ν + H δx is second
    order in μ (the displacement Jacobian H_μ), exact in δV and δl."""
    rng = _rng()
    n, i_v, i_mu, i_l = 21, 3, 15, 18
    for _ in range(5):
        c_prev, c_next = _masters(rng)
        th_prev, th_next = rng.uniform(-0.5, 0.5, 2)
        v_r = rng.normal(size=3) * 100
        # the truth: V_s = V_r + (S_m+1 − S_m−1)/2T
        v_s = v_r + (_carried(c_next, MOUNT, th_next, LEVER)
                     - _carried(c_prev, MOUNT, th_prev, LEVER)) / (2 * T)  # fmt: skip
        dv, dl = rng.normal(size=3) * 1e-3, rng.normal(size=3) * 1e-2
        mu = rng.normal(size=3) * 1e-5
        m_hat = dcm_from_rotvec(mu) @ MOUNT
        w = [tm.platform_offset(m_hat, tm.scan_dcm(AXIS, th), DISP) for th in (th_prev, th_next)]
        e, h_mu = tm.displacement_transport(c_prev, c_next, w[0], w[1], T)
        d = tm.transport_matrix("central_difference", c_prev, None, c_next, None, T)
        nu, h = tm.velocity_matching(v_s + dv, v_r, d, LEVER + dl, n, i_v, i_l, (e, h_mu, i_mu))
        dx = np.zeros(n)
        dx[i_v : i_v + 3], dx[i_mu : i_mu + 3], dx[i_l : i_l + 3] = dv, mu, dl
        first = np.abs(h_mu @ mu).max()
        assert first > 1e-7  # the μ term (measured 4.5e-7 to 3.6e-5 m/s) is not trivial
        # the rest is second order in μ: measured 5e-6 to 6e-6 of the μ term (|μ| ~ 2e-5)
        assert np.max(np.abs(nu + h @ dx)) < 5e-5 * first


def test_attitude_matching_on_a_platform_is_minus_h_times_the_error():
    """``h = Ĉ_s (M̂ Ĉ_scan)ᵀ``: H_φ = I, H_μ = −C_r as for the fixed mount."""
    rng = _rng()
    n, i_phi, i_mu = 15, 6, 12
    c_r = dcm_from_euler(0.3, -0.2, 2.0)
    for theta in (-0.5, 0.1, 0.52):
        c_scan = tm.scan_dcm(AXIS, theta)
        phi, mu = rng.normal(0, 1e-5, 3), rng.normal(0, 1e-5, 3)
        c_hat = dcm_from_rotvec(phi) @ c_r @ MOUNT @ c_scan
        m_hat = dcm_from_rotvec(mu) @ MOUNT
        nu, h = tm.attitude_matching(c_hat, c_r, m_hat @ c_scan, n, i_phi, i_mu)
        dx = np.zeros(n)
        dx[i_phi : i_phi + 3], dx[i_mu : i_mu + 3] = phi, mu
        assert np.max(np.abs(nu + h @ dx)) < 1e-9
        assert np.max(np.abs(nu)) > 1e-6


def test_a_resolver_bias_is_a_mounting_error_along_m_a():
    """``M Rot(a, θ + b) = exp([b (M a)×]) M Rot(a, θ)`` for every θ: the filter that takes the
    biased reading at face value sees the true platform with the mounting ``exp([−b M a×]) M``;
    with it both matching innovations vanish (the bias is not separately observable)."""
    b = np.radians(0.7)
    rng = _rng()
    c_prev, c_next = _masters(rng)
    tilted = dcm_from_rotvec(-b * (MOUNT @ AXIS)) @ MOUNT
    for theta in np.linspace(-0.6, 0.6, 7):
        lhs = MOUNT @ tm.scan_dcm(AXIS, theta + b)
        rhs = dcm_from_rotvec(b * (MOUNT @ AXIS)) @ MOUNT @ tm.scan_dcm(AXIS, theta)
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-15)
        # attitude: the true slave against the biased reading and the tilted mounting
        c_s = c_prev @ MOUNT @ tm.scan_dcm(AXIS, theta)
        nu, _ = tm.attitude_matching(c_s, c_prev, tilted @ tm.scan_dcm(AXIS, theta + b), 15, 6, 12)
        assert np.max(np.abs(nu)) < 1e-15
    # velocity: the carried displacement is the true one
    th = (0.2, 0.25)
    true = [MOUNT @ tm.scan_dcm(AXIS, x) @ DISP for x in th]
    seen = [tm.platform_offset(tilted, tm.scan_dcm(AXIS, x + b), DISP) for x in th]
    e_true, _ = tm.displacement_transport(c_prev, c_next, true[0], true[1], T)
    e_seen, _ = tm.displacement_transport(c_prev, c_next, seen[0], seen[1], T)
    np.testing.assert_allclose(e_seen, e_true, rtol=0, atol=1e-13)


def _numeric_jacobian(f, x0: np.ndarray, step: float = 1e-7) -> np.ndarray:
    cols = []
    for k in range(x0.size):
        dx = np.zeros_like(x0)
        dx[k] = step
        cols.append((f(x0 + dx) - f(x0 - dx)) / (2 * step))
    return np.column_stack(cols)


def test_resolver_noise_is_the_readings_variance_through_the_measurements():
    """R of the resolver's white noise = J σ² Jᵀ with J the numerical derivative of the
    carried velocity (readings m−1, m+1) and of the attitude innovation (reading m)."""
    rng = _rng()
    c_prev, c_next = _masters(rng)
    th = np.array([0.31, 0.36])
    sigma = 1e-3

    def carried(readings: np.ndarray) -> np.ndarray:
        w = [tm.platform_offset(MOUNT, tm.scan_dcm(AXIS, x), DISP) for x in readings]
        return tm.displacement_transport(c_prev, c_next, w[0], w[1], T)[0]

    j = _numeric_jacobian(carried, th)
    want = sigma**2 * j @ j.T
    got = tm.resolver_noise_velocity(c_prev, c_next, MOUNT, tm.scan_dcm(AXIS, th[0]),
                                     tm.scan_dcm(AXIS, th[1]), AXIS, DISP, sigma, T)  # fmt: skip
    assert np.abs(want).max() > 1e-8
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    c_s = c_prev @ MOUNT @ tm.scan_dcm(AXIS, 0.33)

    def innovation(reading: np.ndarray) -> np.ndarray:
        nominal = MOUNT @ tm.scan_dcm(AXIS, float(reading[0]))
        return tm.attitude_matching(c_s, c_prev, nominal, 15, 6, 12)[0]

    ja = _numeric_jacobian(innovation, np.array([0.33]))
    np.testing.assert_allclose(tm.resolver_noise_attitude(c_prev, MOUNT, AXIS, sigma),
                               sigma**2 * ja @ ja.T, rtol=1e-6, atol=1e-22)  # fmt: skip


def test_the_smoothed_scan_is_a_turn_about_the_scan_axis():
    """Appendix D on a single-axis sweep: ``Mᵀ C_Bvar^Bref = Rot(a, θ_f)`` (γ along a), so the
    resolver's angle is well defined; θ_f lags the unfiltered triangle by the window's τ."""
    sc = load_scenario(SCAN_SCENARIO)
    om = sc.variation.offset_model()
    hist = om.history(T, 2400)
    rel = np.swapaxes(om.mount, -1, -2) @ hist.c_bvar_bref
    axis = np.asarray(om.scan.axis)
    theta = tm.scan_angle(hist.c_bvar_bref, om.mount, axis)
    rebuilt = np.array([tm.scan_dcm(axis, x) for x in theta])
    assert np.abs(rebuilt - rel).max() < 5e-15  # measured 4.4e-16
    # the walking window of 21 cycles lags a 20 deg/s sweep by 10 cycles: 0.05 s
    t = np.arange(theta.size) * T
    raw = tm.scan_angle(om.mount @ np.asarray(om.scan(t), dtype=np.float64), om.mount, axis)
    mid = (t > 0.5) & (t < 1.0)  # the first steady ramp
    np.testing.assert_allclose(theta[mid], raw[mid] - np.radians(20.0) * 10 * T, atol=1e-12)


# -- the scenario rules --------------------------------------------------------------------------


def test_resolver_errors_need_a_scan():
    fixed = REPO / "config" / "scenarios" / "transfer_alignment.yaml"
    with pytest.raises(ScenarioError, match=r"transfer_alignment\.resolver.*variation\.scan"):
        load_scenario(fixed, ["transfer_alignment.resolver={noise_deg: 0.01}"])
    # a displacement alone is a platform: accepted with the central difference
    load_scenario(fixed, ["variation.displacement_m=[0, 0, 0.1]"])
    with pytest.raises(ScenarioError, match="central_difference"):
        load_scenario(fixed, ["variation.displacement_m=[0, 0, 0.1]",
                              "transfer_alignment.velocity_transport=rate"])  # fmt: skip


# -- no model error on the scanning platform, bags read back from disk ---------------------------

#: No model error (as test_transfer_alignment.py's EXACT) and an exact resolver.
EXACT_SCAN = ["variation.bending=null", "imu_errors=null",
              "transfer_alignment.imu_topic=/variation/imu", "transfer_alignment.master={}",
              "transfer_alignment.tuning={}", "transfer_alignment.resolver={}"]  # fmt: skip


def _bag(tmp_path: Path, overrides: list[str]) -> dict:
    from test_transfer_alignment import _generate

    return _generate(tmp_path, [*EXACT_SCAN, *overrides], 30.0, SCAN_SCENARIO)


def _norms(r: dict, topic: str) -> np.ndarray:
    return np.linalg.norm(r[topic], axis=1)


@pytest.mark.slow
def test_scan_exact_mounting_at_start_errors_stay_at_round_off(tmp_path):
    """The nominal mounting is the true one and the resolver exact: every error on the sweeping
    platform is the filter's rounding."""
    from test_transfer_alignment import check_round_off

    r = _bag(tmp_path, ["transfer_alignment.mounting_error_deg=[0, 0, 0]"])
    # measured: 2.95e-9 m (the Earth-centred position's ulps), 6.5e-13 m/s, 5.5e-11 rad in the
    # first second (P of the mounting large), 8.3e-15 rad after 15 s; mounting 5.5e-11 rad
    check_round_off(r, {"position": 3e-8, "velocity": 7e-12, "attitude": 6e-10,
                        "mounting": 6e-10, "attitude_late": 1e-13,
                        "mounting_late": 1e-13})  # fmt: skip


@pytest.mark.slow
def test_scan_mounting_error_converges_to_the_true_mounting(tmp_path):
    """Nominal mounting off by (0.5, −0.3, 1.0) deg on the sweeping platform: after the wing rock
    and the first S-turn the mounting estimate equals ``C_mount`` (the zero-scan mounting) to
    far better than 1 µrad; the slave's velocity and attitude errors are at round-off."""
    from test_transfer_alignment import check_converged

    r = _bag(tmp_path, [])
    # measured after 20 s: mounting 6.2e-12 rad, attitude 5.5e-12 rad, velocity 6.4e-10 m/s,
    # mounting σ 5.2e-9 rad; position 1.5e-3 m at the start, 1.8e-5 m constant after 15 s: the
    # 1.17 deg turns the 0.15 m displacement in the start (its second-order part,
    # 0.15 m × 0.0204²/2 = 3e-5 m, is outside P0's correlation)
    check_converged(r, {"mounting": 6e-11, "attitude": 6e-11, "velocity": 6e-9,
                        "position": 2e-3, "position_late": 2e-4, "sigma": 5e-8})  # fmt: skip


@pytest.mark.slow
def test_a_resolver_bias_is_absorbed_by_the_mounting_and_the_slave_stays_exact(tmp_path):
    """A 0.1 deg resolver bias about the scan axis (z, FRD down) and a 90 deg yaw mounting: the
    mounting estimate converges to ``exp([−b (M a)×]) C_mount``, i.e. the published error
    (reference body FLU) to ``(0, 0, +b)``; the slave's attitude and velocity stay exact."""
    b = np.radians(0.1)
    r = _bag(tmp_path, ["transfer_alignment.resolver={bias_deg: 0.1}"])
    late = r["t"] >= 20.0
    mu = r["/transfer/mounting/error"][late]
    # measured: (−2.4e-12, −4.2e-12, b + 4e-12) rad
    np.testing.assert_allclose(mu, np.tile([0.0, 0.0, b], (mu.shape[0], 1)), rtol=0, atol=5e-11)
    assert _norms(r, "/transfer/error/attitude")[late].max() < 7e-11  # measured 6.4e-12 rad
    assert _norms(r, "/transfer/error/velocity")[late].max() < 7e-9  # measured 7.1e-10 m/s


@pytest.mark.slow
def test_the_report_removes_the_scan_from_the_true_mounting(tmp_path):
    """`report` on a scanning-platform bag: the truths' relative attitude ``C_mount C_scan(t)``
    less the scan (rebuilt from the bag's `variation.offsets`) is the scenario's zero-scan
    mounting, constant; the recomputed mounting error is the filter's. Without that record the
    transfer part is omitted with the reason."""
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.core.rotations import euler_from_dcm
    from strapdown_ros.generate import generate_dataset
    from strapdown_ros.plan.metadata import VARIATION_OFFSETS
    from strapdown_ros.report import write_report
    from strapdown_ros.report.transfer import transfer_data

    sc = load_scenario(SCAN_SCENARIO, EXACT_SCAN, duration_s=30.0)
    generate_dataset(sc, tmp_path / "bag")
    res = write_report(tmp_path / "bag", exactness=False, free_inertial=False)
    r = res.transfer["/transfer"]
    assert r.scan_removed
    want = np.radians(sc.variation.mounting_rph_deg)  # (0, 0, 90) deg
    got = np.array([float(x) for x in euler_from_dcm(r.mounting_true)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    assert r.mounting_spread < 5e-15  # measured 4.9e-16 over 30 s of a ±30 deg sweep
    # measured 1.8e-16 rad
    np.testing.assert_allclose(r.error, r.published_error, rtol=0, atol=2e-15)
    contents = read_bag(tmp_path / "bag", ["/transfer/odom", "/transfer/vel", "/variation/odom",
                        "/reference/odom", "/transfer/mounting/estimate",
                        "/transfer/mounting/sigma"])  # fmt: skip
    del contents.custom_data[VARIATION_OFFSETS]
    why = transfer_data(contents, "/transfer", sc.start_time_ns)
    assert isinstance(why, str) and "scanning platform" in why and VARIATION_OFFSETS in why
