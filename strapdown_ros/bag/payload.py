"""What a recorder needs to know about one serialized (CDR) payload: its true length and stamp.

Fast DDS delivers a payload whose length is not a multiple of 4 (``sensor_msgs/NavSatFix``: 133
bytes) with 1-3 zero bytes appended (RTPS submessages are 4-byte aligned and the reader takes
the payload length from the submessage). The CDR content is unchanged, but a bag that stores the
padded bytes is not byte-identical to the one ``strapdown-sim generate`` writes.
:class:`PayloadInspector` finds the true end of the CDR data by walking the message definition
(``rosbags`` Jazzy type store: strings, arrays, sequences, nested messages) and strips what
follows. Types whose serialization always ends 4-byte aligned (Imu, Odometry, Clock,
Vector3Stamped, ...) are never walked. It also reads the header stamp of messages that start
with a ``std_msgs/Header`` or a ``builtin_interfaces/Time``, and of messages that start with a
sequence of such messages (``tf2_msgs/TFMessage``: its first transform's stamp), for the bag log
time (docs/interface.md §2).

Plain CDR (XCDR1, little or big endian) is supported; other encapsulations are left untouched.
No rclpy here.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

from strapdown_ros.bag.writer import TYPESTORE as _TYPESTORE

__all__ = ["PayloadError", "PayloadInspector"]

_HEADER = 4  # encapsulation: representation id (2 bytes) + options (2 bytes)
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4
_SIZES = {
    "bool": 1,
    "byte": 1,
    "char": 1,
    "int8": 1,
    "uint8": 1,
    "int16": 2,
    "uint16": 2,
    "int32": 4,
    "uint32": 4,
    "float32": 4,
    "int64": 8,
    "uint64": 8,
    "float64": 8,
}
_STAMPED_FIRST = {"std_msgs/msg/Header", "builtin_interfaces/msg/Time"}
_U32 = {"<": struct.Struct("<I"), ">": struct.Struct(">I")}
_STAMP = {"<": struct.Struct("<iI"), ">": struct.Struct(">iI")}

#: Walks one element from CDR position ``pos`` (relative to the origin after the header) and
#: returns the position after it. ``buf`` is the whole payload, ``u32`` reads a length.
Walk = Callable[[memoryview, int, Callable[[memoryview, int], tuple[int]]], int]


class PayloadError(ValueError):
    """A payload is shorter than its own CDR content says, or its type cannot be walked."""


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) & -n


def _primitive(size: int, count: int = 1) -> Walk:
    def walk(buf, pos, u32):
        return _align(pos, size) + size * count

    return walk


def _string(buf: memoryview, pos: int, u32) -> int:
    pos = _align(pos, 4)
    (n,) = u32(buf, _HEADER + pos)
    return pos + 4 + n


def _repeat(element: Walk, count: int) -> Walk:
    def walk(buf, pos, u32):
        for _ in range(count):
            pos = element(buf, pos, u32)
        return pos

    return walk


def _sequence(element: Walk, size: int | None) -> Walk:
    def walk(buf, pos, u32):
        pos = _align(pos, 4)
        (n,) = u32(buf, _HEADER + pos)
        pos += 4
        if size is not None:
            return _align(pos, size) + size * n if n else pos
        for _ in range(n):
            pos = element(buf, pos, u32)
        return pos

    return walk


def _element(node: tuple, cache: dict[str, Walk]) -> tuple[Walk, int | None]:
    """Walker of one field type and its primitive size (None for strings/messages)."""
    kind, arg = node
    if kind == _BASE:
        name = arg[0]
        if name == "string":
            return _string, None
        if name not in _SIZES:
            raise PayloadError(f"cannot walk field type {name!r}")
        return _primitive(_SIZES[name]), _SIZES[name]
    if kind == _NAME:
        return _message(arg, cache), None
    sub, count = arg
    element, size = _element(sub, cache)
    if kind == _ARRAY:
        return (_primitive(size, count) if size is not None else _repeat(element, count)), None
    if kind == _SEQUENCE:
        return _sequence(element, size), None
    raise PayloadError(f"cannot walk field node {node!r}")


def _message(msgtype: str, cache: dict[str, Walk]) -> Walk:
    if msgtype in cache:
        return cache[msgtype]
    try:
        _, fields = _TYPESTORE.fielddefs[msgtype]
    except KeyError:
        raise PayloadError(f"message type {msgtype!r} is not in the Jazzy type store") from None
    walks = [_element(node, cache)[0] for _, node in fields]

    def walk(buf, pos, u32):
        for w in walks:
            pos = w(buf, pos, u32)
        return pos

    cache[msgtype] = walk
    return walk


def _ends_aligned(node: tuple) -> bool:
    """True when a field's serialization always ends at a multiple of 4 (from the origin)."""
    kind, arg = node
    if kind == _BASE:
        return _SIZES.get(arg[0], 1) >= 4
    if kind == _NAME:
        _, fields = _TYPESTORE.fielddefs[arg]
        return bool(fields) and _ends_aligned(fields[-1][1])
    sub, count = arg
    if kind == _ARRAY:
        return count > 0 and _ends_aligned(sub)
    # a sequence ends with its uint32 length when empty, else with its last element
    return _ends_aligned(sub)


class PayloadInspector:
    """True CDR length and header stamp of payloads of one message type.

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Name`` of the ROS 2 Jazzy type store (``rosbags``).

    Raises
    ------
    PayloadError
        The type is unknown to the type store.
    """

    def __init__(self, msgtype: str) -> None:
        if msgtype not in _TYPESTORE.fielddefs:
            raise PayloadError(f"message type {msgtype!r} is not in the Jazzy type store")
        self.msgtype = msgtype
        _, fields = _TYPESTORE.fielddefs[msgtype]
        #: False when the CDR data always ends 4-byte aligned (no padding can be appended).
        self.may_be_padded = not (fields and _ends_aligned(fields[-1][1]))
        header_first = bool(fields) and _first_name(fields) is not None
        #: True when it starts with a sequence of such messages (TFMessage): the first one's.
        self.sequence_stamp = bool(fields) and not header_first and _first_sequence(fields)
        #: True when the message starts with a Header or a Time, or with a sequence of messages
        #: that do (see :meth:`stamp_ns`).
        self.has_stamp = header_first or self.sequence_stamp
        self._walk: Walk | None = None
        if self.may_be_padded:
            try:
                self._walk = _message(msgtype, {})
            except PayloadError:
                self._walk = None  # e.g. wstring: payloads are kept as delivered

    def true_length(self, payload: bytes | memoryview) -> int:
        """Length of the CDR data in ``payload`` (header included), trailing padding excluded."""
        n = len(payload)
        if self._walk is None or n % 4:
            return n
        buf = memoryview(payload)
        if n < _HEADER:
            raise PayloadError(f"{self.msgtype}: payload of {n} bytes has no CDR header")
        endian = _endianness(buf)
        if endian is None:
            return n
        u32 = _U32[endian].unpack_from
        try:
            end = _HEADER + self._walk(buf, 0, u32)
        except struct.error as exc:
            raise PayloadError(f"{self.msgtype}: payload of {n} bytes is truncated") from exc
        if end > n:
            raise PayloadError(
                f"{self.msgtype}: payload of {n} bytes is shorter than its CDR content ({end})"
            )
        return end

    def strip(self, payload: bytes | memoryview) -> bytes | memoryview:
        """``payload`` without trailing alignment padding (the same object when there is none)."""
        end = self.true_length(payload)
        return payload if end == len(payload) else payload[:end]

    def stamp_ns(self, payload: bytes | memoryview) -> int | None:
        """Header stamp (ns) of ``payload``; None when the type has none or it is negative."""
        if not self.has_stamp:
            return None
        offset = _HEADER + (4 if self.sequence_stamp else 0)  # a sequence: its uint32 count
        if len(payload) < offset + 8:
            return None
        endian = _endianness(memoryview(payload))
        if endian is None:
            return None
        if self.sequence_stamp and _U32[endian].unpack_from(payload, _HEADER)[0] == 0:
            return None
        sec, nanosec = _STAMP[endian].unpack_from(payload, offset)
        stamp = sec * 1_000_000_000 + nanosec
        return stamp if stamp >= 0 else None


def _first_name(fields: list) -> str | None:
    kind, arg = fields[0][1]
    return arg if kind == _NAME and arg in _STAMPED_FIRST else None


def _first_sequence(fields: list) -> bool:
    """Whether the first field is a sequence of messages starting with a Header or a Time."""
    kind, arg = fields[0][1]
    if kind != _SEQUENCE:
        return False
    (sub_kind, sub_arg), _ = arg
    if sub_kind != _NAME:
        return False
    _, sub_fields = _TYPESTORE.fielddefs[sub_arg]
    return bool(sub_fields) and _first_name(sub_fields) is not None


def _endianness(buf: memoryview) -> str | None:
    """'<' (CDR_LE), '>' (CDR_BE) or None (another encapsulation: not walked)."""
    if buf[0] != 0:
        return None
    return {1: "<", 0: ">"}.get(buf[1])
