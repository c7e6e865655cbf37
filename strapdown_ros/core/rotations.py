"""Rotations: skew matrices, rotation vectors, direction cosine matrices, quaternions, Euler angles.

Conventions (used throughout the core):

* A direction cosine matrix (DCM) ``C_A^B`` maps coordinates in frame A to frame B:
  ``v^B = C_A^B v^A``. Arrays have shape ``(..., 3, 3)`` and broadcast over leading axes.
* A rotation vector ``φ`` (rad, shape ``(..., 3)``) describes the DCM
  ``C = I + f1(φ) (φ×) + f2(φ) (φ×)²`` (Savage 2020 eq. (2), the G_C form), i.e. frame B is
  obtained from frame A by a right-handed rotation of ``|φ|`` about ``φ``; ``C_B^A = C(φ)``.
* Quaternions are Hamilton, scalar first ``q = [w, x, y, z]``; ``q = [cos(θ/2), u sin(θ/2)]``
  is the same rotation as the rotation vector ``θ u``. (ROS messages are scalar last; the
  conversion happens in the message layer.)
* Euler angles ``roll, pitch, heading`` (rad) are those of the body FRD frame relative to the
  local-level NED frame: ``C_B^N = Rz(heading) Ry(pitch) Rx(roll)``.
* Local level is NED and body frames are FRD inside the core. ROS messages use ENU and FLU
  (REP-103); :data:`C_NED_TO_ENU` and :data:`C_FRD_TO_FLU` convert exactly.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.series import f1, f2

__all__ = [
    "C_FRD_TO_FLU",
    "C_NED_TO_ENU",
    "as_matrices",
    "as_vectors",
    "dcm_from_euler",
    "dcm_from_quat",
    "dcm_from_rotvec",
    "dcm_to_flu_enu",
    "dcm_to_frd_ned",
    "euler_from_dcm",
    "frd_to_flu",
    "flu_to_frd",
    "ned_to_enu",
    "enu_to_ned",
    "orthonormality_error",
    "quat_conjugate",
    "quat_from_dcm",
    "quat_from_rotvec",
    "quat_multiply",
    "quat_normalize",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_angle",
    "rotvec_from_dcm",
    "rotvec_from_quat",
    "skew",
    "vee",
]

#: ENU coordinates from NED coordinates, ``v^ENU = C_NED_TO_ENU v^NED`` (exact, self-inverse).
C_NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
C_NED_TO_ENU.setflags(write=False)

#: FLU coordinates from FRD coordinates, ``v^FLU = C_FRD_TO_FLU v^FRD`` (exact, self-inverse).
C_FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])
C_FRD_TO_FLU.setflags(write=False)


def as_vectors(v: ArrayLike) -> NDArray[np.float64]:
    """``v`` as a float64 array of 3-vectors (..., 3); ValueError for another shape."""
    v = np.asarray(v, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise ValueError(f"expected an array of 3-vectors (..., 3), got shape {v.shape}")
    return v


def as_matrices(c: ArrayLike) -> NDArray[np.float64]:
    """``c`` as a float64 array of 3x3 matrices (..., 3, 3); ValueError for another shape."""
    c = np.asarray(c, dtype=np.float64)
    if c.shape[-2:] != (3, 3):
        raise ValueError(f"expected an array of 3x3 matrices (..., 3, 3), got shape {c.shape}")
    return c


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """Skew-symmetric cross-product matrix ``(v×)`` with ``(v×) w = v × w``.

    Parameters
    ----------
    v : array (..., 3)
        Vector in any frame, any unit.

    Returns
    -------
    array (..., 3, 3)
        ``(v×)`` in the same frame (Savage 2020 notation ``(Δα×)``, eqs. (2)-(4)).
    """
    v = as_vectors(v)
    out = np.zeros(v.shape + (3,))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def vee(m: ArrayLike) -> NDArray[np.float64]:
    """Vector of the skew-symmetric part of ``m``: inverse of :func:`skew` (``vee(skew(v)) = v``).

    Parameters
    ----------
    m : array (..., 3, 3)

    Returns
    -------
    array (..., 3)
        ``½ [m32 - m23, m13 - m31, m21 - m12]``.
    """
    m = as_matrices(m)
    return 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
        axis=-1,
    )


def _skew_terms(phi: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(φ×)`` and ``(φ×)² = φ φᵀ - |φ|² I`` for an array of vectors."""
    k = skew(phi)
    k2 = phi[..., :, None] * phi[..., None, :] - np.einsum("...i,...i", phi, phi)[
        ..., None, None
    ] * np.eye(3)
    return k, k2


def dcm_from_rotvec(phi: ArrayLike) -> NDArray[np.float64]:
    """DCM of a rotation vector: ``I + sin φ/φ (φ×) + (1 - cos φ)/φ² (φ×)²``.

    This is Savage 2020 eq. (2), ``G_C(Δα)``, exact at every angle (series near 0).

    Parameters
    ----------
    phi : array (..., 3)
        Rotation vector (rad). For a body rotating from frame B_{m-1} to B_m it gives
        ``C_{B_m}^{B_{m-1}}``.

    Returns
    -------
    array (..., 3, 3)
    """
    phi = as_vectors(phi)
    angle = np.linalg.norm(phi, axis=-1)
    turns = np.round(angle / (2.0 * np.pi))
    if np.any(turns):  # same rotation with the angle in [-π, π]: better conditioned
        scale = 1.0 - 2.0 * np.pi * turns / np.where(turns > 0, angle, 1.0)
        phi = phi * scale[..., None]
        angle = np.abs(angle * scale)
    k, k2 = _skew_terms(phi)
    return np.eye(3) + f1(angle)[..., None, None] * k + f2(angle)[..., None, None] * k2


def quat_from_rotvec(phi: ArrayLike) -> NDArray[np.float64]:
    """Quaternion ``[cos(φ/2), sin(φ/2) φ/|φ|]`` of a rotation vector (rad), scalar first."""
    phi = as_vectors(phi)
    half = 0.5 * np.linalg.norm(phi, axis=-1)
    # sin(h)/(2h) * phi with h = |phi|/2, exact near zero through f1.
    return np.concatenate([np.cos(half)[..., None], (0.5 * f1(half))[..., None] * phi], axis=-1)


def quat_normalize(q: ArrayLike) -> NDArray[np.float64]:
    """Quaternion scaled to unit norm with a non-negative scalar part (canonical sign)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_conjugate(q: ArrayLike) -> NDArray[np.float64]:
    """Conjugate ``[w, -x, -y, -z]``: the inverse rotation of a unit quaternion."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_multiply(p: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``p ⊗ q``; ``q_A^C = q_B^C ⊗ q_A^B`` matches ``C_A^C = C_B^C C_A^B``."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def dcm_from_quat(q: ArrayLike) -> NDArray[np.float64]:
    """DCM of a quaternion (normalized first), same rotation as :func:`dcm_from_rotvec`."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = w * w + x * x - y * y - z * z
    out[..., 1, 1] = w * w - x * x + y * y - z * z
    out[..., 2, 2] = w * w - x * x - y * y + z * z
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 1] = 2 * (y * z + w * x)
    return out


def quat_from_dcm(c: ArrayLike) -> NDArray[np.float64]:
    """Quaternion of a DCM by Shepperd's method (largest pivot), canonical sign ``w >= 0``.

    Accurate to a few ε at every angle including 180°, where the trace method fails. The four
    products ``4 q_i q_j`` of the pivot's row are selected element-wise (no 4x4 table).
    """
    c = as_matrices(c)
    c00, c01, c02 = c[..., 0, 0], c[..., 0, 1], c[..., 0, 2]
    c10, c11, c12 = c[..., 1, 0], c[..., 1, 1], c[..., 1, 2]
    c20, c21, c22 = c[..., 2, 0], c[..., 2, 1], c[..., 2, 2]
    tr = c00 + c11 + c22
    pivot = np.argmax(np.stack([tr, c00, c11, c22], axis=-1), axis=-1)
    d01, d02, d03 = c21 - c12, c02 - c20, c10 - c01
    s12, s13, s23 = c10 + c01, c02 + c20, c21 + c12
    q = np.empty(c.shape[:-2] + (4,))
    np.choose(pivot, [1 + tr, d01, d02, d03], out=q[..., 0])
    np.choose(pivot, [d01, 1 + 2 * c00 - tr, s12, s13], out=q[..., 1])
    np.choose(pivot, [d02, s12, 1 + 2 * c11 - tr, s23], out=q[..., 2])
    np.choose(pivot, [d03, s13, s23, 1 + 2 * c22 - tr], out=q[..., 3])
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    np.negative(q, out=q, where=q[..., :1] < 0.0)
    return q


def rotvec_from_quat(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector (rad, angle in [0, π]) of a quaternion; exact near 0 and at π.

    ``φ = 2 atan2(|q_v|, w) q_v / |q_v|`` with ``w >= 0``; near zero the factor
    ``2 atan(t)/t / w`` (t = |q_v|/w) is evaluated from its series.
    """
    q = quat_normalize(q)
    w = q[..., 0]
    qv = q[..., 1:]
    n = np.linalg.norm(qv, axis=-1)
    small = n < 1e-4 * np.maximum(w, 1e-300)
    t = np.where(small, n / np.where(small, w, 1.0), 0.0)
    t2 = t * t
    series = (2.0 / np.where(small, w, 1.0)) * (1 - t2 / 3 + t2 * t2 / 5 - t2**3 / 7)
    closed = 2.0 * np.arctan2(n, w) / np.where(small, 1.0, n)
    return np.where(small, series, closed)[..., None] * qv


def rotvec_from_dcm(c: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector (rad) of a DCM, inverse of :func:`dcm_from_rotvec`, robust at any angle.

    This is the extraction Savage 2020 eq. (8) needs: ``Δα_var = rotvec(G_C)`` with
    ``G_C = C_{Bvar_{m-1}}^{E0 T} C_{Bvar_m}^{E0}``. Via Shepperd's quaternion, so it stays
    accurate near π (angle error ~ε) where ``vee(C - Cᵀ)`` vanishes.
    """
    return rotvec_from_quat(quat_from_dcm(c))


def rotation_angle(c: ArrayLike) -> NDArray[np.float64]:
    """Angle (rad, in [0, π]) of the rotation a DCM describes; accurate near 0 and π."""
    q = quat_from_dcm(c)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), q[..., 0])


def matrix3(rows: list[list[ArrayLike]]) -> NDArray[np.float64]:
    """Stack a 3×3 nested list of broadcastable arrays into an array (..., 3, 3).

    Same values as nested ``np.stack(..., -1)``/``np.stack(..., -2)``, written element by
    element into one preallocated array (several times faster for long arrays).

    Parameters
    ----------
    rows : list of 3 lists of 3 array_like
        Entry ``rows[i][j]`` is element (i, j).

    Returns
    -------
    ndarray (..., 3, 3)
    """
    shape = np.broadcast_shapes(*(np.shape(x) for row in rows for x in row))
    out = np.empty(shape + (3, 3))
    for i, row in enumerate(rows):
        for j, x in enumerate(row):
            out[..., i, j] = x
    return out


def rot_x(angle: ArrayLike) -> NDArray[np.float64]:
    """Active rotation matrix about x by ``angle`` (rad): ``dcm_from_rotvec([angle, 0, 0])``."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    return matrix3([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: ArrayLike) -> NDArray[np.float64]:
    """Active rotation matrix about y by ``angle`` (rad): ``dcm_from_rotvec([0, angle, 0])``."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    return matrix3([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: ArrayLike) -> NDArray[np.float64]:
    """Active rotation matrix about z by ``angle`` (rad): ``dcm_from_rotvec([0, 0, angle])``."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    return matrix3([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def dcm_from_euler(roll: ArrayLike, pitch: ArrayLike, heading: ArrayLike) -> NDArray[np.float64]:
    """``C_B^N`` of body FRD relative to local-level NED from roll, pitch, heading (rad).

    ``C_B^N = Rz(heading) Ry(pitch) Rx(roll)`` (heading clockwise from north seen from above,
    pitch nose up, roll right wing down), the docs/interface.md §5 ``attitude_rph`` convention.
    """
    return rot_z(heading) @ rot_y(pitch) @ rot_x(roll)


def euler_from_dcm(
    c_b_n: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Roll, pitch, heading (rad) of ``C_B^N`` (FRD w.r.t. NED), inverse of :func:`dcm_from_euler`.

    Roll and heading in (-π, π], pitch in [-π/2, π/2] computed with atan2 (no loss of accuracy
    near ±90° pitch; at exactly ±90° roll is set so that heading carries the yaw-roll sum).
    """
    c = as_matrices(c_b_n)
    pitch = np.arctan2(-c[..., 2, 0], np.hypot(c[..., 2, 1], c[..., 2, 2]))
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    heading = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    # Gimbal lock: the (2,1), (2,2), (0,0), (1,0) entries vanish; recover heading ± roll.
    lock = np.hypot(c[..., 0, 0], c[..., 1, 0]) < 1e-12
    if np.any(lock):
        lock_heading = np.arctan2(-c[..., 0, 1], c[..., 1, 1])
        heading = np.where(lock, lock_heading, heading)
        roll = np.where(lock, 0.0, roll)
    return roll, pitch, heading


def ned_to_enu(v: ArrayLike) -> NDArray[np.float64]:
    """ENU coordinates of a vector given in NED (swap north/east, negate down). Exact."""
    v = as_vectors(v)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def enu_to_ned(v: ArrayLike) -> NDArray[np.float64]:
    """NED coordinates of a vector given in ENU. Exact (the map is its own inverse)."""
    return ned_to_enu(v)


def frd_to_flu(v: ArrayLike) -> NDArray[np.float64]:
    """FLU body coordinates of a vector given in FRD body axes (negate y and z). Exact."""
    v = as_vectors(v)
    return v * np.array([1.0, -1.0, -1.0])


def flu_to_frd(v: ArrayLike) -> NDArray[np.float64]:
    """FRD body coordinates of a vector given in FLU body axes. Exact (self-inverse)."""
    return frd_to_flu(v)


def dcm_to_flu_enu(c_frd_ned: ArrayLike) -> NDArray[np.float64]:
    """``C_FLU^ENU`` from ``C_FRD^NED``: the ROS (REP-103) attitude from the core's. Exact."""
    return C_NED_TO_ENU @ as_matrices(c_frd_ned) @ C_FRD_TO_FLU


def dcm_to_frd_ned(c_flu_enu: ArrayLike) -> NDArray[np.float64]:
    """``C_FRD^NED`` from ``C_FLU^ENU``: inverse of :func:`dcm_to_flu_enu`. Exact."""
    return C_NED_TO_ENU @ as_matrices(c_flu_enu) @ C_FRD_TO_FLU


def orthonormality_error(c: ArrayLike) -> NDArray[np.float64]:
    """Largest absolute element of ``C Cᵀ - I`` (dimensionless), per matrix."""
    c = as_matrices(c)
    return np.max(np.abs(c @ np.swapaxes(c, -1, -2) - np.eye(3)), axis=(-2, -1))
