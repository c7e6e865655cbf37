"""Frame ids and quaternion order at the message boundary (docs/interface.md, "Frames and TF").

The core works with DCMs and scalar-first quaternions ``[w, x, y, z]`` in FRD / NED / ECEF;
messages carry ROS quaternions ``(x, y, z, w)`` in FLU / ENU / ECEF. The FRD ↔ FLU and NED ↔ ENU
flips themselves are :func:`~strapdown_ros.core.rotations.frd_to_flu` and
:func:`~strapdown_ros.core.rotations.dcm_to_flu_enu`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.rotations import dcm_from_quat, quat_from_dcm

__all__ = [
    "BASE_LINK_FRAME",
    "DEFAULT_BODY_FRAME",
    "EARTH_FRAME",
    "MAP_FRAME",
    "dcm_from_quat_ros",
    "quat_ros_from_dcm",
]

#: ROS frame id of ECEF (REP-105), ``header.frame_id`` of every Odometry.
EARTH_FRAME = "earth"
#: Default body frame id of the reference IMU (docs/interface.md §4).
DEFAULT_BODY_FRAME = "reference_imu"
#: REP-105 frame ids of the TF tree: ``earth → map → base_link`` (docs/interface.md).
MAP_FRAME = "map"
BASE_LINK_FRAME = "base_link"


def quat_ros_from_dcm(c: ArrayLike) -> NDArray[np.float64]:
    """ROS quaternion ``(x, y, z, w)``, ``w >= 0``, of a DCM ``C_A^B`` (frame A relative to B).

    :func:`~strapdown_ros.core.rotations.quat_from_dcm` (Shepperd, largest pivot) reordered.
    """
    q = quat_from_dcm(c)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def dcm_from_quat_ros(q_xyzw: ArrayLike) -> NDArray[np.float64]:
    """DCM of a ROS quaternion ``(x, y, z, w)`` (normalized first)."""
    q = np.asarray(q_xyzw, dtype=np.float64)
    return dcm_from_quat(np.concatenate([q[..., 3:], q[..., :3]], axis=-1))
