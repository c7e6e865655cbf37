"""Messages back to core arrays: increments, Earth-referenced states, geodetic positions, streams.

The inverses of :mod:`~strapdown_ros.messages.imu`, :mod:`~strapdown_ros.messages.odometry`
and :mod:`~strapdown_ros.messages.navsatfix` (FLU → FRD, ROS quaternions → DCMs, degrees →
radians), and :func:`stream_from_messages`, which rebuilds a whole :class:`Stream` from its Imu
and Odometry messages.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.earth import ecef_state_to_e0
from strapdown_ros.core.rotations import C_FRD_TO_FLU, flu_to_frd
from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import (
    F64,
    I64,
    ImuFields,
    NavSatFixFields,
    OdometryFields,
    as_stamps,
)
from strapdown_ros.messages.frames import dcm_from_quat_ros

__all__ = [
    "EarthState",
    "ImuIncrements",
    "imu_increments",
    "navsatfix_geodetic",
    "odometry_state",
    "stream_from_messages",
]


class ImuIncrements(NamedTuple):
    """Increments recovered from Imu messages (core frames)."""

    stamps_ns: I64  #: (N,) cycle end stamps t_m
    period_ns: int  #: T (ns)
    dalpha: F64  #: (N, 3) Δα (rad, FRD)
    dv: F64  #: (N, 3) Δv (m/s, FRD)


class EarthState(NamedTuple):
    """Earth-referenced state recovered from Odometry messages (core frames)."""

    stamps_ns: I64  #: (N,)
    r_e: F64  #: (N, 3) ECEF position, m
    v_e: F64  #: (N, 3) velocity relative to the Earth, ECEF axes, m/s
    c_b_e: F64  #: (N, 3, 3) C_FRD^E
    omega_eb_b: F64  #: (N, 3) body rate relative to the Earth, FRD, rad/s


def _uniform_period(stamps_ns: I64, name: str) -> int:
    if stamps_ns.shape[0] < 2:
        raise ValueError(f"{name}: need >= 2 messages to recover T; pass period_ns")
    d = np.diff(stamps_ns)
    if not np.all(d == d[0]) or d[0] <= 0:
        raise ValueError(f"{name}: stamps are not uniformly spaced; pass period_ns")
    return int(d[0])


def _frd(flu: object) -> F64:
    """FRD components of FLU vectors of a message field."""
    return flu_to_frd(np.asarray(flu, dtype=np.float64))


def imu_increments(imu: ImuFields, period_ns: int | None = None) -> ImuIncrements:
    """Δα, Δv (FRD) of Imu messages: ``FRD(angular_velocity) T``, ``FRD(linear_acceleration) T``.

    T is ``period_ns`` or the (uniform) spacing of the stamps (docs/interface.md §2).
    ``x / T * T`` equals ``x`` to 1 ulp (not always bit for bit).
    """
    t = as_stamps(imu.stamps_ns)
    p = _uniform_period(t, "imu") if period_ns is None else int(period_ns)
    T = p * 1e-9
    return ImuIncrements(t, p, _frd(imu.angular_velocity) * T, _frd(imu.linear_acceleration) * T)


def odometry_state(odom: OdometryFields) -> EarthState:
    """Earth-referenced state (FRD body) of Odometry messages; inverse of
    :func:`~strapdown_ros.messages.odometry.odometry_fields_from_ecef` (to rounding of the
    quaternion)."""
    c = matmul33(dcm_from_quat_ros(odom.orientation), C_FRD_TO_FLU)
    v_b = _frd(odom.twist_linear)
    return EarthState(
        as_stamps(odom.stamps_ns),
        np.asarray(odom.position, dtype=np.float64),
        (c @ v_b[..., None])[..., 0],
        c,
        _frd(odom.twist_angular),
    )


def navsatfix_geodetic(fix: NavSatFixFields) -> tuple[I64, F64, F64, F64]:
    """``(stamps_ns, lat, lon, alt)`` with lat/lon in rad, alt in m, of NavSatFix messages."""
    return (
        as_stamps(fix.stamps_ns),
        np.radians(np.asarray(fix.latitude, dtype=np.float64)),
        np.radians(np.asarray(fix.longitude, dtype=np.float64)),
        np.asarray(fix.altitude, dtype=np.float64),
    )


def stream_from_messages(
    imu: ImuFields,
    odom: OdometryFields,
    gravity_model: str = "j2",
    e0_epoch_ns: int | None = None,
) -> Stream:
    """Rebuild a :class:`Stream` (E0 truth, FRD increments) from its Imu and Odometry messages.

    The first Odometry message is cycle 0 (``t0``); Imu message m must be stamped like Odometry
    message m (m = 1..M). Used to check the exactness rule (docs/interface.md §3) on a written
    bag; the E → E0 and quaternion round trips cost ~1e-9 m and ~1e-16 rad, far below the rule's
    tolerances. ``e0_epoch_ns``: the instant E0 coincides with ECEF (default: the first Odometry
    stamp); a window of a longer stream passes the stream's start so E0 stays the same frame.
    """
    t_odom = as_stamps(odom.stamps_ns)
    t_imu = as_stamps(imu.stamps_ns)
    if t_odom.shape[0] != t_imu.shape[0] + 1 or not np.array_equal(t_odom[1:], t_imu):
        raise ValueError("Imu stamps must equal the Odometry stamps of cycles 1..M")
    if not t_imu.shape[0]:
        raise ValueError("need at least one Imu message to rebuild a stream")
    period = _uniform_period(t_odom, "odometry")
    inc = imu_increments(imu, period)
    st = odometry_state(odom)
    epoch = int(t_odom[0]) if e0_epoch_ns is None else int(e0_epoch_ns)
    r0, v0, c0 = ecef_state_to_e0((t_odom - epoch) * 1e-9, st.r_e, st.v_e, st.c_b_e)
    assert c0 is not None
    return Stream(
        e0_epoch_ns=epoch, t0_ns=int(t_odom[0]), period_ns=period, dalpha=inc.dalpha,
        dv=inc.dv, c_b_e0=c0, v_e0=v0, r_e0=r0, gravity_model=gravity_model,
    )  # fmt: skip
