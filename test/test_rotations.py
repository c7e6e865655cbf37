"""Rotations: round trips at random and edge angles, cross-checked with scipy and mpmath."""

import mpmath as mp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strapdown_ros.core import rotations as rot

EDGE_ANGLES = [0.0, 1e-300, 1e-9, 1e-4, 1.0, np.pi / 2, np.pi - 1e-9, np.pi]


def random_axes(n: int, rng: np.random.Generator) -> np.ndarray:
    a = rng.normal(size=(n, 3))
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def edge_rotvecs(rng: np.random.Generator) -> np.ndarray:
    axes = np.vstack([np.eye(3), -np.eye(3), random_axes(20, rng)])
    return np.array([a * ang for ang in EDGE_ANGLES for a in axes])


def test_skew_and_vee():
    rng = np.random.default_rng(1)
    v, w = rng.normal(size=(2, 50, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", rot.skew(v), w), np.cross(v, w), atol=1e-15)
    np.testing.assert_array_equal(rot.vee(rot.skew(v)), v)
    with pytest.raises(ValueError, match="3-vectors"):
        rot.skew(np.zeros(4))


def test_dcm_from_rotvec_matches_scipy_and_mpmath():
    rng = np.random.default_rng(2)
    phi = np.vstack([edge_rotvecs(rng), rng.normal(size=(500, 3)) * 2.0])
    c = rot.dcm_from_rotvec(phi)
    np.testing.assert_allclose(c, Rotation.from_rotvec(phi).as_matrix(), atol=4e-16)
    # Orthonormal to rounding: < 1e-15 for increment-sized angles (<= 1 rad), a few eps beyond
    # (scipy's own matrices reach 1.3e-15 near pi).
    angle = np.linalg.norm(phi, axis=1)
    assert np.max(rot.orthonormality_error(c[angle <= 1.0])) < 1e-15
    assert np.max(rot.orthonormality_error(c[angle <= np.pi])) < 3e-15
    assert np.max(rot.orthonormality_error(c)) < 5e-15  # |phi| up to ~10 rad
    # mpmath Rodrigues formula for a few vectors
    for p in phi[::37]:
        pm = mp.matrix([mp.mpf(float(x)) for x in p])
        ang = mp.sqrt(sum(x * x for x in pm))
        k = mp.matrix([[0, -pm[2], pm[1]], [pm[2], 0, -pm[0]], [-pm[1], pm[0], 0]])
        ref = (
            mp.eye(3)
            if ang == 0
            else (mp.eye(3) + mp.sin(ang) / ang * k + (1 - mp.cos(ang)) / ang**2 * k * k)
        )
        got = rot.dcm_from_rotvec(p)
        err = max(abs(float(ref[i, j]) - got[i, j]) for i in range(3) for j in range(3))
        assert err < 8e-16  # <= 4 ulp of elements of size <= 1 (angles beyond pi are wrapped)


def test_rotvec_round_trip_at_edge_angles():
    rng = np.random.default_rng(3)
    phi = edge_rotvecs(rng)
    back = rot.rotvec_from_dcm(rot.dcm_from_rotvec(phi))
    angle = np.linalg.norm(phi, axis=1)
    at_pi = np.isclose(angle, np.pi, rtol=0, atol=1e-12)
    # Away from pi the rotation vector is unique; relative accuracy a few eps.
    err = np.linalg.norm(back - phi, axis=1)
    assert np.all(err[~at_pi] <= 4e-16 * np.maximum(angle[~at_pi], 1e-300) + 4e-16 * angle[~at_pi])
    # At (and 1e-9 below) pi: phi and -phi describe nearly the same rotation; compare DCMs and
    # the angle.
    np.testing.assert_allclose(
        rot.dcm_from_rotvec(back[at_pi]), rot.dcm_from_rotvec(phi[at_pi]), atol=5e-16
    )
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), angle, rtol=0, atol=2e-15)


def test_rotvec_near_pi_keeps_axis_sign():
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    phi = axis * (np.pi - 1e-9)
    np.testing.assert_allclose(rot.rotvec_from_dcm(rot.dcm_from_rotvec(phi)), phi, atol=2e-15)


def test_rotvec_random_round_trip_and_scipy():
    rng = np.random.default_rng(4)
    phi = random_axes(2000, rng) * rng.uniform(0, np.pi - 1e-6, size=(2000, 1))
    c = rot.dcm_from_rotvec(phi)
    np.testing.assert_allclose(rot.rotvec_from_dcm(c), phi, atol=3e-15)
    np.testing.assert_allclose(
        rot.rotvec_from_dcm(c), Rotation.from_matrix(c).as_rotvec(), atol=3e-15
    )


def test_quaternion_round_trips_and_product():
    rng = np.random.default_rng(5)
    phi = np.vstack([edge_rotvecs(rng), rng.normal(size=(300, 3))])
    q = rot.quat_from_rotvec(phi)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=3e-16)
    np.testing.assert_allclose(rot.dcm_from_quat(q), rot.dcm_from_rotvec(phi), atol=5e-16)
    qc = rot.quat_from_dcm(rot.dcm_from_quat(q))
    np.testing.assert_allclose(qc, rot.quat_normalize(q), atol=5e-16)
    # scipy is scalar-last (reordered: as_quat(scalar_first=) is scipy >= 1.14, noble has 1.11)
    np.testing.assert_allclose(
        rot.quat_normalize(q),
        rot.quat_normalize(Rotation.from_rotvec(phi).as_quat()[:, [3, 0, 1, 2]]),
        atol=5e-16,
    )
    a, b = rng.normal(size=(2, 100, 3))
    qa, qb = rot.quat_from_rotvec(a), rot.quat_from_rotvec(b)
    np.testing.assert_allclose(
        rot.dcm_from_quat(rot.quat_multiply(qa, qb)),
        rot.dcm_from_rotvec(a) @ rot.dcm_from_rotvec(b),
        atol=2e-15,
    )
    np.testing.assert_allclose(
        rot.quat_multiply(qa, rot.quat_conjugate(qa)), np.tile([1, 0, 0, 0], (100, 1)), atol=3e-16
    )


def test_elementary_rotations_are_rotvec_dcms():
    for ang in [0.0, 0.3, -2.0, np.pi]:
        np.testing.assert_allclose(rot.rot_x(ang), rot.dcm_from_rotvec([ang, 0, 0]), atol=3e-16)
        np.testing.assert_allclose(rot.rot_y(ang), rot.dcm_from_rotvec([0, ang, 0]), atol=3e-16)
        np.testing.assert_allclose(rot.rot_z(ang), rot.dcm_from_rotvec([0, 0, ang]), atol=3e-16)


def test_euler_convention_and_round_trip():
    # heading 90 deg: body x (forward) points east
    c = rot.dcm_from_euler(0.0, 0.0, np.pi / 2)
    np.testing.assert_allclose(c @ [1, 0, 0], [0, 1, 0], atol=1e-16)
    # pitch 30 deg nose up: forward axis has negative down component
    c = rot.dcm_from_euler(0.0, np.radians(30), 0.0)
    np.testing.assert_allclose(c @ [1, 0, 0], [np.cos(np.radians(30)), 0, -0.5], atol=1e-16)
    # roll 90 deg right wing down: body y (right) points down
    c = rot.dcm_from_euler(np.pi / 2, 0.0, 0.0)
    np.testing.assert_allclose(c @ [0, 1, 0], [0, 0, 1], atol=1e-16)
    # against scipy intrinsic ZYX
    rng = np.random.default_rng(6)
    n = 1000
    rph = np.column_stack(
        [rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-np.pi, np.pi, n)]
    )
    c = rot.dcm_from_euler(rph[:, 0], rph[:, 1], rph[:, 2])
    np.testing.assert_allclose(c, Rotation.from_euler("ZYX", rph[:, ::-1]).as_matrix(), atol=5e-16)
    back = np.column_stack(rot.euler_from_dcm(c))
    np.testing.assert_allclose(back, rph, atol=5e-15)


def test_euler_at_gimbal_lock_reproduces_dcm():
    for pitch in (np.pi / 2, -np.pi / 2):
        c = rot.dcm_from_euler(0.4, pitch, 1.1)
        r, p, h = rot.euler_from_dcm(c)
        np.testing.assert_allclose(rot.dcm_from_euler(r, p, h), c, atol=1e-15)


def test_frame_conversions_are_exact():
    rng = np.random.default_rng(7)
    v = rng.normal(size=(10, 3))
    np.testing.assert_array_equal(rot.enu_to_ned(rot.ned_to_enu(v)), v)
    np.testing.assert_array_equal(rot.flu_to_frd(rot.frd_to_flu(v)), v)
    np.testing.assert_array_equal(rot.ned_to_enu([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_array_equal(rot.frd_to_flu([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])
    c = rot.dcm_from_rotvec(rng.normal(size=(10, 3)))
    # C_FLU^ENU v^FLU == ENU of (C_FRD^NED v^FRD)
    lhs = np.einsum("nij,nj->ni", rot.dcm_to_flu_enu(c), rot.frd_to_flu(v))
    rhs = rot.ned_to_enu(np.einsum("nij,nj->ni", c, v))
    np.testing.assert_allclose(lhs, rhs, atol=1e-15)
    np.testing.assert_array_equal(rot.dcm_to_frd_ned(rot.dcm_to_flu_enu(c)), c)
    # Level, north-facing FRD body is FLU body facing north in ENU: yaw 90 deg from east.
    q = Rotation.from_matrix(rot.dcm_to_flu_enu(np.eye(3)))
    np.testing.assert_allclose(q.as_euler("ZYX")[0], np.pi / 2, atol=1e-15)
