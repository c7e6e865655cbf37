"""``sensor_msgs/Imu`` fields of increments (docs/interface.md §2, §4).

``header.stamp = t_m``; ``angular_velocity = FLU(Δα_m) / T``; ``linear_acceleration =
FLU(Δv_m) / T``; ``orientation`` = attitude of body FLU relative to ENU at ``t_m``
(``C_FLU^ENU``), or identity with ``orientation_covariance[0] = -1`` when not provided.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.rotations import dcm_to_flu_enu, frd_to_flu
from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import (
    COVARIANCE_NOT_PROVIDED,
    ImuFields,
    as_rows,
    as_stamps,
    covariance_rows,
)
from strapdown_ros.messages.frames import DEFAULT_BODY_FRAME, quat_ros_from_dcm
from strapdown_ros.messages.truth import StreamTruth

__all__ = ["imu_fields", "imu_fields_from_increments"]


def imu_fields_from_increments(
    stamps_ns: ArrayLike,
    dalpha: ArrayLike,
    dv: ArrayLike,
    period_ns: int,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    c_frd_ned: ArrayLike | None = None,
    orientation_covariance: object = None,
    angular_velocity_covariance: object = None,
    linear_acceleration_covariance: object = None,
) -> ImuFields:
    """Imu fields of increments over cycles ending at ``stamps_ns`` (docs/interface.md §2).

    Parameters
    ----------
    stamps_ns : (N,) int
        ``t_m`` (ns since the epoch), the end of each cycle.
    dalpha, dv : (N, 3)
        Δα_m (rad) and Δv_m (m/s) over ``(t_m - T, t_m]`` in body FRD.
    period_ns : int
        T (ns); ``angular_velocity = FLU(Δα) / T`` and ``linear_acceleration = FLU(Δv) / T``.
    frame_id : str
        Body (FLU) frame id.
    c_frd_ned : (N, 3, 3) or None
        True attitude ``C_FRD^NED`` at ``t_m``; ``orientation = C_FLU^ENU``. None: orientation not
        provided (identity quaternion, ``orientation_covariance[0] = -1`` unless given).
    orientation_covariance, angular_velocity_covariance, linear_acceleration_covariance
        REP-145 specs: None (zeros: unknown), :data:`COVARIANCE_NOT_PROVIDED`, or arrays
        (9,), (3, 3), (N, 9), (N, 3, 3) in rad² and (m/s²)², FLU/ENU axes.
    """
    t = as_stamps(stamps_ns)
    n = t.shape[0]
    if int(period_ns) <= 0:
        raise ValueError(f"period_ns must be > 0, got {period_ns}")
    T = int(period_ns) * 1e-9
    da = as_rows(dalpha, n, 3, "dalpha")
    dv = as_rows(dv, n, 3, "dv")
    if c_frd_ned is None:
        q = np.broadcast_to(np.array([0.0, 0.0, 0.0, 1.0]), (n, 4))
        if orientation_covariance is None:
            orientation_covariance = COVARIANCE_NOT_PROVIDED
    else:
        q = quat_ros_from_dcm(dcm_to_flu_enu(as_rows(c_frd_ned, n, (3, 3), "c_frd_ned")))
    return ImuFields(
        stamps_ns=t,
        frame_id=frame_id,
        orientation=q,
        orientation_covariance=covariance_rows(
            orientation_covariance, n, 3, "orientation_covariance"
        ),
        angular_velocity=frd_to_flu(da) / T,
        angular_velocity_covariance=covariance_rows(
            angular_velocity_covariance, n, 3, "angular_velocity_covariance"
        ),
        linear_acceleration=frd_to_flu(dv) / T,
        linear_acceleration_covariance=covariance_rows(
            linear_acceleration_covariance, n, 3, "linear_acceleration_covariance"
        ),
    )


def imu_fields(
    stream: Stream,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    orientation: bool = True,
    truth: StreamTruth | None = None,
    **covariances: object,
) -> ImuFields:
    """Imu fields of a stream, m = 1..M (docs/interface.md §2, §4).

    ``orientation=True`` carries the true attitude (FLU relative to ENU at ``t_m``), as on ideal
    streams; ``False`` marks it not provided (measured data). ``covariances``:
    ``orientation_covariance``, ``angular_velocity_covariance``,
    ``linear_acceleration_covariance``, specs as in :func:`imu_fields_from_increments`.
    ``truth``: the stream's :class:`~strapdown_ros.messages.truth.StreamTruth` when another
    message type of the stream computed it already.
    """
    c_frd_ned = None
    if orientation:
        c_frd_ned = (truth if truth is not None else StreamTruth(stream)).c_frd_ned()
    return imu_fields_from_increments(
        stream.stamps_ns[1:],
        stream.dalpha,
        stream.dv,
        stream.period_ns,
        frame_id,
        c_frd_ned=c_frd_ned,
        **covariances,
    )
