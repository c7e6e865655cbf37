"""``nav_msgs/Odometry`` fields of an Earth-referenced state (docs/interface.md §4).

``header.frame_id = earth``, ``child_frame_id`` = body frame; ``pose.position = r^E``;
``pose.orientation`` = ``C_FLU^E``; ``twist.linear = C_E^FLU v^E`` (velocity relative to the
Earth, body axes); ``twist.angular = FLU(ω_eb^B)`` with ``ω_eb^B = Δα_m / T - C_E^B ω_ie^E``:
the inertial rate is the mean rate of the cycle ending at ``t_m`` (cycle 1 for m = 0), the Earth
rate is removed with the attitude at ``t_m``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.earth import body_rates_relative_to_earth
from strapdown_ros.core.rotations import C_FRD_TO_FLU, frd_to_flu
from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import OdometryFields, as_rows, as_stamps, covariance_rows
from strapdown_ros.messages.frames import DEFAULT_BODY_FRAME, EARTH_FRAME, quat_ros_from_dcm
from strapdown_ros.messages.truth import StreamTruth

__all__ = ["odometry_fields", "odometry_fields_from_ecef", "twist_covariance_flu"]

#: The FRD → FLU axis signs of a twist ``(v, ω)``: ``diag(1, -1, -1)`` on each.
_FLU6 = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])


def twist_covariance_flu(cov_frd: np.ndarray) -> np.ndarray:
    """Twist covariances (k, 6, 6) of ``(v, ω)`` in body FRD axes, in FLU (the message's)."""
    return cov_frd * _FLU6[None, :, None] * _FLU6[None, None, :]


def odometry_fields_from_ecef(
    stamps_ns: ArrayLike,
    r_e: ArrayLike,
    v_e: ArrayLike,
    c_b_e: ArrayLike,
    omega_eb_b: ArrayLike,
    child_frame_id: str = DEFAULT_BODY_FRAME,
    frame_id: str = EARTH_FRAME,
    *,
    pose_covariance: object = None,
    twist_covariance: object = None,
) -> OdometryFields:
    """Odometry fields of an Earth-referenced state (core frames in, ROS frames out).

    Parameters
    ----------
    stamps_ns : (N,) int
    r_e : (N, 3)
        ECEF position, m.
    v_e : (N, 3)
        Velocity relative to the Earth in ECEF axes, m/s.
    c_b_e : (N, 3, 3)
        ``C_FRD^E`` (body FRD to ECEF).
    omega_eb_b : (N, 3)
        Angular rate of the body relative to the Earth, body FRD axes, rad/s.
    pose_covariance, twist_covariance
        REP-145 specs (None, :data:`COVARIANCE_NOT_PROVIDED`, (36,), (6, 6), (N, 36), (N, 6, 6)).
    """
    t = as_stamps(stamps_ns)
    n = t.shape[0]
    r = as_rows(r_e, n, 3, "r_e")
    v = as_rows(v_e, n, 3, "v_e")
    w = as_rows(omega_eb_b, n, 3, "omega_eb_b")
    c = as_rows(c_b_e, n, (3, 3), "c_b_e")
    v_b = (np.swapaxes(c, -1, -2) @ v[..., None])[..., 0]
    return OdometryFields(
        stamps_ns=t,
        frame_id=frame_id,
        child_frame_id=child_frame_id,
        position=r,
        orientation=quat_ros_from_dcm(matmul33(c, C_FRD_TO_FLU)),
        pose_covariance=covariance_rows(pose_covariance, n, 6, "pose_covariance"),
        twist_linear=frd_to_flu(v_b),
        twist_angular=frd_to_flu(w),
        twist_covariance=covariance_rows(twist_covariance, n, 6, "twist_covariance"),
    )


def odometry_fields(
    stream: Stream,
    child_frame_id: str = DEFAULT_BODY_FRAME,
    frame_id: str = EARTH_FRAME,
    *,
    truth: StreamTruth | None = None,
    **covariances: object,
) -> OdometryFields:
    """Odometry (truth) fields of a stream, m = 0..M (docs/interface.md §4).

    ``twist.angular`` is ``FLU(Δα_m / T - C_E^B ω_ie^E)`` with the cycle ending at ``t_m``
    (cycle 1 for m = 0; for a stream without cycles the body is taken at rest on the Earth).
    ``covariances``: ``pose_covariance``, ``twist_covariance`` as in
    :func:`odometry_fields_from_ecef`; ``truth`` as in
    :func:`~strapdown_ros.messages.imu.imu_fields`.
    """
    r_e, v_e, c_b_e = (truth if truth is not None else StreamTruth(stream)).ecef
    n = stream.cycles + 1
    if stream.cycles:
        w_ib = np.concatenate([stream.dalpha[:1], stream.dalpha]) / stream.period
    else:  # no cycle: take the body at rest on the Earth (ω_ib^B = C_E^B ω_ie^E)
        w_ib = -body_rates_relative_to_earth(np.zeros((n, 3)), c_b_e)
    w_eb = body_rates_relative_to_earth(w_ib, c_b_e)
    return odometry_fields_from_ecef(
        stream.stamps_ns, r_e, v_e, c_b_e, w_eb, child_frame_id, frame_id, **covariances
    )
