"""Transfer alignment: the matching measurements, the scenario rules and, on bags read back
from disk, the no-model-error case (master exact, no bending, ideal slave IMU): the mounting
misalignment converges to the scenario's true mounting and the slave's errors stay at the
filter's round-off (docs/transfer_alignment.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.core.rotations import dcm_from_euler, dcm_from_rotvec, rotvec_from_dcm, skew
from strapdown_ros.core.transfer.measurements import (
    attitude_matching,
    transport_matrix,
    velocity_matching,
)

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment.yaml"
SCAN_SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment_scan.yaml"
#: No model error: no bending, the ideal variation IMU, an exact master, no added R.
EXACT = ["variation.bending=null", "imu_errors=null", "transfer_alignment.imu_topic=/variation/imu",
         "transfer_alignment.master={}", "transfer_alignment.tuning={}"]  # fmt: skip
TOPICS = ["/transfer/error/position", "/transfer/error/velocity", "/transfer/error/attitude",
          "/transfer/mounting/error", "/transfer/mounting/sigma", "/transfer/odom",
          "/transfer/nis"]  # fmt: skip


def _rng() -> np.random.Generator:
    return np.random.default_rng(7)


# -- the measurement models --------------------------------------------------------------------


def test_attitude_matching_innovation_is_minus_h_times_the_error():
    rng = _rng()
    c_r = dcm_from_euler(0.3, -0.2, 2.0)
    mount = dcm_from_euler(0.02, -0.01, 1.5)
    n, i_phi, i_mu = 15, 6, 12
    for _ in range(5):
        phi, mu = rng.normal(0, 1e-5, 3), rng.normal(0, 1e-5, 3)
        c_hat = dcm_from_rotvec(phi) @ c_r @ mount  # Ĉ_s = exp([φ×]) C_r M
        m_hat = dcm_from_rotvec(mu) @ mount  # M̂ = exp([μ×]) M
        nu, h = attitude_matching(c_hat, c_r, m_hat, n, i_phi, i_mu)
        dx = np.zeros(n)
        dx[i_phi : i_phi + 3], dx[i_mu : i_mu + 3] = phi, mu
        # second-order residual: |φ||μ| ~ 1e-10
        assert np.max(np.abs(nu + h @ dx)) < 1e-9
        assert np.max(np.abs(nu)) > 1e-6  # the test is not trivial


def test_attitude_jacobian_at_the_estimate_is_dh_and_leaves_the_common_turn_unseen():
    """``H_μ = −ĥ``, ``ĥ = Ĉ_s M̂ᵀ``: h's derivative at the estimate (left perturbations of ĥ),
    and the common turn ``(φ, μ) = (u, ĥᵀ u)`` is in H's nullspace; the measured master
    attitude's ``H_μ = −C̃_r`` turns it by the master's noise (docs/transfer_alignment.md §6)."""
    rng = _rng()
    c_r = dcm_from_euler(0.3, -0.2, 2.0)
    mount = dcm_from_euler(0.02, -0.01, 1.5)
    n, i_phi, i_mu = 15, 6, 12
    for _ in range(5):
        c_hat = dcm_from_rotvec(rng.normal(0, 0.02, 3)) @ c_r @ mount  # 1-deg errors
        m_hat = dcm_from_rotvec(rng.normal(0, 0.02, 3)) @ mount
        c_meas = c_r @ dcm_from_rotvec(rng.normal(0, 1e-4, 3))  # the master's noise
        _, h = attitude_matching(c_hat, c_meas, m_hat, n, i_phi, i_mu, at_estimate=True)
        _, h_meas = attitude_matching(c_hat, c_meas, m_hat, n, i_phi, i_mu)
        h_hat = c_hat @ m_hat.T
        step = 1e-7
        for k in range(3):  # columns of ∂h/∂x: rotvec(h(x̂ ⊞ δx) ĥᵀ) / step
            e = np.eye(3)[k] * step
            d_phi = rotvec_from_dcm(dcm_from_rotvec(e) @ c_hat @ m_hat.T @ h_hat.T) / step
            d_mu = rotvec_from_dcm(c_hat @ (dcm_from_rotvec(e) @ m_hat).T @ h_hat.T) / step
            np.testing.assert_allclose(d_phi, h[:, i_phi + k], rtol=0, atol=1e-8)
            np.testing.assert_allclose(d_mu, h[:, i_mu + k], rtol=0, atol=1e-8)
        for u in np.eye(3):
            x = np.zeros(n)
            x[i_phi : i_phi + 3], x[i_mu : i_mu + 3] = u, h_hat.T @ u
            assert np.max(np.abs(h @ x)) < 1e-15
            assert np.max(np.abs(h_meas @ x)) > 1e-5  # turned by ε and the estimate's ν̂


@pytest.mark.slow  # compiles the update
def test_the_measured_attitude_jacobian_invents_information_on_the_common_turn():
    """Attitude matching alone, N updates of a master with white noise σ_ε (R = σ_ε² I), P0 as
    the stage's (``φ = C_r μ`` plus the master's noise): slave and mounting turned together are
    not observable, so μ's σ keeps its prior with ``attitude_jacobian: estimate``. With the
    measured ``H_μ = −C̃_r`` each update takes ``C_r (ε × μ)`` for signal: E|ε × u|²/σ_ε² = 2
    rad⁻² of information per update and axis, ``1/σ_N² = 1/σ_0² + 2N`` whatever σ_ε."""
    import dataclasses

    from strapdown_ros.core.aided.model import SensorModels, StateOptions, build_model
    from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors
    from strapdown_ros.core.transfer.filter import TransferFilter, TransferLayout

    sensor = dataclasses.replace(SensorErrors.zero(), turn_on_bias_sigma=np.full(3, 1e-5))
    model = build_model(ImuErrorParameters(sensor, sensor), 0.005, SensorModels(),
                        StateOptions(None, None, False))  # fmt: skip
    lay = TransferLayout(model, False)
    c_r = dcm_from_euler(0.03, 0.035, 0.4)
    mount = dcm_from_euler(0.02, -0.01, 1.5)
    s_mu, s_eps, updates = np.radians(1.0), 1e-4, 1000
    sig = np.full(lay.n, 1e-3)
    sig[6:9], sig[lay.i_mu : lay.i_mu + 3] = s_eps, s_mu
    a = np.eye(lay.n)
    a[6:9, lay.i_mu : lay.i_mu + 3] = c_r
    p0 = a @ np.diag(sig**2) @ a.T
    out = {}
    for kind in ("measurement", "estimate"):
        rng = np.random.default_rng(5)
        mu0 = rng.normal(0, s_mu, 3)
        m_hat = dcm_from_rotvec(mu0) @ mount
        c0 = c_r @ dcm_from_rotvec(rng.normal(0, s_eps, 3))
        f = TransferFilter(lay, 5_000_000, "j2", np.array([6.4e6, 0.0, 0.0]), np.zeros(3),
                           c0 @ m_hat, m_hat, np.zeros(3), p0.copy(),
                           attitude_jacobian=kind)  # fmt: skip
        for _ in range(updates):
            f.update_attitude(c_r @ dcm_from_rotvec(rng.normal(0, s_eps, 3)),
                              np.eye(3) * s_eps**2)  # fmt: skip
        out[kind] = np.sqrt(np.diag(f.p)[lay.i_mu : lay.i_mu + 3])
    assert np.all(out["estimate"] > 0.995 * s_mu)
    closed = 1.0 / np.sqrt(1.0 / s_mu**2 + 2.0 * updates)  # 13.8 mrad of 17.5
    np.testing.assert_allclose(out["measurement"], closed, rtol=0.05)


def test_velocity_matching_is_linear_in_the_lever_arm_error():
    rng = _rng()
    d = rng.normal(size=(3, 3))
    lever, v_r = np.array([-2.0, 4.0, 0.5]), rng.normal(size=3) * 100
    v_s = v_r + d @ lever
    dv, dl = rng.normal(size=3) * 1e-3, rng.normal(size=3) * 1e-2
    n = 18
    nu, h = velocity_matching(v_s + dv, v_r, d, lever + dl, n, 3, 15)
    dx = np.zeros(n)
    dx[3:6], dx[15:18] = dv, dl
    assert np.allclose(nu, -h @ dx, rtol=0, atol=1e-12)


def test_central_difference_transport_is_eq_10_for_a_constant_rate():
    # constant body rate ω: C_{m±1} = C_m exp(±[a×]), a = ωT, so (C_{m+1} − C_{m−1}) l / 2T is
    # C_m (sin|a|/|a|) ω × l plus a (1 − cos|a|)/|a|² term along ω × (ω × l)... which cancels
    # in the difference: the result is C_m (sin|a|/|a|) (ω × l) exactly.
    c = dcm_from_euler(0.1, 0.2, 0.3)
    w = np.array([0.3, -0.2, 0.5])
    t = 0.005
    a = w * t
    lever = np.array([-2.0, 4.0, 0.5])
    d = transport_matrix("central_difference", c @ dcm_from_rotvec(-a), c, c @ dcm_from_rotvec(a),
                         w, t)  # fmt: skip
    x = np.linalg.norm(a)
    expected = c @ (np.sin(x) / x * np.cross(w, lever))
    assert np.allclose(d @ lever, expected, rtol=0, atol=1e-13)
    rate = transport_matrix("rate", c, c, c, w, t)
    assert np.allclose(rate, c @ skew(w), rtol=0, atol=0)


# -- the scenario rules --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("scenario", "override", "words"),
    [
        (SCENARIO, "transfer_alignment.rate_hz=40", "even number"),
        (SCENARIO, "transfer_alignment.rate_hz=3", "whole multiple"),
        (SCENARIO, "transfer_alignment.imu_topic=/reference/imu", "neither the variation IMU"),
        (SCENARIO, "transfer_alignment.master_topic=/variation/odom", "reference truth"),
        (SCENARIO, "transfer_alignment.measurements=[attitude]", "must contain velocity"),
        (SCENARIO, "transfer_alignment.master.latency_s=0.0031", "whole number of IMU periods"),
        # the scanning platform: a sweep about one axis only, and eq. (10)'s transport
        (SCAN_SCENARIO, "variation.scan={kind: raster, amplitude_deg: 30, rate_dps: 20, "
         "elevation_step_deg: 5, rows: 3}", "kind 'raster' is not supported"),
        (SCAN_SCENARIO, "variation.scan={kind: segments, segments: [{duration_s: 1, "
         "rate_dps: [0, 0, 5]}]}", "kind 'segments' is not supported"),
        (SCAN_SCENARIO, "transfer_alignment.velocity_transport=rate", "central_difference"),
    ],
)  # fmt: skip
def test_bad_sections_are_refused_naming_the_key(scenario, override, words):
    with pytest.raises(ScenarioError) as err:
        load_scenario(scenario, [override])
    assert "transfer_alignment" in str(err.value)
    assert words in str(err.value)


@pytest.mark.slow  # imports (and compiles) the filter's kernels
def test_the_shipped_scenario_plans_the_transfer_topics():
    from strapdown_ros.plan import resolve_plan

    plan = resolve_plan(load_scenario(SCENARIO, duration_s=2.0))
    assert "transfer_alignment" in plan.links
    odom = plan.topics["/transfer/odom"]
    assert odom.count == plan.variation_cycles // 20 + 1  # 10 Hz at 200 Hz, epoch 0 included
    assert plan.topics["/transfer/nis"].count == odom.count - 1


# -- no model error, bags read back from disk ----------------------------------------------------


def _generate(tmp_path: Path, overrides: list[str], duration: float,
              scenario: Path = SCENARIO) -> dict:  # fmt: skip
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.generate import generate_dataset
    from strapdown_ros.plan import resolve_plan

    sc = load_scenario(scenario, overrides, duration_s=duration)
    generate_dataset(sc, tmp_path / "bag")
    bag = read_bag(tmp_path / "bag", TOPICS)
    plan = resolve_plan(sc)
    for topic in TOPICS:
        assert len(bag.topics[topic]) == plan.topics[topic].count, topic
    out = {t: np.asarray(bag[t].vector) for t in TOPICS if t != "/transfer/odom"}
    st = np.asarray(bag["/transfer/error/attitude"].stamps_ns)
    out["t"] = (st - st[0]) * 1e-9
    return out


def _norms(r: dict, topic: str) -> np.ndarray:
    return np.linalg.norm(r[topic], axis=1)


def check_round_off(r: dict, limits: dict[str, float]) -> None:
    """The nominal mounting is the true one: the slave's position, velocity and attitude errors
    and the mounting error stay under ``limits`` all along; after 15 s the attitude error (and
    the mounting error, if ``limits["mounting_late"]`` is given) under its ``*_late`` limit."""
    assert _norms(r, "/transfer/error/position").max() < limits["position"]
    assert _norms(r, "/transfer/error/velocity").max() < limits["velocity"]
    assert _norms(r, "/transfer/error/attitude").max() < limits["attitude"]
    mounting = _norms(r, "/transfer/mounting/error")
    assert mounting.max() < limits["mounting"]
    late = r["t"] >= 15.0
    assert _norms(r, "/transfer/error/attitude")[late].max() < limits["attitude_late"]
    assert mounting[late].max() < limits.get("mounting_late", np.inf)


@pytest.mark.slow
def test_exact_mounting_at_start_errors_stay_at_round_off(tmp_path):
    """The nominal mounting is the true one: every error is the filter's rounding."""
    r = _generate(tmp_path, [*EXACT, "transfer_alignment.mounting_error_deg=[0, 0, 0]"], 30.0)
    # measured: 2.6e-9 m (3 ulp of the Earth-centred position), 1.2e-12 m/s, 7.1e-11 rad (in
    # the first second, while P of the mounting is large; 2e-14 rad after 15 s), mounting 7.1e-11
    check_round_off(r, {"position": 1e-8, "velocity": 1e-11, "attitude": 5e-10,
                        "mounting": 5e-10, "attitude_late": 1e-12})  # fmt: skip


def check_converged(r: dict, limits: dict[str, float]) -> None:
    """The nominal mounting off by (0.5, −0.3, 1.0) deg (1.17 deg) at the start: after 20 s the
    mounting error is under the 1 µrad acceptance bar and under ``limits["mounting"]``, the
    slave's attitude and velocity errors and the mounting σ under theirs; the position error
    under ``limits["position"]`` all along (and ``limits["position_late"]`` after 20 s, if
    given)."""
    mu = _norms(r, "/transfer/mounting/error")
    assert mu[0] > 0.019  # the initial error, 1.17 deg
    late = r["t"] >= 20.0
    assert mu[late].max() < 1e-6  # the acceptance bar, 1 µrad
    assert mu[late].max() < limits["mounting"]
    assert _norms(r, "/transfer/error/attitude")[late].max() < limits["attitude"]
    assert _norms(r, "/transfer/error/velocity")[late].max() < limits["velocity"]
    position = _norms(r, "/transfer/error/position")
    assert position.max() < limits["position"]
    assert position[late].max() < limits.get("position_late", np.inf)
    assert np.all(r["/transfer/mounting/sigma"][late] < limits["sigma"])


@pytest.mark.slow
def test_exact_mounting_error_converges_to_the_true_mounting(tmp_path):
    """Nominal mounting off by (0.5, −0.3, 1.0) deg: after the wing rock and the first S-turn
    the estimated mounting equals the scenario's to far better than 1 µrad, the slave's
    velocity and attitude errors are at round-off."""
    r = _generate(tmp_path, EXACT, 30.0)
    # measured after 20 s: mounting 6.4e-12 rad, attitude 3.1e-12 rad, velocity 2.1e-10 m/s,
    # mounting σ 5.1e-9 rad; position 4.6e-6 m: what the first 0.1 s of the 1.17 deg attitude
    # error left (the position is seen only through the velocity), constant after
    check_converged(r, {"mounting": 1e-10, "attitude": 5e-11, "velocity": 2e-9,
                        "position": 5e-5, "sigma": 1e-8})  # fmt: skip


@pytest.mark.slow  # compiles the filter's kernels
def test_gauss_markov_estimates_decay_with_the_covariance():
    """Between updates the Gauss–Markov bias estimates are the conditional mean of
    ``ḃ = −b/τ + w``: ``b̂ e^{−Δt/τ}`` (τ = 300 s, Δt = 20 cycles of 5 ms); the random-constant
    biases and the mounting hold."""
    import dataclasses

    from strapdown_ros.core.aided.layout import B_BA, B_BG, B_GMA, B_GMG
    from strapdown_ros.core.aided.model import SensorModels, StateOptions, build_model
    from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors
    from strapdown_ros.core.transfer.filter import TransferFilter, TransferLayout

    tau, T = 300.0, 0.005
    sensor = dataclasses.replace(SensorErrors.zero(), turn_on_bias_sigma=np.full(3, 1e-5),
                                 bias_instability=np.full(3, 1e-5),
                                 correlation_time_s=np.full(3, tau))  # fmt: skip
    model = build_model(ImuErrorParameters(sensor, sensor), T, SensorModels(),
                        StateOptions(None, None, False))  # fmt: skip
    lay = TransferLayout(model, False)
    f = TransferFilter(lay, 5_000_000, "j2", np.array([6.4e6, 0.0, 0.0]), np.zeros(3),
                       np.eye(3), np.eye(3), np.zeros(3), np.eye(lay.n) * 1e-6)  # fmt: skip
    x0 = np.random.default_rng(3).normal(size=lay.n) * 1e-4
    f.est[9:] = x0[9:]
    f.propagate(np.zeros((20, 3)), np.zeros((20, 3)))
    decay = np.exp(-20 * T / tau)
    off = model.layout.offsets
    for block, factor in ((B_GMG, decay), (B_GMA, decay), (B_BG, 1.0), (B_BA, 1.0)):
        s = slice(int(off[block]), int(off[block]) + 3)
        np.testing.assert_allclose(f.est[s], x0[s] * factor, rtol=1e-15)
    np.testing.assert_array_equal(f.est[lay.i_mu : lay.i_mu + 3], x0[lay.i_mu : lay.i_mu + 3])
