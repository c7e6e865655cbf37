"""The ROS/message boundary: streams (FRD, NED, E0) to message fields (FLU, ENU, ECEF) and back.

Everything here is pure numpy (no rclpy, no rosbags). A message *type* is represented by a field
container holding one array per field for N messages (a struct of arrays); the bulk CDR codec in
:mod:`strapdown_ros.bag.cdr` turns those into payloads and back. The frame conversions of
docs/interface.md §1
happen here and only here, exactly (sign flips and 90° rotations):

* body: ``v^FLU = diag(1, -1, -1) v^FRD`` (:func:`~strapdown_ros.core.rotations.frd_to_flu`);
* local level: ``C_FLU^ENU = C_NED_TO_ENU C_FRD^NED C_FRD_TO_FLU``;
* inertial E0 to ECEF at ``t = t_m - t0`` (:func:`~strapdown_ros.core.earth.e0_state_to_ecef`).

Message semantics (docs/interface.md §2, §4; see ``docs/messages.md``):

``sensor_msgs/Imu`` (m = 1..M)
    ``header.stamp = t_m``; ``angular_velocity = FLU(Δα_m) / T``;
    ``linear_acceleration = FLU(Δv_m) / T``; ``orientation`` = attitude of body FLU relative to
    ENU at ``t_m`` (``C_FLU^ENU``), or identity with ``orientation_covariance[0] = -1`` when not
    provided.
``nav_msgs/Odometry`` (m = 0..M)
    ``header.frame_id = earth``, ``child_frame_id`` = body frame; ``pose.position = r^E``;
    ``pose.orientation`` = ``C_FLU^E``; ``twist.linear = C_E^FLU v^E`` (velocity relative to the
    Earth, body axes); ``twist.angular = FLU(ω_eb^B)`` with
    ``ω_eb^B = Δα_m / T - C_E^B ω_ie^E``: the inertial rate is the mean rate of the cycle ending at
    ``t_m`` (cycle 1 for m = 0), the Earth rate is removed with the attitude at ``t_m``.
``sensor_msgs/NavSatFix`` (m = 0..M)
    geodetic latitude/longitude (deg) and ellipsoidal altitude (m) of ``r^E(t_m)``;
    ``STATUS_FIX`` / ``SERVICE_GPS``; ideal streams: zero covariance, ``COVARIANCE_TYPE_UNKNOWN``.

Quaternions in the field containers are in ROS order ``(x, y, z, w)``; the core uses ``[w, x, y,
z]``. Covariances follow REP-145: zeros mean "unknown" (ideal streams), element 0 = -1 means "not
provided" (:data:`COVARIANCE_NOT_PROVIDED`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.earth import (
    body_rates_relative_to_earth,
    dcm_ned_to_ecef,
    e0_state_to_ecef,
    ecef_state_to_e0,
    ecef_to_geodetic,
)
from strapdown_ros.core.rotations import (
    C_FRD_TO_FLU,
    dcm_from_quat,
    dcm_to_flu_enu,
    flu_to_frd,
    frd_to_flu,
    quat_from_dcm,
)
from strapdown_ros.core.stream import Stream

__all__ = [
    "COVARIANCE_NOT_PROVIDED",
    "COVARIANCE_TYPE_APPROXIMATED",
    "COVARIANCE_TYPE_DIAGONAL_KNOWN",
    "COVARIANCE_TYPE_KNOWN",
    "COVARIANCE_TYPE_UNKNOWN",
    "DEFAULT_BODY_FRAME",
    "EARTH_FRAME",
    "SERVICE_GPS",
    "SERVICE_UNKNOWN",
    "STATUS_NO_FIX",
    "STATUS_FIX",
    "ClockFields",
    "EarthState",
    "FluidPressureFields",
    "ImuFields",
    "MagneticFieldFields",
    "TwistWithCovarianceStampedFields",
    "ImuIncrements",
    "NavSatFixFields",
    "OdometryFields",
    "StreamFields",
    "Vector3StampedFields",
    "clock_fields",
    "imu_fields",
    "imu_fields_from_increments",
    "imu_increments",
    "navsatfix_fields",
    "navsatfix_fields_from_geodetic",
    "navsatfix_geodetic",
    "odometry_fields",
    "odometry_fields_from_ecef",
    "odometry_state",
    "quat_ros_from_dcm",
    "dcm_from_quat_ros",
    "stamps_to_sec_nanosec",
    "stream_fields",
    "stream_from_messages",
    "vector3_stamped_fields",
    "BASE_LINK_FRAME",
    "MAP_FRAME",
    "QuaternionStampedFields",
    "TFMessageFields",
    "increment_fields",
    "map_odometry_fields",
    "quaternion_stamped_fields",
    "tf_message_fields",
]

#: ROS frame id of ECEF (REP-105), ``header.frame_id`` of every Odometry.
EARTH_FRAME = "earth"
#: Default body frame id of the reference IMU (docs/interface.md §4).
DEFAULT_BODY_FRAME = "reference_imu"

#: REP-145 "not provided": covariance element 0 set to -1 (the rest zero).
COVARIANCE_NOT_PROVIDED = "not_provided"

# sensor_msgs/NavSatStatus and NavSatFix constants (values of the message definitions).
STATUS_FIX = 0
SERVICE_GPS = 1
#: An inertial-only position (the navigator's): not a GNSS fix (docs/interface.md §4).
STATUS_NO_FIX = -1
SERVICE_UNKNOWN = 0
COVARIANCE_TYPE_UNKNOWN = 0
COVARIANCE_TYPE_APPROXIMATED = 1
COVARIANCE_TYPE_DIAGONAL_KNOWN = 2
COVARIANCE_TYPE_KNOWN = 3

_NS = 1_000_000_000
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


# --------------------------------------------------------------------------------------------
# Field containers (struct of arrays, N messages each)
# --------------------------------------------------------------------------------------------


class _Fields:
    """Shared helpers of the field containers."""

    def __len__(self) -> int:
        return int(np.shape(self.stamps_ns)[0])  # type: ignore[attr-defined]

    def equals(self, other: object) -> bool:
        """Exact equality of every field (arrays compared element-wise, bit for bit)."""
        if type(other) is not type(self):
            return False
        for f in fields(self):  # type: ignore[arg-type]
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, str) or isinstance(b, str):
                if a != b:
                    return False
            elif not np.array_equal(np.asarray(a), np.asarray(b)):
                return False
        return True

    def rows(self, start: int, stop: int) -> Any:
        """Messages ``start..stop-1`` as a container of the same type (views, no copy)."""
        values = {
            f.name: getattr(self, f.name)
            if isinstance(getattr(self, f.name), str)
            else getattr(self, f.name)[start:stop]
            for f in fields(self)  # type: ignore[arg-type]
        }
        return type(self)(**values)

    def append(self, other: Any) -> Any:
        """This container followed by ``other`` (same type and frame ids)."""
        values = {}
        for f in fields(self):  # type: ignore[arg-type]
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, str):
                if a != b:
                    raise ValueError(f"{type(self).__name__}.{f.name}: {a!r} != {b!r}")
                values[f.name] = a
            else:
                values[f.name] = np.concatenate([a, b])
        return type(self)(**values)

    def check(self) -> None:
        """Validate shapes against ``len(self)``; raises ValueError naming the field."""
        n = len(self)
        for f in fields(self):  # type: ignore[arg-type]
            if f.name == "stamps_ns" or isinstance(getattr(self, f.name), str):
                continue
            a = np.asarray(getattr(self, f.name))
            if a.shape[:1] != (n,):
                raise ValueError(
                    f"{type(self).__name__}.{f.name}: expected {n} rows, got shape {a.shape}"
                )


@dataclass(frozen=True, eq=False)
class ImuFields(_Fields):
    """``sensor_msgs/msg/Imu`` fields of N messages with one ``frame_id``.

    Arrays: ``stamps_ns`` (N,) int64 ns since the epoch; ``orientation`` (N, 4) ``x, y, z, w``;
    ``angular_velocity``, ``linear_acceleration`` (N, 3) rad/s, m/s² (FLU); covariances (N, 9)
    row-major. Arrays may be read-only broadcast views (constant covariances).
    """

    stamps_ns: I64
    frame_id: str
    orientation: F64
    orientation_covariance: F64
    angular_velocity: F64
    angular_velocity_covariance: F64
    linear_acceleration: F64
    linear_acceleration_covariance: F64


@dataclass(frozen=True, eq=False)
class OdometryFields(_Fields):
    """``nav_msgs/msg/Odometry`` fields of N messages with constant frame ids.

    ``position`` (N, 3) m ECEF; ``orientation`` (N, 4) ``x, y, z, w`` of body FLU relative to
    ECEF; ``pose_covariance`` (N, 36); ``twist_linear`` (N, 3) m/s and ``twist_angular`` (N, 3)
    rad/s, both relative to the Earth in body FLU axes; ``twist_covariance`` (N, 36).
    """

    stamps_ns: I64
    frame_id: str
    child_frame_id: str
    position: F64
    orientation: F64
    pose_covariance: F64
    twist_linear: F64
    twist_angular: F64
    twist_covariance: F64


@dataclass(frozen=True, eq=False)
class NavSatFixFields(_Fields):
    """``sensor_msgs/msg/NavSatFix`` fields of N messages with one ``frame_id``.

    ``status`` (N,) int8, ``service`` (N,) uint16 (NavSatStatus); ``latitude``, ``longitude``
    (N,) deg; ``altitude`` (N,) m above the WGS-84 ellipsoid; ``position_covariance`` (N, 9) m²
    (ENU); ``position_covariance_type`` (N,) uint8.
    """

    stamps_ns: I64
    frame_id: str
    status: NDArray[np.int8]
    service: NDArray[np.uint16]
    latitude: F64
    longitude: F64
    altitude: F64
    position_covariance: F64
    position_covariance_type: NDArray[np.uint8]


@dataclass(frozen=True, eq=False)
class TwistWithCovarianceStampedFields(_Fields):
    """``geometry_msgs/msg/TwistWithCovarianceStamped`` of N messages (aiding, issue 16).

    ``linear`` (N, 3) m/s, ``angular`` (N, 3) rad/s in the axes ``frame_id`` states (see
    docs/aiding.md: ENU for ``/gnss/vel``, the vehicle FLU axes for ``/wheel/twist``);
    ``covariance`` (N, 36) row-major over (linear, angular).
    """

    stamps_ns: I64
    frame_id: str
    linear: F64
    angular: F64
    covariance: F64


@dataclass(frozen=True, eq=False)
class FluidPressureFields(_Fields):
    """``sensor_msgs/msg/FluidPressure`` of N messages: ``fluid_pressure`` (N,) Pa, ``variance``
    (N,) Pa² (0: unknown)."""

    stamps_ns: I64
    frame_id: str
    fluid_pressure: F64
    variance: F64


@dataclass(frozen=True, eq=False)
class MagneticFieldFields(_Fields):
    """``sensor_msgs/msg/MagneticField`` of N messages: ``magnetic_field`` (N, 3) tesla in the
    body FLU axes of ``frame_id``, ``magnetic_field_covariance`` (N, 9) T², row-major."""

    stamps_ns: I64
    frame_id: str
    magnetic_field: F64
    magnetic_field_covariance: F64


@dataclass(frozen=True, eq=False)
class ClockFields(_Fields):
    """``rosgraph_msgs/msg/Clock`` of N messages: ``clock = stamps_ns``."""

    stamps_ns: I64


@dataclass(frozen=True, eq=False)
class Vector3StampedFields(_Fields):
    """``geometry_msgs/msg/Vector3Stamped`` of N messages: ``vector`` (N, 3)."""

    stamps_ns: I64
    frame_id: str
    vector: F64


# --------------------------------------------------------------------------------------------
# Small helpers
# --------------------------------------------------------------------------------------------


def stamps_to_sec_nanosec(stamps_ns: ArrayLike) -> tuple[NDArray[np.int32], NDArray[np.uint32]]:
    """``builtin_interfaces/Time`` of ns stamps: ``sec = floor(t / 1e9)``, ``nanosec`` in [0, 1e9).

    Raises ValueError if a stamp does not fit ``int32`` seconds.
    """
    t = np.asarray(stamps_ns, dtype=np.int64)
    sec = np.floor_divide(t, _NS)
    if sec.size and (sec.min() < _INT32_MIN or sec.max() > _INT32_MAX):
        raise ValueError("time stamp outside the int32 seconds range of builtin_interfaces/Time")
    return sec.astype(np.int32), (t - sec * _NS).astype(np.uint32)


def quat_ros_from_dcm(c: ArrayLike) -> F64:
    """ROS quaternion ``(x, y, z, w)``, ``w >= 0``, of a DCM ``C_A^B`` (frame A relative to B).

    :func:`~strapdown_ros.core.rotations.quat_from_dcm` (Shepperd, largest pivot) reordered.
    """
    q = quat_from_dcm(c)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def dcm_from_quat_ros(q_xyzw: ArrayLike) -> F64:
    """DCM of a ROS quaternion ``(x, y, z, w)`` (normalized first)."""
    q = np.asarray(q_xyzw, dtype=np.float64)
    return dcm_from_quat(np.concatenate([q[..., 3:], q[..., :3]], axis=-1))


def _stamps(stamps_ns: ArrayLike) -> I64:
    t = np.asarray(stamps_ns)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError("stamps_ns must be a 1-D integer array (ns since the epoch)")
    return t.astype(np.int64, copy=False)


def _rows(a: ArrayLike, n: int, width: int, name: str) -> F64:
    a = np.asarray(a, dtype=np.float64)
    if a.shape != (n, width):
        raise ValueError(f"{name}: expected shape ({n}, {width}), got {a.shape}")
    return a


def _covariance(spec: object, n: int, k: int, name: str) -> F64:
    """(n, k*k) covariance rows from a REP-145 spec.

    ``None`` → zeros (unknown); :data:`COVARIANCE_NOT_PROVIDED` → ``[-1, 0, ...]``; an array of
    shape (k*k,), (k, k), (n, k*k) or (n, k, k) → broadcast rows. Constant specs give read-only
    broadcast views.
    """
    size = k * k
    if spec is None:
        return np.broadcast_to(np.zeros(size), (n, size))
    if isinstance(spec, str):
        if spec != COVARIANCE_NOT_PROVIDED:
            raise ValueError(f"{name}: unknown covariance spec {spec!r}")
        row = np.zeros(size)
        row[0] = -1.0
        return np.broadcast_to(row, (n, size))
    a = np.asarray(spec, dtype=np.float64)
    if a.shape in ((size,), (k, k)):
        return np.broadcast_to(a.reshape(size), (n, size))
    if a.shape in ((n, size), (n, k, k)):
        return a.reshape(n, size)
    raise ValueError(
        f"{name}: expected shape ({size},), ({k}, {k}), ({n}, {size}) or ({n}, {k}, "
        f"{k}), got {a.shape}"
    )


def _column(value: ArrayLike, n: int, dtype: type, name: str) -> NDArray:
    a = np.asarray(value)
    if a.ndim == 0:
        return np.broadcast_to(a.astype(dtype), (n,))
    if a.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got {a.shape}")
    return a.astype(dtype)


# --------------------------------------------------------------------------------------------
# Stream -> message fields
# --------------------------------------------------------------------------------------------


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
    t = _stamps(stamps_ns)
    n = t.shape[0]
    if int(period_ns) <= 0:
        raise ValueError(f"period_ns must be > 0, got {period_ns}")
    T = int(period_ns) * 1e-9
    da = _rows(dalpha, n, 3, "dalpha")
    dv = _rows(dv, n, 3, "dv")
    if c_frd_ned is None:
        q = np.broadcast_to(np.array([0.0, 0.0, 0.0, 1.0]), (n, 4))
        if orientation_covariance is None:
            orientation_covariance = COVARIANCE_NOT_PROVIDED
    else:
        c = np.asarray(c_frd_ned, dtype=np.float64)
        if c.shape != (n, 3, 3):
            raise ValueError(f"c_frd_ned: expected shape ({n}, 3, 3), got {c.shape}")
        q = quat_ros_from_dcm(dcm_to_flu_enu(c))
    return ImuFields(
        stamps_ns=t,
        frame_id=frame_id,
        orientation=q,
        orientation_covariance=_covariance(orientation_covariance, n, 3, "orientation_covariance"),
        angular_velocity=frd_to_flu(da) / T,
        angular_velocity_covariance=_covariance(
            angular_velocity_covariance, n, 3, "angular_velocity_covariance"
        ),
        linear_acceleration=frd_to_flu(dv) / T,
        linear_acceleration_covariance=_covariance(
            linear_acceleration_covariance, n, 3, "linear_acceleration_covariance"
        ),
    )


class _Truth:
    """Earth-referenced truth of a stream at t_m, m = 0..M, each part computed once, on demand.

    Shared by the Imu, Odometry and NavSatFix fields of one stream (:func:`stream_fields`); the
    E0 → E conversion and the extended-precision geodetic conversion dominate their cost.
    """

    def __init__(self, stream: Stream) -> None:
        self.stream = stream

    @cached_property
    def ecef(self) -> tuple[F64, F64, F64]:
        """``r^E, v^E, C_B^E`` (FRD), E0 → E at ``t = t_m - t0``."""
        s = self.stream
        r_e, v_e, c_b_e = e0_state_to_ecef(s.t, s.r_e0, s.v_e0, s.c_b_e0)
        assert c_b_e is not None
        return r_e, v_e, c_b_e

    @cached_property
    def geodetic(self) -> tuple[F64, F64, F64]:
        """Geodetic latitude, longitude (rad) and altitude (m) of ``r^E`` (exact)."""
        return ecef_to_geodetic(self.ecef[0])

    def c_frd_ned(self) -> F64:
        """``C_FRD^NED`` at t_m, m = 1..M (the Imu messages)."""
        lat, lon, _ = self.geodetic
        return matmul33(dcm_ned_to_ecef(lat[1:], lon[1:]), self.ecef[2][1:], transpose_a=True)


def imu_fields(
    stream: Stream,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    orientation: bool = True,
    orientation_covariance: object = None,
    angular_velocity_covariance: object = None,
    linear_acceleration_covariance: object = None,
) -> ImuFields:
    """Imu fields of a stream, m = 1..M (docs/interface.md §2, §4).

    ``orientation=True`` carries the true attitude (FLU relative to ENU at ``t_m``), as on ideal
    streams; ``False`` marks it not provided (measured data). Covariance specs as in
    :func:`imu_fields_from_increments`.
    """
    return _imu_fields(
        stream,
        _Truth(stream),
        frame_id,
        orientation=orientation,
        orientation_covariance=orientation_covariance,
        angular_velocity_covariance=angular_velocity_covariance,
        linear_acceleration_covariance=linear_acceleration_covariance,
    )


def _imu_fields(
    stream: Stream,
    truth: _Truth,
    frame_id: str,
    *,
    orientation: bool = True,
    orientation_covariance: object = None,
    angular_velocity_covariance: object = None,
    linear_acceleration_covariance: object = None,
) -> ImuFields:
    return imu_fields_from_increments(
        stream.stamps_ns[1:],
        stream.dalpha,
        stream.dv,
        stream.period_ns,
        frame_id,
        c_frd_ned=truth.c_frd_ned() if orientation else None,
        orientation_covariance=orientation_covariance,
        angular_velocity_covariance=angular_velocity_covariance,
        linear_acceleration_covariance=linear_acceleration_covariance,
    )


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
    t = _stamps(stamps_ns)
    n = t.shape[0]
    r = _rows(r_e, n, 3, "r_e")
    v = _rows(v_e, n, 3, "v_e")
    w = _rows(omega_eb_b, n, 3, "omega_eb_b")
    c = np.asarray(c_b_e, dtype=np.float64)
    if c.shape != (n, 3, 3):
        raise ValueError(f"c_b_e: expected shape ({n}, 3, 3), got {c.shape}")
    v_b = (np.swapaxes(c, -1, -2) @ v[..., None])[..., 0]
    return OdometryFields(
        stamps_ns=t,
        frame_id=frame_id,
        child_frame_id=child_frame_id,
        position=r,
        orientation=quat_ros_from_dcm(matmul33(c, C_FRD_TO_FLU)),
        pose_covariance=_covariance(pose_covariance, n, 6, "pose_covariance"),
        twist_linear=frd_to_flu(v_b),
        twist_angular=frd_to_flu(w),
        twist_covariance=_covariance(twist_covariance, n, 6, "twist_covariance"),
    )


def odometry_fields(
    stream: Stream,
    child_frame_id: str = DEFAULT_BODY_FRAME,
    frame_id: str = EARTH_FRAME,
    *,
    pose_covariance: object = None,
    twist_covariance: object = None,
) -> OdometryFields:
    """Odometry (truth) fields of a stream, m = 0..M (docs/interface.md §4).

    ``twist.angular`` is ``FLU(Δα_m / T - C_E^B ω_ie^E)`` with the cycle ending at ``t_m``
    (cycle 1 for m = 0; for a stream without cycles the body is taken at rest on the Earth).
    """
    return _odometry_fields(
        stream,
        _Truth(stream),
        child_frame_id,
        frame_id,
        pose_covariance=pose_covariance,
        twist_covariance=twist_covariance,
    )


def _odometry_fields(
    stream: Stream,
    truth: _Truth,
    child_frame_id: str,
    frame_id: str,
    *,
    pose_covariance: object = None,
    twist_covariance: object = None,
) -> OdometryFields:
    r_e, v_e, c_b_e = truth.ecef
    n = stream.cycles + 1
    if stream.cycles:
        w_ib = np.concatenate([stream.dalpha[:1], stream.dalpha]) / stream.period
    else:  # no cycle: take the body at rest on the Earth (ω_ib^B = C_E^B ω_ie^E)
        w_ib = -body_rates_relative_to_earth(np.zeros((n, 3)), c_b_e)
    w_eb = body_rates_relative_to_earth(w_ib, c_b_e)
    return odometry_fields_from_ecef(
        stream.stamps_ns,
        r_e,
        v_e,
        c_b_e,
        w_eb,
        child_frame_id,
        frame_id,
        pose_covariance=pose_covariance,
        twist_covariance=twist_covariance,
    )


def navsatfix_fields_from_geodetic(
    stamps_ns: ArrayLike,
    lat: ArrayLike,
    lon: ArrayLike,
    alt: ArrayLike,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    position_covariance: ArrayLike | None = None,
    position_covariance_type: int | None = None,
    status: ArrayLike = STATUS_FIX,
    service: ArrayLike = SERVICE_GPS,
) -> NavSatFixFields:
    """NavSatFix fields of geodetic positions (``lat``, ``lon`` in rad, ``alt`` ellipsoidal, m).

    ``position_covariance`` None → zeros and ``COVARIANCE_TYPE_UNKNOWN``; otherwise (9,), (3, 3),
    (N, 9) or (N, 3, 3) m² in ENU with type ``position_covariance_type`` (default KNOWN).
    """
    t = _stamps(stamps_ns)
    n = t.shape[0]
    cov = _covariance(position_covariance, n, 3, "position_covariance")
    ctype = position_covariance_type
    if ctype is None:
        ctype = COVARIANCE_TYPE_UNKNOWN if position_covariance is None else COVARIANCE_TYPE_KNOWN
    return NavSatFixFields(
        stamps_ns=t,
        frame_id=frame_id,
        status=_column(status, n, np.int8, "status"),
        service=_column(service, n, np.uint16, "service"),
        latitude=np.degrees(_column(lat, n, np.float64, "lat")),
        longitude=np.degrees(_column(lon, n, np.float64, "lon")),
        altitude=_column(alt, n, np.float64, "alt"),
        position_covariance=cov,
        position_covariance_type=_column(ctype, n, np.uint8, "position_covariance_type"),
    )


def navsatfix_fields(
    stream: Stream,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    position_covariance: ArrayLike | None = None,
    position_covariance_type: int | None = None,
) -> NavSatFixFields:
    """NavSatFix (truth) fields of a stream, m = 0..M: geodetic position of ``r^E(t_m)``."""
    return _navsatfix_fields(
        stream,
        _Truth(stream),
        frame_id,
        position_covariance=position_covariance,
        position_covariance_type=position_covariance_type,
    )


def _navsatfix_fields(
    stream: Stream,
    truth: _Truth,
    frame_id: str,
    *,
    position_covariance: ArrayLike | None = None,
    position_covariance_type: int | None = None,
) -> NavSatFixFields:
    lat, lon, alt = truth.geodetic
    return navsatfix_fields_from_geodetic(
        stream.stamps_ns,
        lat,
        lon,
        alt,
        frame_id,
        position_covariance=position_covariance,
        position_covariance_type=position_covariance_type,
    )


class StreamFields(NamedTuple):
    """Odometry, NavSatFix and Imu fields of one stream (None where not requested)."""

    odometry: OdometryFields | None
    navsatfix: NavSatFixFields | None
    imu: ImuFields | None


def stream_fields(
    stream: Stream,
    body_frame: str = DEFAULT_BODY_FRAME,
    earth_frame: str = EARTH_FRAME,
    *,
    odometry: bool = True,
    navsatfix: bool = True,
    imu: bool = True,
    imu_kwargs: Mapping[str, object] | None = None,
) -> StreamFields:
    """The :func:`odometry_fields`, :func:`navsatfix_fields` and :func:`imu_fields` of a stream.

    Equal, bit for bit, to the three calls with default covariances (``imu_kwargs`` are passed
    to :func:`imu_fields`), but the E0 → E conversion and the geodetic conversion are computed
    once for all three.
    """
    truth = _Truth(stream)
    kw: dict[str, Any] = dict(imu_kwargs or {})
    return StreamFields(
        _odometry_fields(stream, truth, body_frame, earth_frame) if odometry else None,
        _navsatfix_fields(stream, truth, body_frame) if navsatfix else None,
        _imu_fields(stream, truth, body_frame, **kw) if imu else None,
    )


def clock_fields(stamps_ns: ArrayLike) -> ClockFields:
    """``rosgraph_msgs/Clock`` fields (simulated time ``stamps_ns``)."""
    return ClockFields(stamps_ns=_stamps(stamps_ns))


def vector3_stamped_fields(
    stamps_ns: ArrayLike, vector: ArrayLike, frame_id: str
) -> Vector3StampedFields:
    """``geometry_msgs/Vector3Stamped`` fields (e.g. navigator errors, NED; interface.md §4)."""
    t = _stamps(stamps_ns)
    return Vector3StampedFields(
        stamps_ns=t, frame_id=frame_id, vector=_rows(vector, t.shape[0], 3, "vector")
    )


# --------------------------------------------------------------------------------------------
# Message fields -> core arrays (inverses)
# --------------------------------------------------------------------------------------------


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


def imu_increments(imu: ImuFields, period_ns: int | None = None) -> ImuIncrements:
    """Δα, Δv (FRD) of Imu messages: ``FRD(angular_velocity) T``, ``FRD(linear_acceleration) T``.

    T is ``period_ns`` or the (uniform) spacing of the stamps (docs/interface.md §2). ``x / T * T``
    equals
    ``x`` to 1 ulp (not always bit for bit).
    """
    t = _stamps(imu.stamps_ns)
    p = _uniform_period(t, "imu") if period_ns is None else int(period_ns)
    T = p * 1e-9
    return ImuIncrements(
        t,
        p,
        flu_to_frd(np.asarray(imu.angular_velocity, dtype=np.float64)) * T,
        flu_to_frd(np.asarray(imu.linear_acceleration, dtype=np.float64)) * T,
    )


def odometry_state(odom: OdometryFields) -> EarthState:
    """Earth-referenced state (FRD body) of Odometry messages; inverse of
    :func:`odometry_fields_from_ecef` (to rounding of the quaternion)."""
    c = matmul33(dcm_from_quat_ros(odom.orientation), C_FRD_TO_FLU)
    v_b = flu_to_frd(np.asarray(odom.twist_linear, dtype=np.float64))
    return EarthState(
        _stamps(odom.stamps_ns),
        np.asarray(odom.position, dtype=np.float64),
        (c @ v_b[..., None])[..., 0],
        c,
        flu_to_frd(np.asarray(odom.twist_angular, dtype=np.float64)),
    )


def navsatfix_geodetic(fix: NavSatFixFields) -> tuple[I64, F64, F64, F64]:
    """``(stamps_ns, lat, lon, alt)`` with lat/lon in rad, alt in m, of NavSatFix messages."""
    return (
        _stamps(fix.stamps_ns),
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
    message m (m = 1..M). Used to check the exactness rule (docs/interface.md §3) on a written bag;
    the E → E0
    and quaternion round trips cost ~1e-9 m and ~1e-16 rad, far below the rule's tolerances.
    ``e0_epoch_ns``: the instant E0 coincides with ECEF (default: the first Odometry stamp);
    a window of a longer stream passes the stream's start so E0 stays the same frame.
    """
    t_odom = _stamps(odom.stamps_ns)
    t_imu = _stamps(imu.stamps_ns)
    if t_odom.shape[0] != t_imu.shape[0] + 1 or not np.array_equal(t_odom[1:], t_imu):
        raise ValueError("Imu stamps must equal the Odometry stamps of cycles 1..M")
    if t_imu.shape[0]:
        period = _uniform_period(t_odom, "odometry")
    else:
        raise ValueError("need at least one Imu message to rebuild a stream")
    inc = imu_increments(imu, period)
    st = odometry_state(odom)
    epoch = int(t_odom[0]) if e0_epoch_ns is None else int(e0_epoch_ns)
    t = (t_odom - epoch) * 1e-9
    r0, v0, c0 = ecef_state_to_e0(t, st.r_e, st.v_e, st.c_b_e)
    assert c0 is not None
    return Stream(
        e0_epoch_ns=epoch,
        t0_ns=int(t_odom[0]),
        period_ns=period,
        dalpha=inc.dalpha,
        dv=inc.dv,
        c_b_e0=c0,
        v_e0=v0,
        r_e0=r0,
        gravity_model=gravity_model,
    )


# --------------------------------------------------------------------------------------------
# TF, map-frame odometry and increment messages (docs/interface.md, "Frames and TF")
# --------------------------------------------------------------------------------------------

#: REP-105 frame ids of the TF tree: ``earth → map → base_link`` (docs/interface.md).
MAP_FRAME = "map"
BASE_LINK_FRAME = "base_link"


@dataclass(frozen=True, eq=False)
class TFMessageFields(_Fields):
    """``tf2_msgs/msg/TFMessage`` of N messages, each holding the same K transforms.

    Every transform of message i carries ``stamps_ns[i]``; transform k goes from
    ``frame_ids[k]`` (parent) to ``child_frame_ids[k]``. ``translation`` (N, K, 3) m is the child
    origin in parent axes, ``rotation`` (N, K, 4) ``x, y, z, w`` the child's attitude relative to
    the parent (``v^parent = R(q) v^child``).
    """

    stamps_ns: I64
    frame_ids: tuple[str, ...]
    child_frame_ids: tuple[str, ...]
    translation: F64
    rotation: F64

    def rows(self, start: int, stop: int) -> TFMessageFields:
        """Messages ``start..stop-1`` (views)."""
        return TFMessageFields(
            self.stamps_ns[start:stop],
            self.frame_ids,
            self.child_frame_ids,
            self.translation[start:stop],
            self.rotation[start:stop],
        )

    def append(self, other: TFMessageFields) -> TFMessageFields:
        """This container followed by ``other`` (same frame ids)."""
        if (self.frame_ids, self.child_frame_ids) != (other.frame_ids, other.child_frame_ids):
            raise ValueError("TFMessageFields: different frame ids")
        return TFMessageFields(
            np.concatenate([self.stamps_ns, other.stamps_ns]),
            self.frame_ids,
            self.child_frame_ids,
            np.concatenate([self.translation, other.translation]),
            np.concatenate([self.rotation, other.rotation]),
        )

    def check(self) -> None:
        """Validate shapes and frame id counts; raises ValueError naming the field."""
        n, k = len(self), len(self.frame_ids)
        if len(self.child_frame_ids) != k:
            raise ValueError("TFMessageFields: frame_ids and child_frame_ids differ in length")
        for name, width in (("translation", 3), ("rotation", 4)):
            a = np.asarray(getattr(self, name))
            if a.shape != (n, k, width):
                raise ValueError(
                    f"TFMessageFields.{name}: expected shape {(n, k, width)}, got {a.shape}"
                )


@dataclass(frozen=True, eq=False)
class QuaternionStampedFields(_Fields):
    """``geometry_msgs/msg/QuaternionStamped`` of N messages: ``quaternion`` (N, 4) x, y, z, w."""

    stamps_ns: I64
    frame_id: str
    quaternion: F64


def tf_message_fields(
    stamps_ns: ArrayLike,
    frame_ids: tuple[str, ...] | list[str],
    child_frame_ids: tuple[str, ...] | list[str],
    translation: ArrayLike,
    c_child_parent: ArrayLike,
) -> TFMessageFields:
    """TFMessage fields from translations (N, K, 3) m and DCMs ``C_child^parent`` (N, K, 3, 3).

    Quaternions by :func:`quat_ros_from_dcm` (``w >= 0``).
    """
    t = _stamps(stamps_ns)
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
    t = _stamps(stamps_ns)
    return QuaternionStampedFields(t, frame_id, _rows(quaternion, t.shape[0], 4, "quaternion"))


def increment_fields(
    imu: ImuFields, period_ns: int
) -> tuple[Vector3StampedFields, QuaternionStampedFields]:
    """Δv and Δq messages of Imu messages, as Xsens / SBG style drivers publish them.

    ``Δv = linear_acceleration · T`` (m/s, FLU; the generator's Δv to 1 ulp) and ``Δq`` = the
    quaternion of the rotation vector ``Δα = angular_velocity · T`` (FLU;
    ``(x, y, z, w) = (sin(θ/2) Δα/θ, cos(θ/2))``, θ = |Δα|), T = ``period_ns`` (the stream's
    cycle). Both in the Imu's frame and stamped like it (``t_m``, end of the cycle).
    """
    t = _stamps(imu.stamps_ns)
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
    cov = np.asarray(odom.pose_covariance)
    if cov.shape[0] and cov.strides[0] == 0 and (not cov[0].any() or cov[0, 0] == -1.0):
        pose_cov = cov  # unknown / not provided: unchanged (broadcast view)
    else:
        rot = np.zeros((6, 6))
        rot[:3, :3] = rot[3:, 3:] = c
        p = cov.reshape(-1, 6, 6)
        given = p[:, 0, 0] != -1.0
        out = p.copy()
        out[given] = rot @ p[given] @ rot.T
        pose_cov = out.reshape(-1, 36)
    return OdometryFields(
        stamps_ns=odom.stamps_ns,
        frame_id=map_frame,
        child_frame_id=odom.child_frame_id,
        position=pos,
        orientation=quat_ros_from_dcm(c @ c_flu_e),
        pose_covariance=pose_cov,
        twist_linear=odom.twist_linear,
        twist_angular=odom.twist_angular,
        twist_covariance=odom.twist_covariance,
    )
