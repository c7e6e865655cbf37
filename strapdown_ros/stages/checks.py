"""Input checks shared by the stages: non-finite values and the per-event log with counters.

Written once here and used by the stage objects, so ``generate`` and the nodes apply the same
checks. What each stage does with each fault class: docs/reliability.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import fields
from typing import Any

import numpy as np

__all__ = ["InputEvents", "format_stamp", "nonfinite_rows", "without_rows"]

Log = Callable[[str], None]


def format_stamp(stamp_ns: int) -> str:
    """``sec.nanosec`` of a stamp (ns since the epoch)."""
    return f"{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


#: Floating-point field names of each field-container type (found once per type).
_FLOAT_FIELDS: dict[type, tuple[str, ...]] = {}


def _float_fields(container: Any) -> tuple[str, ...]:
    names = _FLOAT_FIELDS.get(type(container))
    if names is None:
        names = tuple(
            f.name for f in fields(container)
            if not isinstance(getattr(container, f.name), str)
            and np.asarray(getattr(container, f.name)).dtype.kind == "f"
        )  # fmt: skip
        _FLOAT_FIELDS[type(container)] = names
    return names


def nonfinite_rows(container: Any) -> np.ndarray | None:
    """Boolean mask of the messages of a field container with a NaN or an infinity in any
    floating-point field (None: every message is finite, the common case).

    Fast path (a few microseconds per batch): the sum of each array is finite; only if one is
    not (a non-finite value, or an overflow of huge finite ones) are the rows checked exactly.
    """
    suspect = []
    with np.errstate(over="ignore", invalid="ignore"):  # huge finite values may overflow
        for name in _float_fields(container):
            a = getattr(container, name)
            if a.size and not math.isfinite(a.sum()):
                suspect.append(a)
    if not suspect:
        return None
    n = len(container)
    bad = np.zeros(n, dtype=bool)
    for a in suspect:
        bad |= ~np.isfinite(np.asarray(a).reshape(n, -1)).all(axis=1)
    return bad if bad.any() else None


def without_rows(container: Any, drop: np.ndarray) -> Any:
    """The container without the messages where ``drop`` is True (None: none is left)."""
    keep = np.flatnonzero(~drop)
    if keep.size == 0:
        return None
    values = {}
    for f in fields(container):
        value = getattr(container, f.name)
        values[f.name] = value if isinstance(value, str) else np.asarray(value)[keep]
    return type(container)(**values)


def stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` indices of each run of True in ``mask``."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


class InputEvents:
    """Counts input events by class and logs one line per event.

    Every event gets its own line (stamp, topic, what was wrong, what the stage did) through
    ``warn`` or ``error``; the limit is per class: beyond ``burst`` lines of one class within
    ``window_s`` seconds the lines of that class are held and the next line of that class says
    how many were held (a flood of bad input cannot drown the log, and one class can never
    hide another). :attr:`counts` (class → events) goes into the node's end-of-run summary.
    """

    def __init__(
        self,
        warn: Log,
        error: Log,
        *,
        burst: int = 20,
        window_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.warn, self.error = warn, error
        self.burst, self.window_s, self.clock = burst, window_s, clock
        self.counts: dict[str, int] = {}
        self._recent: dict[str, list[float]] = {}
        self._held: dict[str, int] = {}
        self._dropped: dict[str, set[int]] = {}  # topic -> stamps dropped (already logged)

    def dropped(self, topic: str, stamps: Iterable[int]) -> None:
        """Remember stamps of ``topic`` whose messages were dropped (and logged) here, so the
        gap they leave is not logged as a second event (:meth:`gap`)."""
        held = self._dropped.setdefault(topic, set())
        if len(held) > 100_000:
            held.clear()
        held.update(int(s) for s in stamps)

    def gap(self, topic: str, missing: Iterable[int], message: str, info: Log) -> None:
        """A gap of the ``missing`` stamps: an event, unless every one of them was dropped here
        (then ``message`` goes to ``info`` only: the event was counted when they were)."""
        held = self._dropped.get(topic, set())
        missing = [int(s) for s in missing]
        if missing and all(s in held for s in missing):
            held.difference_update(missing)
            info(message + " (the message(s) dropped above)")
            return
        self("gap", message)

    def __call__(self, what: str, message: str, *, error: bool = False, n: int = 1) -> None:
        """Count ``n`` events of class ``what`` and log ``message`` (unless flooded)."""
        self.counts[what] = self.counts.get(what, 0) + n
        now = self.clock()
        recent = [t for t in self._recent.get(what, []) if now - t < self.window_s]
        if len(recent) >= self.burst:
            self._recent[what] = recent
            self._held[what] = self._held.get(what, 0) + 1
            return
        recent.append(now)
        self._recent[what] = recent
        held = self._held.pop(what, 0)
        if held:
            message += f" [{held} more '{what}' line(s) held back in the last {self.window_s:g} s]"
        (self.error if error else self.warn)(message)

    def summary(self) -> str:
        """``input events: class n, ...`` (``none`` without any)."""
        if not self.counts:
            return "input events: none"
        return "input events: " + ", ".join(f"{k} {v}" for k, v in sorted(self.counts.items()))
