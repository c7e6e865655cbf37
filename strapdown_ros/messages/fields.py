"""Field containers: one array per message field for N messages (a struct of arrays).

A container is the numpy form of N messages of one type with constant frame ids; the bulk CDR
codec (:mod:`strapdown_ros.bag.cdr`) turns it into payloads and back. Quaternions are in ROS
order ``(x, y, z, w)``; covariances are row-major and follow REP-145 (zeros: unknown, element 0
= -1: not provided, :data:`COVARIANCE_NOT_PROVIDED`). This module also holds the validation the
constructors share (stamps, row shapes, covariance specs) and the ``builtin_interfaces/Time``
split of the stamps.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.array_types import F64, I64

__all__ = [
    "COVARIANCE_NOT_PROVIDED",
    "ClockFields",
    "FluidPressureFields",
    "ImuFields",
    "MagneticFieldFields",
    "NavSatFixFields",
    "OdometryFields",
    "QuaternionStampedFields",
    "TFMessageFields",
    "TwistWithCovarianceStampedFields",
    "Vector3StampedFields",
    "as_column",
    "as_rows",
    "as_stamps",
    "clock_fields",
    "covariance_rows",
    "stamps_to_sec_nanosec",
    "vector3_stamped_fields",
]

#: REP-145 "not provided": covariance element 0 set to -1 (the rest zero).
COVARIANCE_NOT_PROVIDED = "not_provided"

_NS = 1_000_000_000
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1



def _constant(value: object) -> bool:
    """Frame ids (a ``str``, or the tuples of TFMessage) hold one value for all N messages."""
    return isinstance(value, str | tuple)


class _Fields:
    """Shared methods of the field containers (frame ids constant, every other field N rows)."""

    def __len__(self) -> int:
        return int(np.shape(self.stamps_ns)[0])  # type: ignore[attr-defined]

    def equals(self, other: object) -> bool:
        """Exact equality of every field (arrays compared element-wise, bit for bit)."""
        if type(other) is not type(self):
            return False
        for f in fields(self):  # type: ignore[arg-type]
            a, b = getattr(self, f.name), getattr(other, f.name)
            if _constant(a) or _constant(b):
                if a != b:
                    return False
            elif not np.array_equal(np.asarray(a), np.asarray(b)):
                return False
        return True

    def rows(self, start: int, stop: int) -> Any:
        """Messages ``start..stop-1`` as a container of the same type (views, no copy)."""
        values = {}
        for f in fields(self):  # type: ignore[arg-type]
            a = getattr(self, f.name)
            values[f.name] = a if _constant(a) else a[start:stop]
        return type(self)(**values)

    def append(self, other: Any) -> Any:
        """This container followed by ``other`` (same type and frame ids)."""
        values = {}
        for f in fields(self):  # type: ignore[arg-type]
            a, b = getattr(self, f.name), getattr(other, f.name)
            if _constant(a):
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
            if f.name == "stamps_ns" or _constant(getattr(self, f.name)):
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
    """``geometry_msgs/msg/TwistWithCovarianceStamped`` of N messages (aiding sensors).

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


@dataclass(frozen=True, eq=False)
class QuaternionStampedFields(_Fields):
    """``geometry_msgs/msg/QuaternionStamped`` of N messages: ``quaternion`` (N, 4) x, y, z, w."""

    stamps_ns: I64
    frame_id: str
    quaternion: F64


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


# --------------------------------------------------------------------------------------------
# Validation shared by the constructors
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


def as_stamps(stamps_ns: ArrayLike) -> I64:
    """``stamps_ns`` as (N,) int64 ns since the epoch; ValueError unless a 1-D integer array."""
    t = np.asarray(stamps_ns)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError("stamps_ns must be a 1-D integer array (ns since the epoch)")
    return t.astype(np.int64, copy=False)


def as_rows(a: ArrayLike, n: int, width: int | tuple[int, ...], name: str) -> F64:
    """``a`` as an (n, width) float64 array (a tuple ``width``: (n, *width), e.g. (n, 3, 3) for
    matrices); ValueError naming ``name`` otherwise."""
    shape = (n, *width) if isinstance(width, tuple) else (n, width)
    a = np.asarray(a, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
    return a


def covariance_rows(spec: object, n: int, k: int, name: str) -> F64:
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


def as_column(value: ArrayLike, n: int, dtype: type, name: str) -> NDArray:
    """A scalar (broadcast, read-only) or an (n,) array as an (n,) column of ``dtype``."""
    a = np.asarray(value)
    if a.ndim == 0:
        return np.broadcast_to(a.astype(dtype), (n,))
    if a.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got {a.shape}")
    return a.astype(dtype)


# --------------------------------------------------------------------------------------------
# Constructors of the types without frame conversion
# --------------------------------------------------------------------------------------------


def clock_fields(stamps_ns: ArrayLike) -> ClockFields:
    """``rosgraph_msgs/Clock`` fields (simulated time ``stamps_ns``)."""
    return ClockFields(stamps_ns=as_stamps(stamps_ns))


def vector3_stamped_fields(
    stamps_ns: ArrayLike, vector: ArrayLike, frame_id: str
) -> Vector3StampedFields:
    """``geometry_msgs/Vector3Stamped`` fields (e.g. navigator errors, NED; interface.md §4)."""
    t = as_stamps(stamps_ns)
    return Vector3StampedFields(
        stamps_ns=t, frame_id=frame_id, vector=as_rows(vector, t.shape[0], 3, "vector")
    )
