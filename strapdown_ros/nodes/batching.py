"""Input in batches: subscription callbacks only buffer, the node's loop processes.

Decoding, computing and serializing k messages with one set of numpy calls costs little more
than one message, so a node that takes its input in batches keeps up with kHz streams on a
fraction of a core and, when it falls behind, takes larger batches by itself (measurements:
docs/benchmarks.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from strapdown_ros.nodes.parameters import ParameterError, declare_number

__all__ = ["BATCH_PERIOD_S", "InputBatch", "declare_batch_period", "header_stamps"]

#: Default ``batch_period_s``: the longest a received message waits before it is processed.
BATCH_PERIOD_S = 0.01


def declare_batch_period(node: Any, default: float = BATCH_PERIOD_S) -> float:
    """Declare ``batch_period_s`` (latency against CPU) and return it."""
    value = declare_number(
        node,
        "batch_period_s",
        default,
        "longest wait (s) of a received message before it is processed while input keeps "
        "coming: messages are decoded, computed and serialized in batches (latency vs CPU)",
    )
    if not 0 < value <= 1:
        raise ParameterError("batch_period_s", f"must be > 0 and <= 1, got {value}")
    return value


#: Bytes of the CDR encapsulation header, then of the std_msgs/Header stamp (sec i4, nanosec u4)
#: that every input message type starts with.
_STAMP = slice(4, 12)


def header_stamps(payloads: list[bytes | memoryview]) -> np.ndarray:
    """Header stamps (ns) read from serialized messages whose first field is a std_msgs/Header;
    -1 for a payload too short to hold one (the stage's decoder rejects it)."""
    out = np.full(len(payloads), -1, dtype=np.int64)
    for i, p in enumerate(payloads):
        head = bytes(p[_STAMP])
        if len(head) == 8:
            sec = int.from_bytes(head[:4], "little", signed=True)
            out[i] = sec * 1_000_000_000 + int.from_bytes(head[4:], "little")
    return out


class InputBatch:
    """Raw input messages buffered by subscription callbacks, processed in batches.

    A callback only calls :meth:`add`; the node's loop calls :meth:`spin` and processes
    :meth:`take` when :meth:`due`: when nothing arrived for ``quiet_s`` (the burst of one cycle
    is in, or the stream paused or ended: low latency at low rates) or the oldest message has
    waited ``period_s`` (messages keep coming: a kHz stream, or a backlog).
    """

    #: Default ``quiet_s`` (s): a 200 Hz stream's cycles are processed as they come.
    QUIET_S = 0.002

    def __init__(self, period_s: float, quiet_s: float = QUIET_S) -> None:
        self.period_s = period_s
        self.quiet_s = min(quiet_s, period_s)
        self.items: list[Any] = []
        self.received = 0
        self.last_input = time.monotonic()
        self._oldest = 0.0
        self._quiet = False

    def add(self, item: Any) -> None:
        """Buffer one message (called by subscription callbacks)."""
        now = time.monotonic()
        if not self.items:
            self._oldest = now
        self.items.append(item)
        self.received += 1
        self.last_input = now

    def spin(self, spin: Callable[[float], None]) -> None:
        """Spin the executor for at most ``quiet_s``; note whether anything arrived."""
        before = self.received
        spin(self.quiet_s)
        self._quiet = self.received == before

    def due(self) -> bool:
        """Messages wait and the input was quiet for ``quiet_s`` or the oldest waited
        ``period_s``."""
        if not self.items:
            return False
        return self._quiet or time.monotonic() - self._oldest >= self.period_s

    def take(self) -> list[Any]:
        """The buffered messages, oldest first; the buffer is emptied."""
        items, self.items = self.items, []
        return items
