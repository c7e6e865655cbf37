"""The recorder's bookkeeping without ROS: serialized messages in, a rosbag2 directory out.

:class:`Recording` takes each received payload (``bytes`` from a raw subscription), strips the
middleware's trailing alignment padding (:class:`~strapdown_ros.bag.payload.PayloadInspector`),
chooses its log time — the header stamp, as ``strapdown-sim generate`` does (docs/interface.md §2),
or the
receive time — and appends it to an :class:`~strapdown_ros.bag.incremental.IncrementalBagWriter`.
It counts messages per topic and flushes the bag every ``flush_period_s``. A topic enters the
bag with its first message (so that a bag holds only topics that carried data, as ``generate``'s
do). The ``bag_recorder`` node (:mod:`strapdown_ros.nodes.bag_recorder`) adds discovery,
subscriptions and signals around it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from rosbags.interfaces import Qos

from strapdown_ros.bag.incremental import IncrementalBagWriter
from strapdown_ros.bag.payload import PayloadError, PayloadInspector

__all__ = ["LOG_TIMES", "Recording", "TopicStats"]

#: ``header``: the message's header stamp (receive time for types without one); ``receive``.
LOG_TIMES = ("header", "receive")

#: ``handler(payload, receive_ns)``: record one message of a topic.
Handler = Callable[[bytes | memoryview, int], None]


@dataclass
class TopicStats:
    """Per-topic figures of a recording."""

    topic: str
    msgtype: str
    count: int = 0  #: messages written
    padded: int = 0  #: payloads that arrived with trailing padding (stripped)
    bytes: int = 0  #: payload bytes written
    receive_time_logs: int = 0  #: messages logged at their receive time (no usable stamp)
    malformed: int = 0  #: payloads shorter than their CDR content says (kept as received)
    first_log_ns: int = 0  #: log time of the first message
    first_receive_ns: int = 0  #: receive time of the first message
    last_log_ns: int = 0  #: log time of the last message


class Recording:
    """Writes received payloads into a bag, with per-topic counts and periodic flushes.

    Parameters
    ----------
    writer : IncrementalBagWriter
        An open writer; :meth:`close` closes it.
    log_time : {"header", "receive"}
        Bag log time of a message: its header stamp (types that start with a Header or a Time;
        the receive time otherwise, and for a negative stamp) or its receive time.
    flush_period_s : float
        :meth:`tick` flushes the bag when this much time passed since the last flush.
    clock : callable
        Monotonic clock (seconds) for the flush schedule.
    """

    def __init__(
        self,
        writer: IncrementalBagWriter,
        *,
        log_time: str = "header",
        flush_period_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if log_time not in LOG_TIMES:
            raise ValueError(f"log_time must be one of {LOG_TIMES}, got {log_time!r}")
        if not flush_period_s > 0:
            raise ValueError(f"flush_period_s must be > 0, got {flush_period_s}")
        self.writer = writer
        self.log_time = log_time
        self.flush_period_s = flush_period_s
        self._clock = clock
        self._last_flush = clock()
        self.stats: dict[str, TopicStats] = {}
        self.flushes = 0
        #: receive times (ns) of the first and the last message written
        self.first_receive_ns: int | None = None
        self.last_receive_ns: int | None = None

    def handler(
        self, topic: str, msgtype: str, qos: Callable[[], Sequence[Qos]], delay_ns: int = 0
    ) -> Handler:
        """Return the function recording the messages of ``topic``.

        ``qos()`` gives the offered QoS profiles to store; it is called with the first message
        (when the topic enters the bag). ``delay_ns`` is added to a header-stamp log time
        (the GNSS latency of the aiding topics: their log time is the publication time).
        """
        inspector = PayloadInspector(msgtype)
        stats = self.stats.setdefault(topic, TopicStats(topic, msgtype))
        writer = self.writer
        use_stamp = self.log_time == "header" and inspector.has_stamp
        strip = inspector.strip if inspector.may_be_padded else None
        stamp_ns = inspector.stamp_ns
        write = None
        recording = self

        def record(payload: bytes | memoryview, receive_ns: int) -> None:
            nonlocal write
            if recording.first_receive_ns is None:
                recording.first_receive_ns = receive_ns
            recording.last_receive_ns = receive_ns
            if strip is not None:
                n = len(payload)
                try:
                    payload = strip(payload)
                except PayloadError:
                    stats.malformed += 1
                if len(payload) != n:
                    stats.padded += 1
            t = stamp_ns(payload) if use_stamp else None
            if t is not None and delay_ns:
                t += delay_ns
            if t is None:
                t = receive_ns
                stats.receive_time_logs += 1
            if write is None:
                write = writer.sink(writer.add_topic(topic, msgtype, list(qos()) or None))
                stats.first_log_ns, stats.first_receive_ns = t, receive_ns
            write(t, payload)
            stats.last_log_ns = t
            stats.count += 1
            stats.bytes += len(payload)

        return record

    @property
    def receive_span_s(self) -> float:
        """Seconds from the first to the last message received."""
        if self.first_receive_ns is None or self.last_receive_ns is None:
            return 0.0
        return (self.last_receive_ns - self.first_receive_ns) * 1e-9

    def lags_s(self, now_ns: int) -> dict[str, float]:
        """Seconds each topic's data is behind the wall clock, for a real-time recording:
        wall time since the first message minus data (log) time since it, the first message
        being that of the earliest topic with more than one message. Empty before that."""
        started = [s for s in self.stats.values() if s.count > 1]
        if not started:
            return {}
        first = min(started, key=lambda s: s.first_receive_ns)
        wall = now_ns - first.first_receive_ns
        return {
            s.topic: (wall - (s.last_log_ns - first.first_log_ns)) * 1e-9
            for s in self.stats.values()
            if s.count
        }

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return sum(s.count for s in self.stats.values())

    @property
    def flushed_counts(self) -> dict[str, int]:
        """Messages on disk per topic as of the last flush."""
        return self.writer.flushed_counts

    def tick(self) -> bool:
        """Flush when the flush period has passed; returns True when it flushed."""
        now = self._clock()
        if now - self._last_flush < self.flush_period_s:
            return False
        self.flush()
        return True

    def flush(self) -> dict[str, int]:
        """Flush now; returns the flushed counts per topic."""
        counts = self.writer.flush()
        self._last_flush = self._clock()
        self.flushes += 1
        return counts

    def close(self) -> Path:
        """Finish the bag (summary, ``metadata.yaml``)."""
        return self.writer.close()

    def summary(self) -> list[str]:
        """One line per topic: messages, bytes, stripped padding, receive-time log times."""
        width = max((len(t) for t in self.stats), default=0)
        lines = []
        for s in self.stats.values():
            extra = []
            if s.padded:
                extra.append(f"{s.padded} padded payloads stripped")
            if s.receive_time_logs:
                extra.append(f"{s.receive_time_logs} logged at receive time")
            if s.malformed:
                extra.append(f"{s.malformed} malformed (kept as received)")
            tail = f" ({', '.join(extra)})" if extra else ""
            lines.append(f"  {s.topic:<{width}} {s.count:>9} msgs {s.bytes:>12} B{tail}")
        return lines
