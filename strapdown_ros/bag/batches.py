"""Pre-serialized message batches: what ``generate`` writes and the nodes publish.

A :class:`Batch` holds the CDR payloads of one topic with their stamps. The bag writer and the
ROS nodes consume the same batches in the same :func:`merge_order`, which is how the offline
bag and the live topics carry identical messages (docs/interface.md §6). No rosbags or rclpy here.

Every stage's output is serialized by :func:`batch`, which is where outputs are checked, once
for all: a message holding a NaN or an infinity is never serialized (so never written nor
published), each stretch of them logged (:func:`finite_outputs`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.bag import cdr
from strapdown_ros.core.stream import Stream
from strapdown_ros.messages import (
    DEFAULT_BODY_FRAME,
    EARTH_FRAME,
    clock_fields,
    stream_fields,
)
from strapdown_ros.stages.intake import nonfinite_rows, stamp_span, stretches, without_rows

__all__ = [
    "Batch",
    "batch",
    "clock_batch",
    "finite_outputs",
    "header_stamps_ns",
    "merge_order",
    "stream_batches",
    "subset",
]

F = TypeVar("F")
#: Where :func:`batch` reports outputs it does not serialize when the caller gives no log.
_LOG = logging.getLogger("strapdown_ros.outputs")


class Batch(NamedTuple):
    """Pre-serialized messages of one topic: payloads[i] is logged at stamps_ns[i]."""

    topic: str
    msgtype: str
    stamps_ns: NDArray[np.int64]
    payloads: Sequence[bytes | memoryview]


def header_stamps_ns(b: Batch) -> NDArray[np.int64] | None:
    """The ``header.stamp`` (ns) of every message of ``b``, read from the CDR bytes without
    decoding (bytes 4-12, after the encapsulation header); None when a payload is too short
    to hold one (malformed: decode all and let the decoder say so)."""
    head = b"".join(bytes(p[4:12]) for p in b.payloads)
    if len(head) != 8 * len(b.payloads):
        return None
    raw = np.frombuffer(head, dtype=np.dtype([("sec", "<i4"), ("ns", "<u4")]))
    return raw["sec"].astype(np.int64) * 1_000_000_000 + raw["ns"].astype(np.int64)


def subset(b: Batch, need: NDArray[np.bool_]) -> Batch:
    """The messages of ``b`` where ``need`` is true (``b`` itself when that is all of them)."""
    keep = np.flatnonzero(need)
    if len(keep) == len(b.payloads):
        return b
    return Batch(b.topic, b.msgtype, np.asarray(b.stamps_ns)[keep],
                 [b.payloads[i] for i in keep])  # fmt: skip


def finite_outputs(topic: str, fields: F, log: Callable[[str], None] | None = None
                   ) -> tuple[F | None, NDArray[np.bool_] | None]:  # fmt: skip
    """``fields`` without its messages holding a NaN or an infinity (None: none is left) and
    the mask of those removed (None: none, the common case, checked in microseconds). Each
    stretch of removed messages is logged to ``log`` (default: the ``strapdown_ros.outputs``
    logger, error level), naming the topic and the stamps."""
    bad = nonfinite_rows(fields)
    if bad is None:
        return fields, None
    stamps = np.asarray(fields.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
    say = log if log is not None else _LOG.error
    for a, b in stretches(bad):
        say(f"{topic}: stamp {stamp_span(stamps[a : b + 1])}: a NaN or an infinity in the "
            "output; not published nor written (a defect upstream: please report it)")  # fmt: skip
    return without_rows(fields, bad), bad


def batch(topic: str, fields: object, *, log_ns: ArrayLike | None = None,
          log: Callable[[str], None] | None = None) -> Batch:  # fmt: skip
    """Serialize a field container (:mod:`strapdown_ros.messages`) into a :class:`Batch`,
    logged at its stamps (or at ``log_ns``), after :func:`finite_outputs` (``log``)."""
    msgtype = cdr.msgtype_of(fields)
    at = np.asarray(fields.stamps_ns if log_ns is None else log_ns,  # type: ignore[attr-defined]
                    dtype=np.int64)  # fmt: skip
    checked, bad = finite_outputs(topic, fields, log)
    if bad is not None:
        at = at[~bad]
    if checked is None:
        return Batch(topic, msgtype, at, [])
    return Batch(topic, msgtype, at, cdr.serialize(checked))


def stream_batches(
    stream: Stream,
    *,
    imu_topic: str | None = "/reference/imu",
    odom_topic: str | None = "/reference/odom",
    fix_topic: str | None = "/reference/fix",
    body_frame: str = DEFAULT_BODY_FRAME,
    earth_frame: str = EARTH_FRAME,
    imu_kwargs: Mapping[str, object] | None = None,
) -> list[Batch]:
    """Serialized Imu / Odometry / NavSatFix batches of a stream (a topic set to None is skipped).

    Order within equal stamps (as written by :meth:`BagWriter.write_batches`): odom, fix, imu.
    ``imu_kwargs`` are passed to :func:`~strapdown_ros.messages.imu_fields` (covariances,
    ``orientation=False`` for measured data).
    """
    f = stream_fields(
        stream,
        body_frame,
        earth_frame,
        odometry=bool(odom_topic),
        navsatfix=bool(fix_topic),
        imu=bool(imu_topic),
        imu_kwargs=imu_kwargs,
    )
    out = []
    if odom_topic and f.odometry is not None:
        out.append(batch(odom_topic, f.odometry))
    if fix_topic and f.navsatfix is not None:
        out.append(batch(fix_topic, f.navsatfix))
    if imu_topic and f.imu is not None:
        out.append(batch(imu_topic, f.imu))
    return out


def clock_batch(stamps_ns: ArrayLike, topic: str = "/clock") -> Batch:
    """``/clock`` batch publishing simulated time ``stamps_ns``."""
    return batch(topic, clock_fields(np.asarray(stamps_ns, dtype=np.int64)))


def merge_order(batches: Sequence[Batch]) -> Iterator[tuple[int, int, int]]:
    """Yield ``(batch index, message index, stamp_ns)`` of all messages in stamp order.

    The sort is stable: at equal stamps the order of ``batches`` (then of the messages within a
    batch) is kept, so odometry, fix and Imu of one cycle come in the order of
    :func:`stream_batches`.
    """
    if not batches:
        return
    stamps = [np.asarray(b.stamps_ns, dtype=np.int64) for b in batches]
    all_t = np.concatenate(stamps)
    which = np.concatenate([np.full(t.shape, i, dtype=np.int64) for i, t in enumerate(stamps)])
    index = np.concatenate([np.arange(t.shape[0]) for t in stamps])
    order = np.argsort(all_t, kind="stable")
    yield from zip(which[order].tolist(), index[order].tolist(), all_t[order].tolist(), strict=True)
