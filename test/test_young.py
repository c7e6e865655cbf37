"""Young 1980 eqs. (28), (30), (31): error angles checked against independent constructions."""

import numpy as np

from strapdown_ros.core import young
from strapdown_ros.core.rotations import dcm_from_rotvec, rot_x, rot_y, rot_z, rotvec_from_dcm


def passive_h(theta):
    """H of eq. (28) as the product of passive elementary rotations R3(θ3) R2(θ2) R1(θ1)."""
    return rot_z(theta[2]).T @ rot_y(theta[1]).T @ rot_x(theta[0]).T


def test_eq28_matrix_is_the_rotation_sequence():
    rng = np.random.default_rng(0)
    for theta in rng.uniform(-3, 3, size=(50, 3)):
        np.testing.assert_allclose(young.young_dcm(theta), passive_h(theta), atol=1e-15)


def test_angles_round_trip_small_and_large():
    rng = np.random.default_rng(1)
    theta = np.vstack(
        [
            rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(1000, 3)),
            rng.normal(size=(100, 3)) * 1e-9,
            np.zeros((1, 3)),
        ]
    )
    back = young.young_angles_from_dcm(young.young_dcm(theta))
    np.testing.assert_allclose(back, theta, rtol=0, atol=5e-15)
    small = young.young_angles_from_dcm(young.young_dcm(theta[1000:]))
    np.testing.assert_allclose(small, theta[1000:], rtol=1e-12, atol=1e-24)


def random_truth(rng, n):
    return dcm_from_rotvec(rng.normal(size=(n, 3)))


def computed_attitude(theta, c_true):
    """C_B^N(computed) whose local level is the true one rotated by H(θ) (UEN axes)."""
    u = young.C_NED_TO_UEN
    return u.T @ young.young_dcm(theta) @ u @ c_true


def test_error_angles_recover_large_errors_by_direct_decomposition():
    rng = np.random.default_rng(2)
    theta = rng.uniform([-np.pi, -1.4, -np.pi], [np.pi, 1.4, np.pi], size=(200, 3))
    c_true = random_truth(rng, 200)
    got = young.young_error_angles(computed_attitude(theta, c_true), c_true)
    np.testing.assert_allclose(got, theta, atol=5e-14)


def test_small_errors_equal_error_rotation_vector_to_second_order():
    rng = np.random.default_rng(3)
    c_true = random_truth(rng, 100)
    ratios = []
    for size in (1e-3, 1e-5):
        # the computed local level is the true one rotated by rotation vector psi (UEN axes)
        psi = rng.normal(size=(100, 3)) * size
        u = young.C_NED_TO_UEN
        c_comp = u.T @ np.swapaxes(dcm_from_rotvec(psi), -1, -2) @ u @ c_true
        theta = young.young_error_angles(c_comp, c_true)
        diff = np.linalg.norm(theta - psi, axis=1)
        ratio = np.max(diff / np.linalg.norm(psi, axis=1) ** 2)
        ratios.append(ratio)
        assert ratio < 1.0  # second-order agreement: |θ - ψ| < |ψ|²
        assert np.max(np.linalg.norm(theta, axis=1)) > 0.5 * size  # not trivially zero
    # The difference is genuinely second order: it shrinks with the square of the size.
    assert 0.2 < ratios[0] / ratios[1] < 5
    # and in UEN axes the error angles are the rotation vector of H^T to the same order
    h = young.young_dcm(theta)
    phi = rotvec_from_dcm(np.swapaxes(h, -1, -2))
    assert np.all(np.linalg.norm(phi - theta, axis=1) < np.linalg.norm(theta, axis=1) ** 2)


def test_eq30_rates_from_numerical_derivative_and_eq31_inverse():
    rng = np.random.default_rng(4)
    for _ in range(20):
        theta = rng.uniform([-3, -1.2, -3], [3, 1.2, 3])
        rate = rng.normal(size=3)
        h_step = 1e-6
        hp = young.young_dcm(theta + rate * h_step)
        hm = young.young_dcm(theta - rate * h_step)
        h_dot = (hp - hm) / (2 * h_step)
        gamma_op = young.young_dcm(theta).T @ h_dot  # eq. (29): Γ^P = Hᵀ Ḣ
        # Γ is skew; Young's γ are its elements with the sign convention of eq. (30)
        gamma = np.array([gamma_op[1, 2], gamma_op[2, 0], gamma_op[0, 1]])
        np.testing.assert_allclose(young.young_platform_rates(theta, rate), gamma, atol=1e-8)
        np.testing.assert_allclose(young.young_rates(theta, gamma), rate, atol=1e-8)
