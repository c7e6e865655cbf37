"""The aided filter's models against independent references (core/aided, no ROS).

* measurement Jacobians: central differences of the *simulation's* sensor equations
  (core/aiding: antenna_state, gnss_measurement, icao_pressure, igrf_field_ned, field_body,
  contact_point_velocity) at states perturbed in the filter's error convention
  (R + δR, V + δV, exp([φ×]) C, estimates + δ);
* error dynamics F: central differences of the nonlinear error rate of the mechanization
  (Ṙ = V, V̇ = C f + g(R), Ċ = C [ω×], measured rates with bias, Gauss–Markov and scale
  factor), gravitation from core/gravity;
* Van Loan: scipy's expm of Van Loan's block matrix and a fine-step RK4 of Ṗ = FP + PFᵀ + Q;
* Joseph form: the dense textbook product, positive definite in a hostile case where the
  short form P - KHP is not;
* the scalar compiled fields against the vectorized ones the simulation uses.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

from strapdown_ros.core.aided._fields import (
    ecef_to_geodetic1,
    gravitation_gradient,
    icao_pressure1,
    igrf_ned1,
)
from strapdown_ros.core.aided.dynamics import (
    continuous_noise,
    dense_dynamics,
    propagate_covariance,
    sparse_dynamics,
    van_loan_series,
)
from strapdown_ros.core.aided.layout import (
    B_BA,
    B_BARO_BIAS,
    B_BARO_DRIFT,
    B_BG,
    B_GMA,
    B_GMG,
    B_GNSS_POS,
    B_GNSS_VEL,
    B_MAG,
    B_SFA,
    B_SFG,
    B_WHEEL_QUANT,
    B_WHEEL_SF,
    N_BLOCKS,
    StateLayout,
)
from strapdown_ros.core.aided.measurement_models import (
    baro_model,
    gnss_position_model,
    gnss_velocity_model,
    mag_model,
    wheel_model,
)
from strapdown_ros.core.aided.update import joseph_update, reset_attitude
from strapdown_ros.core.aiding.baro import icao_pressure
from strapdown_ros.core.aiding.gnss import antenna_state, gnss_measurement
from strapdown_ros.core.aiding.magnetometer import _recursion_factors, field_body, igrf_field_ned
from strapdown_ros.core.aiding.odometer import contact_point_velocity
from strapdown_ros.core.earth import (
    OMEGA_IE,
    dcm_e0_to_ecef,
    dcm_ecef_to_ned,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.gravity import gravitation

LAYOUT = StateLayout(tuple(range(N_BLOCKS)))
N = LAYOUT.n
OFF = LAYOUT.offsets
T = 0.005  # IMU period, s
W = np.array([0.0, 0.0, OMEGA_IE])


def _rot(phi: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(phi).as_matrix()


@pytest.fixture(scope="module")
def state():
    """A nominal state (E0), estimates of every state, a raw gyro increment, time since E0."""
    rng = np.random.default_rng(7)
    t = 137.25
    lat, lon, alt = np.radians(45.3), np.radians(7.6), 1500.0
    r_e = geodetic_to_ecef(lat, lon, alt)
    c_e0 = dcm_e0_to_ecef(t).T  # C_E^E0
    v_e = np.array([60.0, -25.0, 3.0])
    r = c_e0 @ r_e
    v = c_e0 @ (v_e + np.cross(W, r_e))
    c = c_e0 @ _rot(rng.normal(size=3))
    est = np.zeros(N)
    est[9:] = rng.normal(size=N - 9) * 1e-3
    est[LAYOUT.slice(B_BG)] = rng.normal(size=3) * 1e-5
    est[LAYOUT.slice(B_GMG)] = rng.normal(size=3) * 1e-6
    est[LAYOUT.slice(B_SFG)] = rng.normal(size=3) * 1e-3
    est[LAYOUT.slice(B_SFA)] = rng.normal(size=3) * 1e-3
    est[LAYOUT.slice(B_MAG)] = rng.normal(size=3) * 1e-6
    est[LAYOUT.slice(B_GNSS_POS)] = rng.normal(size=3)
    est[LAYOUT.slice(B_BARO_BIAS)] = 30.0
    da = np.array([0.2, -0.35, 0.6]) * T  # a hard turn
    return {"t": t, "r": r, "v": v, "c": c, "est": est, "da": da}


def _perturbed(s: dict, dx: np.ndarray) -> dict:
    """The state ``s`` with the error ``dx`` in the filter's convention."""
    return {**s, "r": s["r"] + dx[0:3], "v": s["v"] + dx[3:6], "c": _rot(dx[6:9]) @ s["c"],
            "est": s["est"] + np.concatenate([np.zeros(9), dx[9:]])}  # fmt: skip


def _omega_eb(s: dict) -> np.ndarray:
    """ω̂_eb^B written out: (Δα̃/T - b - m)/(1 + s) - Cᵀ ω_ie."""
    e = s["est"]
    raw = s["da"] / T - e[LAYOUT.slice(B_BG)] - e[LAYOUT.slice(B_GMG)]
    return raw / (1.0 + e[LAYOUT.slice(B_SFG)]) - s["c"].T @ W


def _ecef(s: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ce = dcm_e0_to_ecef(s["t"])
    return ce @ s["r"], ce @ (s["v"] - np.cross(W, s["r"])), ce @ s["c"]


#: Perturbation size per state (m, m/s, rad, then the other states).
STEP = np.concatenate([np.full(3, 1e-2), np.full(3, 1e-3), np.full(3, 1e-6), np.full(N - 9, 1e-6)])


#: Larger steps for models of large absolute values (ECEF positions ~6e6 m, pressures ~1e5 Pa),
#: where a 1e-6 step would be lost in the rounding of the value itself.
STEP_ABSOLUTE = np.concatenate([np.full(3, 1.0), np.full(3, 1e-3), np.full(3, 1e-3),
                                np.full(N - 9, 1e-2)])  # fmt: skip


def _numeric(h, s: dict, step: np.ndarray = STEP) -> np.ndarray:
    cols = []
    for j in range(N):
        e = np.zeros(N)
        e[j] = step[j]
        cols.append((h(_perturbed(s, e)) - h(_perturbed(s, -e))) / (2 * step[j]))
    return np.array(cols).T


def _check(h_model: np.ndarray, h_num: np.ndarray, rel: float, ignore: slice | None = None) -> None:
    scale = np.abs(h_num).max()
    diff = np.abs(h_model - h_num)
    if ignore is not None:
        diff[:, ignore] = 0.0
    worst = np.unravel_index(diff.argmax(), diff.shape)
    assert diff.max() <= rel * scale, (diff.max() / scale, worst)


LEVER = np.array([1.2, -0.4, -1.5])


def test_gnss_position_jacobian(state):
    r_e, _, _ = _ecef(state)
    lat, lon, _ = ecef_to_geodetic(r_e)
    cen = dcm_ecef_to_ned(lat, lon)
    z = r_e + np.array([3.0, -2.0, 1.0])

    def h(s):
        re, ve, cbe = _ecef(s)
        ra, _ = antenna_state(re[None], ve[None], cbe[None], _omega_eb(s)[None], LEVER)
        return cen @ ra[0] + s["est"][LAYOUT.slice(B_GNSS_POS)]

    nu, hm = gnss_position_model(state["r"], np.zeros(6), state["c"], state["t"], state["est"],
                                 OFF, LEVER, z, float(lat), float(lon))  # fmt: skip
    np.testing.assert_allclose(nu, cen @ z - h(state), atol=1e-8)
    _check(hm, _numeric(h, state, STEP_ABSOLUTE), 3e-6)  # measured 3.7e-7 (step rounding)


def test_gnss_velocity_jacobian(state):
    def h(s):
        re, ve, cbe = _ecef(s)
        ra, va = antenna_state(re[None], ve[None], cbe[None], _omega_eb(s)[None], LEVER)
        enu = gnss_measurement(ra, va, np.zeros((1, 3)), np.zeros((1, 3))).v_enu[0]
        return np.array([enu[1], enu[0], -enu[2]]) + s["est"][LAYOUT.slice(B_GNSS_VEL)]

    z = h(state) + np.array([0.1, -0.2, 0.05])
    nu, hm = gnss_velocity_model(state["r"], state["v"], state["c"], state["t"], state["est"],
                                 OFF, LEVER, state["da"], T, z)  # fmt: skip
    np.testing.assert_allclose(nu, z - h(state), atol=1e-10)
    _check(hm, _numeric(h, state), 3e-8)  # measured 3.1e-9


def test_baro_jacobian(state):
    def h(s):
        re, ve, cbe = _ecef(s)
        rs, _ = antenna_state(re[None], ve[None], cbe[None], np.zeros((1, 3)), LEVER)
        _, _, alt = ecef_to_geodetic(rs)
        e = s["est"]
        return icao_pressure(alt) + e[LAYOUT.slice(B_BARO_BIAS)] + e[LAYOUT.slice(B_BARO_DRIFT)]

    z = float(h(state)[0]) + 12.0
    nu, hm = baro_model(state["r"], np.zeros(6), state["c"], state["t"], state["est"], OFF,
                        LEVER, z)  # fmt: skip
    np.testing.assert_allclose(nu, z - h(state), atol=1e-9)
    _check(hm, _numeric(h, state, STEP_ABSOLUTE), 3e-6)  # measured 2.8e-7 (step rounding)


@pytest.fixture(scope="module")
def igrf():
    from strapdown_ros.stages.aiding import igrf_coefficients

    g, h = igrf_coefficients(2026.0)
    a1, a2, d = _recursion_factors(g.shape[0] - 1)
    return np.ascontiguousarray(g), np.ascontiguousarray(h), a1, a2, d


def test_mag_jacobian(state, igrf):
    g, hc, a1, a2, d = igrf

    def h(s):
        re, _, cbe = _ecef(s)
        lat, lon, _ = ecef_to_geodetic(re)
        b_ned = igrf_field_ned(re[None], lat[None], g, hc) * 1e-9
        c_b_n = dcm_ecef_to_ned(lat, lon) @ cbe
        return field_body(c_b_n[None], b_ned)[0] + s["est"][LAYOUT.slice(B_MAG)]

    z = h(state) + 1e-7
    nu, hm = mag_model(state["r"], state["c"], state["t"], state["est"], OFF, z, g, hc, a1, a2,
                       d, 6371200.0)  # fmt: skip
    np.testing.assert_allclose(nu, z - h(state), atol=1e-15)
    hn = _numeric(h, state)
    # the field's position gradient (3|B|/r ≈ 2e-11 T/m) is left out of the model: measured
    assert np.abs(hn[:, 0:3]).max() < 5e-11
    _check(hm, hn, 1e-13, ignore=slice(0, 3))  # measured 3.8e-15


@pytest.mark.parametrize("mask", [(True, True, True), (True, False, False), (True, True, False)])
def test_wheel_jacobian(state, mask):
    lever = np.array([-2.0, 0.8, 1.1])
    mask = np.array(mask)

    def h(s):
        _, ve, cbe = _ecef(s)
        vc = contact_point_velocity(ve[None], cbe[None], _omega_eb(s)[None], lever)[0]
        vc[0] *= 1.0 + s["est"][LAYOUT.slice(B_WHEEL_SF)][0]
        last, nxt = s["est"][LAYOUT.slice(B_WHEEL_QUANT)]
        vc[0] += last - nxt  # the encoder's speed: ũ + (ρ_{k-1} − ρ_k) / P
        return vc[mask]

    z = h(state) + 0.01
    nu, hm = wheel_model(state["r"], state["v"], state["c"], state["est"], OFF, lever,
                         state["da"], T, np.pad(z, (0, 3 - len(z))), mask)  # fmt: skip
    np.testing.assert_allclose(nu, z - h(state), atol=1e-10)
    _check(hm, _numeric(h, state), 1e-9)  # measured 1.0e-10


# ---------------------------------------------------------------------------------------------
# error dynamics


def _error_rate(nom: dict, tru: dict, tau: float, gm_tau: np.ndarray) -> np.ndarray:
    """d/dt of the error (estimate minus truth) over a step τ of both mechanizations."""
    out = np.zeros(N)
    out[0:3] = nom["v"] - tru["v"]

    def accel(s, f):
        return s["c"] @ f + gravitation(s["r"])

    out[3:6] = accel(nom, nom["f"]) - accel(tru, tru["f"])
    c_nom = nom["c"] @ _rot(nom["w"] * tau)
    c_tru = tru["c"] @ _rot(tru["w"] * tau)
    phi0 = Rotation.from_matrix(nom["c"] @ tru["c"].T).as_rotvec()
    phi1 = Rotation.from_matrix(c_nom @ c_tru.T).as_rotvec()
    out[6:9] = (phi1 - phi0) / tau
    for b in (B_GMG, B_GMA):
        sl = LAYOUT.slice(b)
        out[sl] = -(nom["est"][sl] - tru["est"][sl]) / gm_tau
    return out


def test_error_dynamics_against_the_mechanization(state):
    """F of sparse_dynamics = ∂(error rate)/∂(error) of the nonlinear equations."""
    gm_tau = np.array([300.0, 200.0, 100.0])
    beta = np.zeros(N)
    beta[LAYOUT.slice(B_GMG)] = 1.0 / gm_tau
    beta[LAYOUT.slice(B_GMA)] = 1.0 / gm_tau
    w_true = np.array([0.05, -0.1, 0.3])
    f_true = np.array([1.5, -0.7, -9.9])
    truth = {**state, "est": state["est"].copy()}
    # measured rate and specific force of the true errors (b + m, scale factor)
    e = truth["est"]

    def measured(true_rate, b, m, s):
        return (1.0 + e[LAYOUT.slice(s)]) * true_rate + e[LAYOUT.slice(b)] + e[LAYOUT.slice(m)]

    w_meas = measured(w_true, B_BG, B_GMG, B_SFG)
    f_meas = measured(f_true, B_BA, B_GMA, B_SFA)

    def corrected(s, meas, b, m, sf):
        x = s["est"]
        return (meas - x[LAYOUT.slice(b)] - x[LAYOUT.slice(m)]) / (1.0 + x[LAYOUT.slice(sf)])

    tau = 1e-4

    def rate(dx):
        nom = _perturbed(truth, dx)
        nom["w"] = corrected(nom, w_meas, B_BG, B_GMG, B_SFG)
        nom["f"] = corrected(nom, f_meas, B_BA, B_GMA, B_SFA)
        tru = {**truth, "w": w_true, "f": f_true}
        return _error_rate(nom, tru, tau, gm_tau)

    ni = LAYOUT.n_coupled
    fn = np.zeros((N, N))
    for j in range(N):
        d = np.zeros(N)
        d[j] = STEP[j]
        fn[:, j] = (rate(d) - rate(-d)) / (2 * STEP[j])
    grad = gravitation_gradient(state["r"], 0)
    rows, cols, vals, nnz = sparse_dynamics(state["c"], state["c"] @ f_true, w_true, f_true, grad,
                                            e, OFF, beta, ni)  # fmt: skip
    fm = dense_dynamics(rows, cols, vals, nnz, ni)
    # the attitude rate of a finite step τ carries O(τ |ω|) of the rotation: measured 1.4e-6
    # relative; every other entry 9e-11
    diff = np.abs(fm - fn[:ni, :ni])
    scale = np.abs(fn[:ni, :ni]).max()
    assert diff.max() <= 1e-5 * scale
    off_att = np.ones_like(diff, dtype=bool)
    off_att[6:9, :] = False
    assert diff[off_att].max() <= 1e-9 * scale
    # the gravitation gradient: against core.gravity by central differences of its own
    h = 1.0
    ref = np.array([(gravitation(state["r"] + h * ej) - gravitation(state["r"] - h * ej)) / (2 * h)
                    for ej in np.eye(3)]).T  # fmt: skip
    np.testing.assert_allclose(grad, ref, rtol=0, atol=1e-13)
    assert np.abs(fn[ni:, :]).max() == 0.0  # sensor states decoupled (their own decay only)


def _random_dynamics(dt_rate: float = 1.0):
    s = np.random.default_rng(11)
    c = _rot(s.normal(size=3))
    grad = gravitation_gradient(geodetic_to_ecef(0.8, 0.1, 100.0), 0)
    est = np.zeros(N)
    est[LAYOUT.slice(B_SFG)] = 1e-3
    beta = np.zeros(N)
    beta[LAYOUT.slice(B_GMG)] = 1 / 300.0
    beta[LAYOUT.slice(B_GMA)] = 1 / 100.0
    ni = LAYOUT.n_coupled
    rows, cols, vals, nnz = sparse_dynamics(c, c @ np.array([2.0, -1.0, -9.8]),
                                            np.array([0.1, 0.2, -0.3]), np.array([2.0, -1, -9.8]),
                                            grad, est, OFF, beta, ni)  # fmt: skip
    q = np.zeros(N)
    q[9:ni] = s.uniform(1e-14, 1e-10, ni - 9)
    qc = continuous_noise(c, np.array([1e-6, 2e-6, 3e-6, 1e-9, 2e-9, 3e-9]), q, ni)
    return rows, cols, vals, nnz, qc, beta, q, ni


@pytest.mark.parametrize("dt", [0.005, 0.1, 1.0])
def test_van_loan_series_against_expm_and_fine_steps(dt):
    rows, cols, vals, nnz, qc, _, _, ni = _random_dynamics()
    f = dense_dynamics(rows, cols, vals, nnz, ni)
    phi, qd = van_loan_series(rows, cols, vals, nnz, qc, dt)
    # Van Loan 1978: expm([[-F, Q], [0, Fᵀ]] dt) = [[., Φ⁻¹ Qd], [0, Φᵀ]]
    m = np.zeros((2 * ni, 2 * ni))
    m[:ni, :ni], m[:ni, ni:], m[ni:, ni:] = -f, qc, f.T
    e = scipy.linalg.expm(m * dt)
    phi_ref = e[ni:, ni:].T
    qd_ref = phi_ref @ e[:ni, ni:]
    np.testing.assert_allclose(phi, phi_ref, rtol=0, atol=1e-13 * np.abs(phi_ref).max())
    np.testing.assert_allclose(qd, qd_ref, rtol=0, atol=1e-10 * np.abs(qd_ref).max())
    # fine-step RK4 of Φ̇ = FΦ, Ṗ = FP + PFᵀ + Q
    steps = 2000
    h = dt / steps
    p = np.zeros((ni, ni))
    ph = np.eye(ni)

    def dp(x):
        return f @ x + x @ f.T + qc

    for _ in range(steps):
        k1 = dp(p)
        k2 = dp(p + 0.5 * h * k1)
        k3 = dp(p + 0.5 * h * k2)
        k4 = dp(p + h * k3)
        p = p + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ph = ph + h * f @ (ph + 0.5 * h * f @ (ph + h / 3 * f @ (ph + 0.25 * h * f @ ph)))
    np.testing.assert_allclose(qd, p, rtol=0, atol=1e-9 * np.abs(p).max())
    np.testing.assert_allclose(phi, ph, rtol=0, atol=1e-11 * np.abs(ph).max())


def test_propagate_covariance_against_the_dense_product():
    rows, cols, vals, nnz, qc, beta, q, ni = _random_dynamics()
    dt = 0.1
    beta = beta.copy()
    q = q.copy()
    beta[LAYOUT.slice(B_GNSS_POS)] = 1 / 300.0
    q[LAYOUT.slice(B_GNSS_POS)] = 2 * 1.5**2 / 300.0
    q[LAYOUT.slice(B_BARO_BIAS)] = 0.0
    phi, qd = van_loan_series(rows, cols, vals, nnz, qc, dt)
    a = np.random.default_rng(5).normal(size=(N, N))
    p = a @ a.T + np.eye(N)
    full_phi = np.eye(N)
    full_phi[:ni, :ni] = phi
    full_qd = np.zeros((N, N))
    full_qd[:ni, :ni] = qd
    for i in range(ni, N):
        full_phi[i, i] = np.exp(-beta[i] * dt)
        full_qd[i, i] = (q[i] * (1 - np.exp(-2 * beta[i] * dt)) / (2 * beta[i]) if beta[i]
                         else q[i] * dt)  # fmt: skip
    ref = full_phi @ p @ full_phi.T + full_qd
    out = p.copy()
    propagate_covariance(out, phi, qd, beta, q, dt, ni)
    np.testing.assert_allclose(out, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())


# ---------------------------------------------------------------------------------------------
# update


def _hostile():
    """P with 20 orders of magnitude between states and strong correlations; a very precise
    measurement of a combination: the short form P - KHP loses positive definiteness."""
    rng = np.random.default_rng(2)
    n = 15
    scales = np.logspace(4, -8, n)
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    corr = q @ np.diag(np.linspace(1e-6, 2.0, n)) @ q.T
    d = np.sqrt(np.diag(corr))
    corr = corr / np.outer(d, d)
    p = corr * np.outer(scales, scales)
    h = np.zeros((2, n))
    h[0, 0], h[0, 14] = 1.0, 1e9
    h[1, 3], h[1, 8] = 1.0, -1e6
    r = np.diag([1e-14, 1e-16])
    return p, h, r


def test_joseph_update_matches_the_dense_form_and_stays_positive():
    p, h, r = _hostile()
    nu = np.array([1e-3, -2e-4])
    out = p.copy()
    dx, nis, ok = joseph_update(out, nu, h, r, np.inf)
    assert ok
    s = h @ p @ h.T + r
    k = p @ h.T @ np.linalg.inv(s)
    a = np.eye(len(p)) - k @ h
    ref = a @ p @ a.T + k @ r @ k.T
    np.testing.assert_allclose(dx, k @ nu, rtol=1e-6)
    np.testing.assert_allclose(nis, nu @ np.linalg.solve(s, nu), rtol=1e-9)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    np.testing.assert_array_equal(out, out.T)
    np.linalg.cholesky(out)  # positive definite
    # and the case is hostile: the short form is not
    short = p - k @ h @ p
    short = 0.5 * (short + short.T)
    assert np.linalg.eigvalsh(short).min() < 0.0


def test_gate_rejects_and_leaves_p():
    p = np.diag([4.0, 4.0, 9.0] + [1.0] * 12)
    h = np.zeros((3, 15))
    h[:, :3] = np.eye(3)
    out = p.copy()
    dx, nis, ok = joseph_update(out, np.array([100.0, 0, 0]), h, np.eye(3), 21.1)
    assert not ok and nis == pytest.approx(100.0**2 / 5.0)
    np.testing.assert_array_equal(out, p)
    np.testing.assert_array_equal(dx, 0.0)


def test_reset_jacobian_of_the_attitude_injection():
    """After Ĉ ← exp([dφ×]) Ĉ the error is φ' = log(exp([dφ×]) exp([φ×])); its Jacobian at the
    estimated error φ = -dφ is I + ½ [dφ×] to second order in dφ."""
    dphi = np.array([2e-3, -1e-3, 3e-3])

    def after(phi):
        return Rotation.from_matrix(_rot(dphi) @ _rot(phi)).as_rotvec()

    jac = np.array([(after(-dphi + 1e-7 * e) - after(-dphi - 1e-7 * e)) / 2e-7
                    for e in np.eye(3)]).T  # fmt: skip
    p = np.eye(12)
    p[6:9, 6:9] = np.diag([1.0, 2.0, 3.0])
    out = p.copy()
    reset_attitude(out, dphi)
    ref = p.copy()
    ref[6:9, 6:9] = jac @ p[6:9, 6:9] @ jac.T
    np.testing.assert_allclose(out, ref, atol=np.dot(dphi, dphi) * 10)
    np.testing.assert_allclose(out[6:9, 6:9], out[6:9, 6:9].T, atol=1e-15)


# ---------------------------------------------------------------------------------------------
# compiled fields against the vectorized ones


def test_scalar_fields_against_the_vectorized_ones(igrf):
    g, hc, a1, a2, d = igrf
    rng = np.random.default_rng(0)
    for _ in range(50):
        lat, lon = rng.uniform(-1.5, 1.5), rng.uniform(-3.1, 3.1)
        alt = rng.uniform(-500.0, 30000.0)
        r = geodetic_to_ecef(lat, lon, alt)
        la, lo, al = ecef_to_geodetic1(*r)
        assert abs(la - lat) < 2e-15 and abs(lo - lon) < 2e-15 and abs(al - alt) < 2e-8
        p, dp = icao_pressure1(alt)
        assert p == pytest.approx(float(icao_pressure(np.array([alt]))[0]), rel=1e-14)
        num = (icao_pressure(np.array([alt + 0.01])) - icao_pressure(np.array([alt - 0.01])))
        assert dp == pytest.approx(float(num[0]) / 0.02, rel=1e-7)
        b = np.array(igrf_ned1(*r, lat, g, hc, a1, a2, d, 6371200.0))
        ref = igrf_field_ned(r[None], np.array([lat]), g, hc)[0]
        np.testing.assert_allclose(b, ref, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# estimates of the Gauss–Markov states between updates


def test_gauss_markov_estimates_decay_as_their_covariance():
    """Between updates the estimate of a Gauss–Markov state is its conditional mean
    ``e^{-t/τ} x̂(0)``: the GNSS position/velocity, barometer drift and IMU Gauss–Markov
    estimates decay with their τ (the Φ the covariance uses), random constants hold."""
    from strapdown_ros.core.aided.engine import AidedFilter, FilterSetup
    from strapdown_ros.core.aided.model import SensorModels, build_model
    from strapdown_ros.core.aiding.baro import BaroErrors
    from strapdown_ros.core.aiding.gnss import GnssErrors
    from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors

    def triad(tau: float) -> SensorErrors:
        z = SensorErrors.zero()
        return SensorErrors(**{**{k: getattr(z, k) for k in z.__dataclass_fields__},
                               "turn_on_bias_sigma": np.full(3, 1e-4),
                               "bias_instability": np.full(3, 1e-5),
                               "correlation_time_s": np.full(3, tau)})  # fmt: skip

    tau_p, tau_v, tau_d, tau_g, tau_a = 7.0, 3.0, 11.0, 13.0, 17.0
    gnss = GnssErrors(position_white=np.ones(3), position_gm_sigma=np.ones(3),
                      position_gm_tau_s=np.full(3, tau_p), velocity_white=np.ones(3),
                      velocity_gm_sigma=np.ones(3), velocity_gm_tau_s=np.full(3, tau_v))
    baro = BaroErrors(turn_on_bias_sigma=10.0, drift_sigma=5.0, drift_tau_s=tau_d)
    model = build_model(ImuErrorParameters(triad(tau_g), triad(tau_a), 0), 0.01,
                        SensorModels(gnss=gnss, baro=baro))  # fmt: skip
    lay = model.layout
    r0 = geodetic_to_ecef(np.array([0.7]), np.array([0.1]), np.array([100.0]))[0]
    filt = AidedFilter(model, FilterSetup(period_ns=10_000_000, start_cycle=0,
                                          grid_periods=(10, 7)), r0, np.zeros(3), np.eye(3),
                       np.eye(lay.n))  # fmt: skip
    filt.est[9:] = np.linspace(0.5, 1.5, lay.n - 9)
    x0 = filt.est.copy()
    cycles = 1000  # 10 s, covariance steps of 0.1 s and 0.07 s
    filt.add_imu(np.zeros((cycles, 3)), np.zeros((cycles, 3)))
    filt.advance(cycles)
    t = cycles * 0.01
    expect = x0.copy()
    for block, tau in ((B_GNSS_POS, tau_p), (B_GNSS_VEL, tau_v), (B_BARO_DRIFT, tau_d),
                       (B_GMG, tau_g), (B_GMA, tau_a)):  # fmt: skip
        expect[lay.slice(block)] *= np.exp(-t / tau)
    np.testing.assert_allclose(filt.est[9:], expect[9:], rtol=1e-12)
    for block in (B_BG, B_BA, B_BARO_BIAS):
        assert np.array_equal(filt.est[lay.slice(block)], x0[lay.slice(block)])


# ---------------------------------------------------------------------------------------------
# the wheel encoder's quantization residuals


def test_carry_quantization_moves_the_next_residual_to_the_last():
    """After a wheel update ρ_next becomes ρ_last with all its correlations, and a fresh
    ρ_next starts uncorrelated: ``P' = S P Sᵀ + v e eᵀ`` with S the shift (row k ← row k+1,
    row k+1 ← 0), written here as a matrix product."""
    from strapdown_ros.core.aided.update import carry_quantization

    rng = np.random.default_rng(3)
    n, k, var = 14, 11, 0.0042
    a = rng.normal(size=(n, n))
    p = a @ a.T
    est = rng.normal(size=n)
    s = np.eye(n)
    s[k] = 0.0
    s[k, k + 1] = 1.0
    s[k + 1] = 0.0
    e = np.zeros(n)
    e[k + 1] = 1.0
    expect_p = s @ p @ s.T + var * np.outer(e, e)
    expect_est = s @ est
    carry_quantization(est, p, k, var)
    np.testing.assert_array_equal(p, expect_p)
    np.testing.assert_array_equal(est, expect_est)


def test_quantization_states_of_an_encoder():
    """An encoder (pulses_per_m > 0) adds the two residual states with σ0 = (q/P)/√12 each,
    (q = 1/pulses_per_m, P the wheel period); none without quantization or with the sensor
    error states off; a missing wheel period is refused."""
    from strapdown_ros.core.aided.model import SensorModels, StateOptions, build_model
    from strapdown_ros.core.aiding.odometer import OdometerErrors
    from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors

    imu = ImuErrorParameters(SensorErrors.zero(), SensorErrors.zero(), 0)
    wheel = OdometerErrors(white=0.02, pulses_per_m=48.0)
    model = build_model(imu, 0.01, SensorModels(wheel=wheel, wheel_period_s=0.1))
    lay = model.layout
    np.testing.assert_allclose(model.sigma0[lay.slice(B_WHEEL_QUANT)],
                               (1 / 48.0 / 0.1) / np.sqrt(12.0), rtol=1e-15)  # fmt: skip
    assert lay.names()[-2:] == ["wheel_quantization_last", "wheel_quantization_next"]
    assert model.beta[lay.slice(B_WHEEL_QUANT)].tolist() == [0.0, 0.0]
    assert model.q[lay.slice(B_WHEEL_QUANT)].tolist() == [0.0, 0.0]
    for sensors, options in ((SensorModels(wheel=OdometerErrors(white=0.02)), StateOptions()),
                             (SensorModels(wheel=wheel, wheel_period_s=0.1),
                              StateOptions(sensor_errors=False))):  # fmt: skip
        assert not build_model(imu, 0.01, sensors, options).layout.has(B_WHEEL_QUANT)
    with pytest.raises(ValueError, match="wheel_period_s"):
        build_model(imu, 0.01, SensorModels(wheel=wheel))
