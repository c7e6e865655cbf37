"""TF, map-frame odometry and increment messages (docs/interface.md, "Frames and TF").

``tf2_msgs/TFMessage`` of translations and DCMs; ``nav_msgs/Odometry`` in ``map`` (ENU at a
datum, REP-105) of the ECEF Odometry; the Δv (``Vector3Stamped``) and Δq
(``QuaternionStamped``) topics that Xsens / SBG style drivers publish beside the Imu.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.messages.fields import (
    ImuFields,
    OdometryFields,
    QuaternionStampedFields,
    TFMessageFields,
    Vector3StampedFields,
    as_rows,
    as_stamps,
)
from strapdown_ros.messages.frames import MAP_FRAME, dcm_from_quat_ros, quat_ros_from_dcm

__all__ = [
    "increment_fields",
    "map_odometry_fields",
    "quaternion_stamped_fields",
    "tf_message_fields",
]


def tf_message_fields(
    stamps_ns: ArrayLike,
    frame_ids: tuple[str, ...] | list[str],
    child_frame_ids: tuple[str, ...] | list[str],
    translation: ArrayLike,
    c_child_parent: ArrayLike,
) -> TFMessageFields:
    """TFMessage fields from translations (N, K, 3) m and DCMs ``C_child^parent`` (N, K, 3, 3).

    Quaternions by :func:`~strapdown_ros.messages.frames.quat_ros_from_dcm` (``w >= 0``).
    """
    t = as_stamps(stamps_ns)
    n, k = t.shape[0], len(frame_ids)
    tr = np.asarray(translation, dtype=np.float64)
    c = np.asarray(c_child_parent, dtype=np.float64)
    if tr.shape != (n, k, 3) or c.shape != (n, k, 3, 3):
        raise ValueError(
            f"tf: expected translation {(n, k, 3)} and rotation {(n, k, 3, 3)}, got "
            f"{tr.shape} and {c.shape}"
        )
    fields_ = TFMessageFields(t, tuple(frame_ids), tuple(child_frame_ids), tr, quat_ros_from_dcm(c))
    fields_.check()
    return fields_


def quaternion_stamped_fields(
    stamps_ns: ArrayLike, quaternion: ArrayLike, frame_id: str
) -> QuaternionStampedFields:
    """``geometry_msgs/QuaternionStamped`` fields (quaternions (N, 4) ``x, y, z, w``)."""
    t = as_stamps(stamps_ns)
    return QuaternionStampedFields(t, frame_id, as_rows(quaternion, t.shape[0], 4, "quaternion"))


def increment_fields(
    imu: ImuFields, period_ns: int
) -> tuple[Vector3StampedFields, QuaternionStampedFields]:
    """Δv and Δq messages of Imu messages, as Xsens / SBG style drivers publish them.

    ``Δv = linear_acceleration · T`` (m/s, FLU; the generator's Δv to 1 ulp) and ``Δq`` = the
    quaternion of the rotation vector ``Δα = angular_velocity · T`` (FLU;
    ``(x, y, z, w) = (sin(θ/2) Δα/θ, cos(θ/2))``, θ = |Δα|), T = ``period_ns`` (the stream's
    cycle). Both in the Imu's frame and stamped like it (``t_m``, end of the cycle).
    """
    t = as_stamps(imu.stamps_ns)
    if int(period_ns) <= 0:
        raise ValueError(f"period_ns must be > 0, got {period_ns}")
    period = int(period_ns) * 1e-9
    da = np.asarray(imu.angular_velocity, dtype=np.float64) * period
    dv = np.asarray(imu.linear_acceleration, dtype=np.float64) * period
    theta = np.linalg.norm(da, axis=1)
    half = 0.5 * theta
    # sin(θ/2)/θ without the 0/0 at θ = 0 (series below 1e-4 rad: exact to round-off)
    small = theta < 1e-4
    ratio = np.where(small, 0.5 - theta**2 / 48.0, np.sin(half) / np.where(small, 1.0, theta))
    q = np.concatenate([da * ratio[:, None], np.cos(half)[:, None]], axis=1)
    return (
        Vector3StampedFields(t, imu.frame_id, dv),
        QuaternionStampedFields(t, imu.frame_id, q),
    )


def _pose_covariance_in_map(cov: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(N, 36) pose covariances rotated by ``diag(C, C)``; unknown / not provided unchanged."""
    if cov.shape[0] and cov.strides[0] == 0 and (not cov[0].any() or cov[0, 0] == -1.0):
        return cov  # unknown / not provided: unchanged (broadcast view)
    rot = np.zeros((6, 6))
    rot[:3, :3] = rot[3:, 3:] = c
    p = cov.reshape(-1, 6, 6)
    given = p[:, 0, 0] != -1.0
    out = p.copy()
    out[given] = rot @ p[given] @ rot.T
    return out.reshape(-1, 36)


def map_odometry_fields(
    odom: OdometryFields,
    r0_e: ArrayLike,
    c_map_e: ArrayLike,
    map_frame: str = MAP_FRAME,
) -> OdometryFields:
    """Odometry in ``map`` (ENU at a datum) of ECEF Odometry fields (REP-105 ``map`` pose).

    ``position = C_E^map (r^E − r0^E)``; ``orientation`` = ``C_FLU^map = C_E^map C_FLU^E``;
    the twist (body axes) is copied unchanged. Pose covariance: zeros (unknown) and ``[−1, …]``
    (not provided) are kept; a given 6×6 covariance is rotated into map axes,
    ``P' = diag(C, C) P diag(C, C)ᵀ`` with ``C = C_E^map``. ``r0_e`` (3,) m, ``c_map_e`` =
    ``C_map^E`` (3, 3) (:class:`strapdown_ros.core.frames.Datum`).
    """
    c_map_e = np.asarray(c_map_e, dtype=np.float64)
    c = c_map_e.T  # C_E^map
    d = np.asarray(odom.position, dtype=np.float64) - np.asarray(r0_e)
    # row-wise C^T d, elementwise (no BLAS: same bits for any number of rows)
    pos = d[:, 0:1] * c_map_e[0] + d[:, 1:2] * c_map_e[1] + d[:, 2:3] * c_map_e[2]
    c_flu_e = dcm_from_quat_ros(odom.orientation)
    return OdometryFields(
        stamps_ns=odom.stamps_ns,
        frame_id=map_frame,
        child_frame_id=odom.child_frame_id,
        position=pos,
        orientation=quat_ros_from_dcm(c @ c_flu_e),
        pose_covariance=_pose_covariance_in_map(np.asarray(odom.pose_covariance), c),
        twist_linear=odom.twist_linear,
        twist_angular=odom.twist_angular,
        twist_covariance=odom.twist_covariance,
    )
