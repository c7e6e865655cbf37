"""Bulk CDR codec of the project's fixed-layout messages (numpy, no per-message Python work).

ROS 2 serializes messages as plain CDR (XCDR1) little endian: a 4-byte encapsulation header
``00 01 00 00`` (CDR_LE, options 0) followed by the fields, each primitive aligned to its size
relative to the first byte *after* the header. A string is a ``uint32`` length (counting the
terminating NUL), the UTF-8 bytes and the NUL. There is no trailing padding.

With constant frame ids, every message of a topic has the same length and the same field
offsets, so N messages are one ``(N, size)`` byte matrix viewed through a numpy structured dtype:
the constant bytes (header, string lengths and contents) are stamped from a template row, the
variable fields are written column-wise, and padding stays zero exactly as ``rosbags`` writes it
(rclpy/Fast CDR leave padding uninitialized; both decode to the same fields). The payloads are
byte-identical to ``rosbags.typesys`` ``serialize_cdr`` of the ``ROS2_JAZZY`` store (tested).

Supported types: ``sensor_msgs/msg/Imu``, ``nav_msgs/msg/Odometry``,
``sensor_msgs/msg/NavSatFix``, ``rosgraph_msgs/msg/Clock``, ``geometry_msgs/msg/Vector3Stamped``;
for the aiding sensors ``geometry_msgs/msg/TwistWithCovarianceStamped``,
``sensor_msgs/msg/FluidPressure`` and ``sensor_msgs/msg/MagneticField``; for TF and the
increment topics ``tf2_msgs/msg/TFMessage`` (a fixed number K of transforms per topic: the
sequence length is part of the layout) and ``geometry_msgs/msg/QuaternionStamped``.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.messages import (
    ClockFields,
    FluidPressureFields,
    ImuFields,
    MagneticFieldFields,
    NavSatFixFields,
    OdometryFields,
    QuaternionStampedFields,
    TFMessageFields,
    TwistWithCovarianceStampedFields,
    Vector3StampedFields,
    stamps_to_sec_nanosec,
)

__all__ = [
    "CLOCK",
    "FLUID_PRESSURE",
    "IMU",
    "MAGNETIC_FIELD",
    "TWIST_WITH_COVARIANCE_STAMPED",
    "MSGTYPES",
    "NAVSATFIX",
    "ODOMETRY",
    "QUATERNION_STAMPED",
    "TF_MESSAGE",
    "VECTOR3_STAMPED",
    "CdrError",
    "deserialize",
    "msgtype_of",
    "serialize",
    "serialize_rows",
    "split_rows",
]

IMU = "sensor_msgs/msg/Imu"
TWIST_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/TwistWithCovarianceStamped"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
MAGNETIC_FIELD = "sensor_msgs/msg/MagneticField"
ODOMETRY = "nav_msgs/msg/Odometry"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
CLOCK = "rosgraph_msgs/msg/Clock"
QUATERNION_STAMPED = "geometry_msgs/msg/QuaternionStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"

#: CDR_LE representation identifier + zero options.
ENCAPSULATION = b"\x00\x01\x00\x00"
_HEADER = len(ENCAPSULATION)
_NS = 1_000_000_000


class CdrError(ValueError):
    """A payload does not match the layout the bulk codec expects."""


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------

#: One item of a message layout: (name, kind, count) with kind a numpy type code ('<f8', ...)
#: or "str" (a string; its value is given separately, in order of appearance).
Item = tuple[str, str, int]


@dataclass(frozen=True)
class Layout:
    """Byte layout of one message type with known strings (hence a fixed size)."""

    size: int  #: payload size in bytes, encapsulation header included
    dtype: np.dtype  #: structured dtype of the variable fields (explicit offsets)
    template: NDArray[np.uint8]  #: (size,) constant bytes: header, strings; zero elsewhere
    const_mask: NDArray[np.bool_]  #: (size,) bytes that must equal the template (not padding)
    strings: tuple[str, ...]


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) // n * n


def build_layout(items: Sequence[Item], strings: Sequence[str]) -> Layout:
    """Layout of ``items`` with string values ``strings`` (positions relative to the CDR origin).

    Layouts are cached (a live node decodes thousands of one-message batches per second with
    the same frame ids); the returned arrays are read-only.
    """
    return _cached_layout(tuple(items), tuple(strings))


@functools.lru_cache(maxsize=256)
def _cached_layout(items: tuple[Item, ...], strings: tuple[str, ...]) -> Layout:
    names: list[str] = []
    formats: list[object] = []
    offsets: list[int] = []
    template = bytearray(ENCAPSULATION)
    mask = bytearray(b"\x01" * _HEADER)
    pos = 0
    it = iter(strings)
    for name, kind, count in items:
        if kind == "str":
            text = next(it)
            data = text.encode("utf-8")
            if b"\x00" in data:
                raise CdrError(f"{name}: a ROS string cannot contain NUL")
            data += b"\x00"
            new = _align(pos, 4)
            chunk = b"\x00" * (new - pos) + struct.pack("<I", len(data)) + data
            template += chunk
            mask += b"\x00" * (new - pos) + b"\x01" * (4 + len(data))
            pos = new + 4 + len(data)
        else:
            dt = np.dtype(kind)
            new = _align(pos, dt.itemsize)
            names.append(name)
            formats.append(dt if count == 1 else (dt, (count,)))
            offsets.append(_HEADER + new)
            width = new - pos + dt.itemsize * count
            template += b"\x00" * width
            mask += b"\x00" * width
            pos = new + dt.itemsize * count
    size = _HEADER + pos
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": size})
    const_mask = np.frombuffer(bytes(mask), dtype=np.uint8).astype(bool)
    const_mask.flags.writeable = False  # shared through the cache
    return Layout(
        size=size,
        dtype=dtype,
        template=np.frombuffer(bytes(template), dtype=np.uint8),
        const_mask=const_mask,
        strings=tuple(strings),
    )


def _read_strings(payload: bytes | memoryview, items: Sequence[Item]) -> list[str]:
    """String values of one payload, walking ``items`` (strings only need their offsets)."""
    buf = memoryview(payload)
    if len(buf) < _HEADER:
        raise CdrError(f"payload of {len(buf)} bytes is shorter than the CDR header")
    if bytes(buf[:2]) != ENCAPSULATION[:2]:
        raise CdrError(
            f"unsupported CDR encapsulation {bytes(buf[:2]).hex()} (expected 0001, CDR_LE)"
        )
    pos = 0
    out = []
    for name, kind, count in items:
        if kind == "str":
            pos = _align(pos, 4)
            if _HEADER + pos + 4 > len(buf):
                raise CdrError(f"{name}: payload truncated")
            (n,) = struct.unpack_from("<I", buf, _HEADER + pos)
            start = _HEADER + pos + 4
            if n == 0 or start + n > len(buf) or buf[start + n - 1] != 0:
                raise CdrError(f"{name}: bad string length {n}")
            out.append(bytes(buf[start : start + n - 1]).decode("utf-8"))
            pos += 4 + n
        else:
            size = np.dtype(kind).itemsize
            pos = _align(pos, size) + size * count
    return out


# --------------------------------------------------------------------------------------------
# Per-type codecs
# --------------------------------------------------------------------------------------------

_STAMP: list[Item] = [("sec", "<i4", 1), ("nanosec", "<u4", 1)]


@dataclass(frozen=True)
class Codec:
    """How one message type maps between its field container and its layout."""

    msgtype: str
    fields_type: type
    items: tuple[Item, ...]
    strings: Callable[[object], tuple[str, ...]]
    pack: Callable[[np.ndarray, object], None]
    unpack: Callable[[np.ndarray, NDArray[np.int64], tuple[str, ...]], object]
    #: Layout items of a field container / of a payload, for types whose item list varies
    #: (TFMessage: one block per transform); None: ``items`` for every message.
    items_for: Callable[[object], tuple[Item, ...]] | None = None
    items_of_payload: Callable[[bytes | memoryview], tuple[Item, ...]] | None = None


def _stamps_from(arr: np.ndarray) -> NDArray[np.int64]:
    return arr["sec"].astype(np.int64) * _NS + arr["nanosec"].astype(np.int64)


def _put_stamps(arr: np.ndarray, stamps_ns: NDArray[np.int64]) -> None:
    sec, nsec = stamps_to_sec_nanosec(stamps_ns)
    arr["sec"] = sec
    arr["nanosec"] = nsec


def _put(dst: np.ndarray, src: object) -> None:
    """``dst[...] = src`` into a zero-initialized ``dst``.

    Skipped when ``src`` repeats one all-zero-bytes row (a broadcast view such as the constant
    covariances of ideal streams): those bytes are already zero. ``-0.0`` is not all-zero bytes.
    """
    a = np.asarray(src)
    if a.ndim and a.shape[0] and a.strides[0] == 0:
        if not np.ascontiguousarray(a[0]).view(np.uint8).any():
            return
    dst[...] = a


# The pack functions write into zero-initialized rows (see _blank).


def _pack_imu(arr: np.ndarray, f: ImuFields) -> None:
    d = arr["d"]
    _put(d[:, 0:4], f.orientation)
    _put(d[:, 4:13], f.orientation_covariance)
    _put(d[:, 13:16], f.angular_velocity)
    _put(d[:, 16:25], f.angular_velocity_covariance)
    _put(d[:, 25:28], f.linear_acceleration)
    _put(d[:, 28:37], f.linear_acceleration_covariance)


def _unpack_imu(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> ImuFields:
    d = np.ascontiguousarray(arr["d"])
    return ImuFields(
        t, s[0], d[:, 0:4], d[:, 4:13], d[:, 13:16], d[:, 16:25], d[:, 25:28], d[:, 28:37]
    )


def _pack_odom(arr: np.ndarray, f: OdometryFields) -> None:
    d = arr["d"]
    _put(d[:, 0:3], f.position)
    _put(d[:, 3:7], f.orientation)
    _put(d[:, 7:43], f.pose_covariance)
    _put(d[:, 43:46], f.twist_linear)
    _put(d[:, 46:49], f.twist_angular)
    _put(d[:, 49:85], f.twist_covariance)


def _unpack_odom(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> OdometryFields:
    d = np.ascontiguousarray(arr["d"])
    return OdometryFields(
        t, s[0], s[1], d[:, 0:3], d[:, 3:7], d[:, 7:43], d[:, 43:46], d[:, 46:49], d[:, 49:85]
    )


def _pack_fix(arr: np.ndarray, f: NavSatFixFields) -> None:
    _put(arr["status"], f.status)
    _put(arr["service"], f.service)
    d = arr["d"]
    d[:, 0] = f.latitude
    d[:, 1] = f.longitude
    d[:, 2] = f.altitude
    _put(d[:, 3:12], f.position_covariance)
    _put(arr["covariance_type"], f.position_covariance_type)


def _unpack_fix(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> NavSatFixFields:
    d = np.ascontiguousarray(arr["d"])
    return NavSatFixFields(
        t,
        s[0],
        arr["status"].astype(np.int8),
        arr["service"].astype(np.uint16),
        d[:, 0].copy(),
        d[:, 1].copy(),
        d[:, 2].copy(),
        d[:, 3:12],
        arr["covariance_type"].astype(np.uint8),
    )


def _pack_vec(arr: np.ndarray, f: Vector3StampedFields) -> None:
    arr["d"] = f.vector


def _unpack_vec(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> Vector3StampedFields:
    return Vector3StampedFields(t, s[0], np.ascontiguousarray(arr["d"]))


def _pack_twist(arr: np.ndarray, f: TwistWithCovarianceStampedFields) -> None:
    d = arr["d"]
    _put(d[:, 0:3], f.linear)
    _put(d[:, 3:6], f.angular)
    _put(d[:, 6:42], f.covariance)


def _unpack_twist(
    arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]
) -> TwistWithCovarianceStampedFields:
    d = np.ascontiguousarray(arr["d"])
    return TwistWithCovarianceStampedFields(t, s[0], d[:, 0:3], d[:, 3:6], d[:, 6:42])


def _pack_pressure(arr: np.ndarray, f: FluidPressureFields) -> None:
    d = arr["d"]
    d[:, 0] = f.fluid_pressure
    d[:, 1] = f.variance


def _unpack_pressure(
    arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]
) -> FluidPressureFields:
    d = np.ascontiguousarray(arr["d"])
    return FluidPressureFields(t, s[0], d[:, 0].copy(), d[:, 1].copy())


def _pack_mag(arr: np.ndarray, f: MagneticFieldFields) -> None:
    d = arr["d"]
    _put(d[:, 0:3], f.magnetic_field)
    _put(d[:, 3:12], f.magnetic_field_covariance)


def _unpack_mag(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> MagneticFieldFields:
    d = np.ascontiguousarray(arr["d"])
    return MagneticFieldFields(t, s[0], d[:, 0:3], d[:, 3:12])


def _pack_quat(arr: np.ndarray, f: QuaternionStampedFields) -> None:
    arr["d"] = f.quaternion


def _unpack_quat(
    arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]
) -> QuaternionStampedFields:
    return QuaternionStampedFields(t, s[0], np.ascontiguousarray(arr["d"]))


def _tf_items(k: int) -> tuple[Item, ...]:
    """TFMessage with k transforms: sequence length, then per transform its header (stamp,
    frame id), child frame id, translation and rotation (7 float64).

    Transform 0's stamp is ``sec``/``nanosec`` (the message stamp), the others
    ``sec{i}``/``nanosec{i}``.
    """
    items: list[Item] = [("count", "<u4", 1)]
    for i in range(k):
        sfx = "" if i == 0 else str(i)
        items += [
            (f"sec{sfx}", "<i4", 1),
            (f"nanosec{sfx}", "<u4", 1),
            (f"frame_id{i}", "str", 1),
            (f"child_frame_id{i}", "str", 1),
            (f"d{i}", "<f8", 7),
        ]
    return tuple(items)


def _tf_items_of_payload(payload: bytes | memoryview) -> tuple[Item, ...]:
    buf = memoryview(payload)
    if len(buf) < _HEADER + 4:
        raise CdrError(f"TFMessage payload of {len(buf)} bytes is too short")
    (k,) = struct.unpack_from("<I", buf, _HEADER)
    if not 1 <= k <= 4096:
        raise CdrError(f"TFMessage with {k} transforms is not supported (1..4096)")
    return _tf_items(int(k))


def _tf_strings(f: TFMessageFields) -> tuple[str, ...]:
    return tuple(s for pair in zip(f.frame_ids, f.child_frame_ids, strict=True) for s in pair)


def _pack_tf(arr: np.ndarray, f: TFMessageFields) -> None:
    k = len(f.frame_ids)
    arr["count"] = k
    sec, nsec = stamps_to_sec_nanosec(f.stamps_ns)
    for i in range(k):
        if i:
            arr[f"sec{i}"] = sec
            arr[f"nanosec{i}"] = nsec
        d = arr[f"d{i}"]
        d[:, 0:3] = f.translation[:, i]
        d[:, 3:7] = f.rotation[:, i]


def _unpack_tf(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> TFMessageFields:
    k = len(s) // 2
    n = t.shape[0]
    tr = np.empty((n, k, 3))
    rot = np.empty((n, k, 4))
    for i in range(k):
        d = arr[f"d{i}"]
        tr[:, i] = d[:, 0:3]
        rot[:, i] = d[:, 3:7]
    return TFMessageFields(t, tuple(s[0::2]), tuple(s[1::2]), tr, rot)


MSGTYPES: dict[str, Codec] = {
    IMU: Codec(
        IMU,
        ImuFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 37)),
        lambda f: (f.frame_id,),
        _pack_imu,
        _unpack_imu,  # type: ignore[attr-defined]
    ),
    ODOMETRY: Codec(
        ODOMETRY,
        OdometryFields,
        (*_STAMP, ("frame_id", "str", 1), ("child_frame_id", "str", 1), ("d", "<f8", 85)),
        lambda f: (f.frame_id, f.child_frame_id),
        _pack_odom,
        _unpack_odom,  # type: ignore
    ),
    NAVSATFIX: Codec(
        NAVSATFIX,
        NavSatFixFields,
        (
            *_STAMP,
            ("frame_id", "str", 1),
            ("status", "<i1", 1),
            ("service", "<u2", 1),
            ("d", "<f8", 12),
            ("covariance_type", "<u1", 1),
        ),
        lambda f: (f.frame_id,),
        _pack_fix,
        _unpack_fix,  # type: ignore[attr-defined]
    ),
    CLOCK: Codec(
        CLOCK,
        ClockFields,
        tuple(_STAMP),
        lambda f: (),
        lambda arr, f: None,
        lambda arr, t, s: ClockFields(t),
    ),
    VECTOR3_STAMPED: Codec(
        VECTOR3_STAMPED,
        Vector3StampedFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 3)),
        lambda f: (f.frame_id,),
        _pack_vec,
        _unpack_vec,  # type: ignore[attr-defined]
    ),
    # aiding sensors (issue 16)
    TWIST_WITH_COVARIANCE_STAMPED: Codec(
        TWIST_WITH_COVARIANCE_STAMPED,
        TwistWithCovarianceStampedFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 42)),
        lambda f: (f.frame_id,),
        _pack_twist,
        _unpack_twist,  # type: ignore[arg-type]
    ),
    FLUID_PRESSURE: Codec(
        FLUID_PRESSURE,
        FluidPressureFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 2)),
        lambda f: (f.frame_id,),
        _pack_pressure,
        _unpack_pressure,  # type: ignore[arg-type]
    ),
    MAGNETIC_FIELD: Codec(
        MAGNETIC_FIELD,
        MagneticFieldFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 12)),
        lambda f: (f.frame_id,),
        _pack_mag,
        _unpack_mag,  # type: ignore[arg-type]
    ),
    # TF and increment topics (docs/interface.md)
    QUATERNION_STAMPED: Codec(
        QUATERNION_STAMPED,
        QuaternionStampedFields,
        (*_STAMP, ("frame_id", "str", 1), ("d", "<f8", 4)),
        lambda f: (f.frame_id,),
        _pack_quat,  # type: ignore[arg-type]
        _unpack_quat,
    ),
    TF_MESSAGE: Codec(
        TF_MESSAGE,
        TFMessageFields,
        _tf_items(1),
        _tf_strings,  # type: ignore[arg-type]
        _pack_tf,  # type: ignore[arg-type]
        _unpack_tf,
        items_for=lambda f: _tf_items(len(f.frame_ids)),  # type: ignore[attr-defined]
        items_of_payload=_tf_items_of_payload,
    ),
}

_BY_FIELDS = {c.fields_type: c for c in MSGTYPES.values()}


def msgtype_of(fields: object) -> str:
    """ROS message type name (``pkg/msg/Name``) of a field container."""
    try:
        return _BY_FIELDS[type(fields)].msgtype
    except KeyError:
        raise TypeError(f"no CDR codec for {type(fields).__name__}") from None


def layout_of(msgtype: str, strings: Sequence[str]) -> Layout:
    """Layout of ``msgtype`` with the given string values (frame ids in field order)."""
    codec = _codec(msgtype)
    if codec.items_for is not None:  # TFMessage: one (frame_id, child_frame_id) per transform
        return build_layout(_tf_items(len(strings) // 2), strings)
    return build_layout(codec.items, strings)


def _codec(msgtype: str) -> Codec:
    try:
        return MSGTYPES[msgtype]
    except KeyError:
        raise CdrError(
            f"no bulk CDR codec for {msgtype!r} (supported: {', '.join(MSGTYPES)})"
        ) from None


# --------------------------------------------------------------------------------------------
# Bulk serialize / deserialize
# --------------------------------------------------------------------------------------------


#: Rows per block of :func:`serialize`: about 512 KiB, so that a block is still in cache when
#: its rows are copied out into ``bytes``.
_BLOCK_BYTES = 1 << 19


def _prepare(fields: object) -> tuple[Codec, Layout]:
    codec = _BY_FIELDS.get(type(fields))
    if codec is None:
        raise TypeError(f"no CDR codec for {type(fields).__name__}")
    fields.check()  # type: ignore[attr-defined]
    items = codec.items if codec.items_for is None else codec.items_for(fields)
    return codec, build_layout(items, codec.strings(fields))


def _blank(n: int, layout: Layout) -> NDArray[np.uint8]:
    """``(n, size)`` rows holding the template: zero except the constant bytes.

    Padding and the fields that :func:`_put` skips (all-zero constants) need no further writes;
    the pack functions rely on this.
    """
    raw = np.zeros((n, layout.size), dtype=np.uint8)
    # Constant bytes (header, string lengths and contents) up to the last non-zero one; field
    # bytes in that span are zero in the template and are written by the pack functions.
    prefix = int(np.flatnonzero(layout.template)[-1]) + 1
    raw[:, :prefix] = layout.template[:prefix]
    return raw


def _fill(raw: NDArray[np.uint8], layout: Layout, codec: Codec, fields: object) -> None:
    """Write the variable fields of ``fields`` into :func:`_blank` rows ``raw`` (same length)."""
    arr = raw.view(layout.dtype)[:, 0]
    _put_stamps(arr, fields.stamps_ns)  # type: ignore[attr-defined]
    codec.pack(arr, fields)


def _rows_of(fields: object, start: int, stop: int) -> object:
    """Field container of messages ``start:stop`` (views; strings kept)."""
    kw = {}
    for f in dataclass_fields(fields):  # type: ignore[arg-type]
        v = getattr(fields, f.name)
        kw[f.name] = v if isinstance(v, str | tuple) else v[start:stop]  # tuple: TF frame ids
    return type(fields)(**kw)


def serialize_rows(fields: object) -> NDArray[np.uint8]:
    """Payloads of all messages of a field container as one ``(N, size)`` uint8 matrix."""
    codec, layout = _prepare(fields)
    raw = _blank(len(fields), layout)  # type: ignore[arg-type]
    _fill(raw, layout, codec, fields)
    return raw


def split_rows(raw: NDArray[np.uint8]) -> list[bytes]:
    """One ``bytes`` object per row of a payload matrix."""
    raw = np.ascontiguousarray(raw, dtype=np.uint8)
    # An unstructured void item converts to bytes (all of them: no NUL stripping as with "S").
    return raw.view(f"V{raw.shape[1]}")[:, 0].tolist()


def serialize(fields: object) -> list[bytes]:
    """CDR payloads (``bytes``, encapsulation header included) of N messages of a field container.

    Byte-identical to ``rosbags`` ``Typestore.serialize_cdr`` (ROS2_JAZZY) of each message.
    Equal to ``split_rows(serialize_rows(fields))``, done in cache-sized blocks of rows reusing
    one buffer (the constant bytes and skipped zero fields are the same in every block).
    """
    codec, layout = _prepare(fields)
    n = len(fields)  # type: ignore[arg-type]
    block = max(1, _BLOCK_BYTES // layout.size)
    if n <= block:
        raw = _blank(n, layout)
        _fill(raw, layout, codec, fields)
        return split_rows(raw)
    buf = _blank(block, layout)
    items = buf.view(f"V{layout.size}")[:, 0]
    out: list[bytes] = []
    for start in range(0, n, block):
        stop = min(start + block, n)
        _fill(buf[: stop - start], layout, codec, _rows_of(fields, start, stop))
        out += items[: stop - start].tolist()
    return out


def deserialize(msgtype: str, payloads: Sequence[bytes | memoryview]) -> object:
    """Field container of N CDR payloads of ``msgtype`` (inverse of :func:`serialize`).

    All payloads must carry the same strings (frame ids); up to 3 trailing padding bytes per
    payload are tolerated (some middlewares pad to 4). Padding content is ignored. Raises
    :class:`CdrError` when a payload does not fit the layout.
    """
    codec = _codec(msgtype)
    n = len(payloads)
    if n == 0:
        layout = build_layout(codec.items, [""] * sum(k == "str" for _, k, _ in codec.items))
        arr = np.zeros(0, dtype=layout.dtype)
        return codec.unpack(arr, np.zeros(0, np.int64), layout.strings)
    items = codec.items
    if codec.items_of_payload is not None:
        items = codec.items_of_payload(payloads[0])
    strings = _read_strings(payloads[0], items)
    layout = build_layout(items, strings)
    size = layout.size
    lengths = np.fromiter(map(len, payloads), dtype=np.int64, count=n)
    if np.all(lengths == size):
        buf = b"".join(payloads)
    elif np.all((lengths >= size) & (lengths < size + 4)):
        buf = b"".join(bytes(memoryview(p)[:size]) for p in payloads)
    else:
        bad = int(np.flatnonzero((lengths < size) | (lengths >= size + 4))[0])
        raise CdrError(
            f"{msgtype}: message {bad} has {lengths[bad]} bytes, expected {size} (all messages of "
            f"a topic must carry the frame ids {strings!r} of the first one)"
        )
    raw = np.frombuffer(buf, dtype=np.uint8).reshape(n, size)
    const = layout.const_mask.copy()
    const[2:4] = False  # encapsulation options are not checked
    mismatch = np.any(raw[:, const] != layout.template[const], axis=1)
    if mismatch.any():
        rows = np.flatnonzero(mismatch)
        raise CdrError(
            f"{msgtype}: message {int(rows[0])} differs from message 0 in its encapsulation or "
            f"strings (frame ids {strings!r}); mixed frame ids are not supported"
        )
    arr = raw.view(layout.dtype)[:, 0]
    return codec.unpack(arr, _stamps_from(arr), tuple(strings))
