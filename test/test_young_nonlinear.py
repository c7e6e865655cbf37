"""Young 1980's derivation checked numerically: operators (8)/(9), frames (25)–(27), rates (39),
(47), (50), the nonlinear equations (51) against two independently integrated rotating frames,
the H form against the Euler form, and the small-angle limit against the phi-angle model."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from strapdown_ros.core import young
from strapdown_ros.core import young_nonlinear as yn
from strapdown_ros.core.earth import OMEGA_IE, dcm_ecef_to_ned
from strapdown_ros.core.rotations import dcm_from_rotvec, skew


def central_difference(f, t, h=1e-4):
    return (f(t + h) - f(t - h)) / (2 * h)


def test_eq8_operator_of_a_rotating_frame():
    """W^T Ẇ of a frame turning at α about a fixed axis is Young's operator of α (eq. (8)),
    and eq. (9) recovers α from W and Ẇ."""
    rng = np.random.default_rng(10)
    for _ in range(10):
        alpha = rng.normal(size=3)  # rad/s, in Σ_a axes
        c0 = dcm_from_rotvec(rng.normal(size=3))

        def w(t, alpha=alpha, c0=c0):  # v^b = W v^a; Σ_b turns at α relative to Σ_a
            return (dcm_from_rotvec(alpha * t) @ c0).T

        t = rng.uniform(0, 2)
        a = w(t).T @ central_difference(w, t)
        np.testing.assert_allclose(a, young.young_operator(alpha), atol=1e-8)
        np.testing.assert_allclose(a, -skew(alpha), atol=1e-8)
        np.testing.assert_allclose(young.young_operator_vector(a), alpha, atol=1e-8)


def test_eq25_27_frames():
    rng = np.random.default_rng(11)
    lat, lon = rng.uniform(-1.5, 1.5, 20), rng.uniform(-3, 3, 20)
    f = young.earth_to_platform_dcm(lat, lon)
    np.testing.assert_allclose(f, young.C_NED_TO_UEN @ dcm_ecef_to_ned(lat, lon), atol=1e-15)
    # rows: up (ellipsoid normal), east, north
    np.testing.assert_allclose(f[:, 0, 2], np.sin(lat), atol=1e-15)
    e = young.earth_rotation_dcm(1000.0)
    np.testing.assert_allclose(e, dcm_from_rotvec([0, 0, OMEGA_IE * 1000.0]).T, atol=1e-15)


def test_eq39_rate_of_a_moving_local_level_frame():
    """Ψ^P = Ḟ Fᵀ + F Ė Eᵀ Fᵀ (eq. (37)) from finite differences equals eq. (39)."""

    def path(t):
        return 0.8 + 1e-3 * np.sin(0.01 * t), 0.3 + 2e-3 * t, 1e-5 * np.cos(0.01 * t), 2e-3

    def w(t):
        lat, lon, _, _ = path(t)
        return young.earth_to_platform_dcm(lat, lon) @ young.earth_rotation_dcm(t)

    for t in (0.0, 37.0, 500.0):
        psi = young.young_operator_vector(central_difference(w, t, 1e-3) @ w(t).T)
        lat, _, lat_rate, lon_rate = path(t)
        np.testing.assert_allclose(psi, young.frame_rates(lat, lat_rate, lon_rate), atol=1e-11)


def test_eq51_is_eq31_of_eq50():
    rng = np.random.default_rng(12)
    theta = rng.uniform([-3, -1.3, -3], [3, 1.3, 3], size=(500, 3))
    delta, psi = rng.normal(size=(2, 500, 3))
    via_gamma = young.young_rates(theta, young.relative_rates(theta, delta, psi))
    np.testing.assert_allclose(young.young_angle_rates(theta, delta, psi), via_gamma, atol=1e-12)


# An analytic run: true and indicated latitude/longitude, and a gyro error d^P(t) (rad/s, Σ_P).
def true_path(t):
    return 0.84 + 2e-4 * np.sin(1.2e-3 * t), 0.2 + 1e-5 * t


def indicated_path(t):
    return 0.84 + 0.01 * np.sin(1.24e-3 * t + 0.3), 0.2 + 1e-5 * t + 0.02 * np.sin(8e-4 * t)


def rates(path, t, h=1e-2):
    lat_p, lon_p = path(t + h)
    lat_m, lon_m = path(t - h)
    return (lat_p - lat_m) / (2 * h), (lon_p - lon_m) / (2 * h)


def drift_p(t):
    return 1e-5 * np.array([np.cos(1e-3 * t), 0.5, np.sin(2e-3 * t)])


def drift_angle(t):
    """∫_0^t drift_p."""
    return 1e-5 * np.stack([np.sin(1e-3 * t) / 1e-3, 0.5 * t, (1 - np.cos(2e-3 * t)) / 2e-3], -1)


def analytic_inputs(t):
    tracks = []
    for path in (true_path, indicated_path):
        lat, lon = path(t)
        tracks.append(yn.FrameTrack(t, lat, lon, *rates(path, t)))
    fine = np.arange(t[0], t[-1] + 0.5, 1.0)
    return yn.OrientationInputs(*tracks, fine, drift_angle(fine), interpolation="hermite")


def independent_frames(theta0, t_eval):
    """Σ_M integrated in inertial axes: Ċ_I^M = -(δ^M×) C_I^M with δ^M = eq. (47)'s commanded
    rates at the indicated position plus ε^M = -H d^P; H = C_I^M (C_I^P)ᵀ, C_I^P = F E."""

    def c_i_p(t):
        return young.earth_to_platform_dcm(*true_path(t)) @ young.earth_rotation_dcm(t)

    def rhs(t, y):
        c = y.reshape(3, 3)
        lat_s, _ = indicated_path(t)
        dlat, dlon = rates(indicated_path, t)
        h = c @ c_i_p(t).T
        delta = young.frame_rates(lat_s, dlat, dlon) - h @ drift_p(t)
        return (-skew(delta) @ c).ravel()

    c0 = young.young_dcm(theta0) @ c_i_p(t_eval[0])
    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), c0.ravel(), "DOP853", t_eval=t_eval,
                    rtol=1e-13, atol=1e-15)  # fmt: skip
    h = sol.y.T.reshape(-1, 3, 3) @ np.array([c_i_p(t).T for t in t_eval])
    return young.young_angles_from_dcm(h)


@pytest.mark.parametrize("theta0", [(0.0, 0.0, 0.0), (2.97, 0.17, -0.17), (-1.2, 0.6, 2.5)])
def test_eq51_against_two_rotating_frames(theta0):
    """Eq. (51) (and the H form) reproduce the Euler angles between Σ_P (true position) and a
    Σ_M integrated independently in inertial axes: 5e-10 rad over 2 h with inputs every 2.5 s
    and rtol 1e-13 (measured 5.4e-11; inputs every 10 s: 1e-9, the Hermite interpolation)."""
    t = np.linspace(0.0, 7200.0, 721)
    inputs = analytic_inputs(np.linspace(0.0, 7200.0, 2881))
    expected = independent_frames(np.array(theta0), t)
    for method in ("young", "young_dcm"):
        got = yn.integrate_orientation(inputs, theta0, t, method=method, rtol=1e-13, atol=1e-15)
        err = np.max(np.abs(yn.wrap_angle(got.theta - expected)))
        assert err < 5e-10, (method, err)
    change = np.max(np.abs(yn.wrap_angle(expected - expected[0])))
    assert change > 0.01  # the angles do move


def test_small_angle_limit_is_phi_angle_model():
    """Eq. (51) minus the phi-angle rates is second order: it shrinks as s² when θ, δω_in and
    the drift all scale with s."""
    rng = np.random.default_rng(13)
    psi = OMEGA_IE * np.array([0.74, -0.1, 0.67])
    theta_u, dw_u, d_u = rng.normal(size=(3, 200, 3))
    diffs = []
    for s in (1e-3, 1e-4):
        theta, delta0, d = s * theta_u, psi + OMEGA_IE * s * dw_u, OMEGA_IE * s * d_u
        delta = delta0 - np.einsum("nij,nj->ni", young.young_dcm(theta), d)
        exact = young.young_angle_rates(theta, delta, psi)
        linear = yn.phi_angle_rates(theta, delta0, psi, d)
        first = np.max(np.abs(linear - yn.phi_angle_rates(0 * theta, psi, psi, 0 * d)))
        diffs.append(np.max(np.abs(exact - linear)))
        assert diffs[-1] < 1e-2 * first  # the linear terms carry almost everything
    assert 50 < diffs[0] / diffs[1] < 200  # second order: 10x smaller s, 100x smaller diff


def test_inputs_are_checked():
    t = np.arange(5.0)
    track = yn.FrameTrack(t, 0.8 + 0 * t, 0 * t, 0 * t, 0 * t)
    with pytest.raises(ValueError, match="strictly increasing"):
        yn.FrameTrack(t[::-1], t, t, t, t)
    with pytest.raises(ValueError, match="non-finite"):
        yn.FrameTrack(t, t * np.nan, t, t, t)
    with pytest.raises(ValueError, match="both"):
        yn.OrientationInputs(track, track, t, None)
    with pytest.raises(ValueError, match="outside"):
        yn.integrate_orientation(yn.OrientationInputs(track, track), (0, 0, 0), [0.0, 10.0])
    with pytest.raises(ValueError, match="interpolation"):
        yn.integrate_orientation(yn.OrientationInputs(track, track, interpolation="linear"),
                                 (0, 0, 0))  # fmt: skip
    with pytest.raises(ValueError, match="method"):
        yn.integrate_orientation(yn.OrientationInputs(track, track), (0, 0, 0), method="euler")
