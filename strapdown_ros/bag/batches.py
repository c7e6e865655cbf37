"""Pre-serialized message batches: what ``generate`` writes and the nodes publish.

A :class:`Batch` holds the CDR payloads of one topic with their stamps. The bag writer and the
ROS nodes consume the same batches in the same :func:`merge_order`, which is how the offline
bag and the live topics carry identical messages (docs/interface.md §6). No rosbags or rclpy here.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import NamedTuple

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

__all__ = ["Batch", "batch", "clock_batch", "merge_order", "stream_batches"]


class Batch(NamedTuple):
    """Pre-serialized messages of one topic: payloads[i] is logged at stamps_ns[i]."""

    topic: str
    msgtype: str
    stamps_ns: NDArray[np.int64]
    payloads: Sequence[bytes | memoryview]


def batch(topic: str, fields: object) -> Batch:
    """Serialize a field container (:mod:`strapdown_ros.messages`) into a :class:`Batch`."""
    return Batch(
        topic,
        cdr.msgtype_of(fields),
        np.asarray(fields.stamps_ns, dtype=np.int64),  # type: ignore[attr-defined]
        cdr.serialize(fields),
    )


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
