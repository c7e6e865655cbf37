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

import numpy as np
from numpy.typing import NDArray

from strapdown_ros import messages as msg

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
    sec, nsec = msg.stamps_to_sec_nanosec(stamps_ns)
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


@dataclass(frozen=True)
class Part:
    """Where one field of a container lies in a layout: item ``item``, and for a float64 block
    the columns ``cols`` (``(start, stop)``, or one column index for a 1-D field; None: the
    whole item). ``dtype``: the container's dtype of a typed (non-float64) item."""

    field: str
    item: str = "d"
    cols: tuple[int, int] | int | None = None
    dtype: type | None = None


def _part_view(arr: np.ndarray, part: Part) -> np.ndarray:
    """The bytes of ``part`` in structured rows ``arr`` (a view, for writing)."""
    view = arr[part.item]
    if isinstance(part.cols, tuple):
        return view[:, part.cols[0] : part.cols[1]]
    return view if part.cols is None else view[:, part.cols]


def _pack_parts(parts: tuple[Part, ...], arr: np.ndarray, f: object) -> None:
    """Write each part's field of ``f`` into ``arr`` (:func:`_put`: zero constants skipped)."""
    for part in parts:
        _put(_part_view(arr, part), getattr(f, part.field))


def _unpack_parts(
    fields_type: type,
    strings: tuple[str, ...],
    parts: tuple[Part, ...],
    arr: np.ndarray,
    t: NDArray[np.int64],
    s: tuple[str, ...],
) -> object:
    """The container of rows ``arr``: stamps ``t``, string fields ``strings`` = ``s``, and every
    part as a contiguous array of its own (1-D fields and typed items copied)."""
    blocks: dict[str, np.ndarray] = {}
    values: dict[str, object] = {"stamps_ns": t, **dict(zip(strings, s, strict=True))}
    for part in parts:
        if part.dtype is not None:
            values[part.field] = arr[part.item].astype(part.dtype)
            continue
        if part.item not in blocks:
            blocks[part.item] = np.ascontiguousarray(arr[part.item])
        d = blocks[part.item]
        if isinstance(part.cols, tuple):
            values[part.field] = d[:, part.cols[0] : part.cols[1]]
        else:
            values[part.field] = d if part.cols is None else d[:, part.cols].copy()
    return fields_type(**values)


def _fixed(
    msgtype: str,
    fields_type: type,
    strings: tuple[str, ...],
    items: tuple[Item, ...],
    parts: tuple[Part, ...],
) -> Codec:
    """The codec of a type with one item list: the string fields ``strings`` (in item order)
    and the other fields at ``parts``."""
    return Codec(
        msgtype,
        fields_type,
        items,
        lambda f: tuple(getattr(f, name) for name in strings),
        functools.partial(_pack_parts, parts),
        functools.partial(_unpack_parts, fields_type, strings, parts),
    )


def _float_block(
    msgtype: str, fields_type: type, strings: tuple[str, ...], *widths: tuple[str, int]
) -> Codec:
    """The codec of a header type whose fields follow the strings as one float64 block ``d``:
    ``widths`` are (field, columns) in order, 0 columns meaning a 1-D field (one column)."""
    parts, start = [], 0
    for name, width in widths:
        parts.append(Part(name, cols=start if width == 0 else (start, start + width)))
        start += max(width, 1)
    items = (*_STAMP, *((name, "str", 1) for name in strings))
    if start:
        items += (("d", "<f8", start),)
    return _fixed(msgtype, fields_type, strings, items, tuple(parts))


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


def _tf_strings(f: msg.TFMessageFields) -> tuple[str, ...]:
    return tuple(s for pair in zip(f.frame_ids, f.child_frame_ids, strict=True) for s in pair)


def _pack_tf(arr: np.ndarray, f: msg.TFMessageFields) -> None:
    k = len(f.frame_ids)
    arr["count"] = k
    sec, nsec = msg.stamps_to_sec_nanosec(f.stamps_ns)
    for i in range(k):
        if i:
            arr[f"sec{i}"] = sec
            arr[f"nanosec{i}"] = nsec
        d = arr[f"d{i}"]
        d[:, 0:3] = f.translation[:, i]
        d[:, 3:7] = f.rotation[:, i]


def _unpack_tf(arr: np.ndarray, t: NDArray[np.int64], s: tuple[str, ...]) -> msg.TFMessageFields:
    k = len(s) // 2
    n = t.shape[0]
    tr = np.empty((n, k, 3))
    rot = np.empty((n, k, 4))
    for i in range(k):
        d = arr[f"d{i}"]
        tr[:, i] = d[:, 0:3]
        rot[:, i] = d[:, 3:7]
    return msg.TFMessageFields(t, tuple(s[0::2]), tuple(s[1::2]), tr, rot)


MSGTYPES: dict[str, Codec] = {
    IMU: _float_block(
        IMU, msg.ImuFields, ("frame_id",),
        ("orientation", 4), ("orientation_covariance", 9),
        ("angular_velocity", 3), ("angular_velocity_covariance", 9),
        ("linear_acceleration", 3), ("linear_acceleration_covariance", 9),
    ),
    ODOMETRY: _float_block(
        ODOMETRY, msg.OdometryFields, ("frame_id", "child_frame_id"),
        ("position", 3), ("orientation", 4), ("pose_covariance", 36),
        ("twist_linear", 3), ("twist_angular", 3), ("twist_covariance", 36),
    ),
    NAVSATFIX: _fixed(
        NAVSATFIX, msg.NavSatFixFields, ("frame_id",),
        (
            *_STAMP, ("frame_id", "str", 1), ("status", "<i1", 1), ("service", "<u2", 1),
            ("d", "<f8", 12), ("covariance_type", "<u1", 1),
        ),
        (
            Part("status", "status", dtype=np.int8), Part("service", "service", dtype=np.uint16),
            Part("latitude", cols=0), Part("longitude", cols=1), Part("altitude", cols=2),
            Part("position_covariance", cols=(3, 12)),
            Part("position_covariance_type", "covariance_type", dtype=np.uint8),
        ),
    ),
    CLOCK: _float_block(CLOCK, msg.ClockFields, ()),
    VECTOR3_STAMPED: _float_block(
        VECTOR3_STAMPED, msg.Vector3StampedFields, ("frame_id",), ("vector", 3)
    ),
    # aiding sensors
    TWIST_WITH_COVARIANCE_STAMPED: _float_block(
        TWIST_WITH_COVARIANCE_STAMPED, msg.TwistWithCovarianceStampedFields, ("frame_id",),
        ("linear", 3), ("angular", 3), ("covariance", 36),
    ),
    FLUID_PRESSURE: _float_block(
        FLUID_PRESSURE, msg.FluidPressureFields, ("frame_id",),
        ("fluid_pressure", 0), ("variance", 0),
    ),
    MAGNETIC_FIELD: _float_block(
        MAGNETIC_FIELD, msg.MagneticFieldFields, ("frame_id",),
        ("magnetic_field", 3), ("magnetic_field_covariance", 9),
    ),
    # TF and increment topics (docs/interface.md)
    QUATERNION_STAMPED: _float_block(
        QUATERNION_STAMPED, msg.QuaternionStampedFields, ("frame_id",), ("quaternion", 4)
    ),
    TF_MESSAGE: Codec(
        TF_MESSAGE,
        msg.TFMessageFields,
        _tf_items(1),
        _tf_strings,  # type: ignore[arg-type]
        _pack_tf,  # type: ignore[arg-type]
        _unpack_tf,
        items_for=lambda f: _tf_items(len(f.frame_ids)),  # type: ignore[attr-defined]
        items_of_payload=_tf_items_of_payload,
    ),
}  # fmt: skip

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
        rows = fields.rows(start, stop)  # type: ignore[attr-defined]
        _fill(buf[: stop - start], layout, codec, rows)
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
