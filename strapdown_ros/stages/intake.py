"""The input intake shared by every stage: decoding, per-message checks, stamp verdicts, the
per-event log with its flood limit.

Written once here and used by every stage object, so ``generate`` and the nodes apply the same
rules: payloads decode in one CDR call or, when they do not (a malformed message, another frame
id), message by message (:func:`decode_runs`); messages with a NaN or an infinity, or an
orientation quaternion of degenerate norm, are dropped and a small departure from unit norm is
normalized (:func:`screen`); a stamp is judged against the one expected next on the stream's
grid (:func:`stamp_verdict`). What each stage does with each fault class: docs/reliability.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import fields, replace
from typing import Any

import numpy as np

from strapdown_ros.logs import Log

__all__ = [
    "MAX_LATE_CYCLES",
    "InputEvents",
    "decode_one",
    "decode_runs",
    "format_stamp",
    "nonfinite_rows",
    "screen",
    "stamp_span",
    "stamp_verdict",
    "stretches",
    "without_rows",
]


#: A stamp more than this many periods behind the last one received: the source restarted
#: (fewer: a late, out-of-order message).
MAX_LATE_CYCLES = 10
#: Departure of a quaternion's norm from 1 below which it is left as it is (round-off of a
#: unit quaternion written in float64), and above which it is degenerate (dropped).
QUATERNION_ROUNDOFF = 1e-9
QUATERNION_DEGENERATE = 1e-3


def format_stamp(stamp_ns: int) -> str:
    """``sec.nanosec`` of a stamp (ns since the epoch)."""
    return f"{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


def stamp_span(stamps: Iterable[int]) -> str:
    """``s`` or ``s1..s2 (n messages)`` of consecutive stamps, for a log line."""
    stamps = [int(s) for s in stamps]
    text = format_stamp(stamps[0])
    if len(stamps) > 1:
        text += f"..{format_stamp(stamps[-1])} ({len(stamps)} messages)"
    return text


def stamp_verdict(stamp: int, last: int | None, period: int, *, restart_below: int | None = None
                  ) -> str:  # fmt: skip
    """What a stamp is, after ``last`` (the last stamp taken; None: none yet) on a grid of
    ``period``: ``next`` (last + period, or the first), ``gap`` (later), ``duplicate`` (= last),
    ``out-of-order`` (earlier, at most :data:`MAX_LATE_CYCLES` periods back) or ``restart``
    (further back, or at or before ``restart_below``: e.g. a stream's first cycle)."""
    if last is None or stamp == last + period:
        return "next"
    if stamp > last:
        return "gap"
    if stamp < last - MAX_LATE_CYCLES * period or (
        restart_below is not None and stamp <= restart_below
    ):
        return "restart"
    return "duplicate" if stamp == last else "out-of-order"


def decode_one(msgtype: str, payload: bytes | memoryview, topic: str, events: InputEvents
               ) -> Any:  # fmt: skip
    """One payload decoded, or None when it does not decode (a ``malformed`` event)."""
    from strapdown_ros.bag import cdr

    try:
        return cdr.deserialize(msgtype, [payload])
    except cdr.CdrError as exc:
        events("malformed", f"{topic}: rejected a malformed {msgtype.rsplit('/', 1)[-1]} "
               f"(it does not decode: {exc})", error=True)  # fmt: skip
        return None


def decode_runs(msgtype: str, payloads: Sequence[bytes | memoryview], topic: str,
                events: InputEvents) -> list[tuple[int, Any]]:  # fmt: skip
    """``(index of the first payload, fields)`` of consecutive payloads that decode together:
    all at once when they do (one CDR call), else message by message, consecutive messages with
    the same frame ids joined; a payload that does not decode is rejected (a ``malformed``
    event naming the topic)."""
    from strapdown_ros.bag import cdr

    if not payloads:
        return []
    try:
        return [(0, cdr.deserialize(msgtype, payloads))]
    except cdr.CdrError:
        pass
    out: list[tuple[int, Any]] = []
    for i, payload in enumerate(payloads):
        one = decode_one(msgtype, payload, topic, events)
        if one is None:
            continue
        if out and out[-1][0] + len(out[-1][1]) == i:
            try:
                out[-1] = (out[-1][0], out[-1][1].append(one))
                continue
            except ValueError:  # other frame ids: a run of its own
                pass
        out.append((i, one))
    return out


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


def _orientation_norms(container: Any) -> np.ndarray | None:
    """Norms of the orientation quaternions the messages provide (NaN where not provided:
    an Imu whose ``orientation_covariance[0]`` is -1), None without an orientation field."""
    q = getattr(container, "orientation", None)
    if q is None:
        return None
    norms = np.sqrt(np.einsum("ij,ij->i", np.asarray(q), np.asarray(q)))
    cov = getattr(container, "orientation_covariance", None)
    if cov is not None:
        norms = np.where(np.asarray(cov)[:, 0] == -1.0, np.nan, norms)
    return norms


def screen(container: Any, topic: str, events: InputEvents, action: str,
           dropped: Callable[[list[int]], None] | None = None
           ) -> tuple[Any, np.ndarray | None]:  # fmt: skip
    """The messages of a field container fit to use: those with a NaN or an infinity, or an
    orientation quaternion whose norm departs from 1 by more than
    :data:`QUATERNION_DEGENERATE`, are dropped, each stretch logged (``non-finite`` /
    ``degenerate`` events, error level) with ``action`` (what the stage does about it);
    orientations departing by more than round-off but less are normalized. ``dropped`` is told
    the stamps of the dropped messages. Returns the container (None when no message is left)
    and the mask of the dropped messages (None: none)."""
    bad = nonfinite_rows(container)
    if bad is not None:
        _log_rows(container, bad, topic, events, "non-finite", "NaN or infinity in the message",
                  action, dropped)  # fmt: skip
    norms = _orientation_norms(container)
    if norms is not None:
        with np.errstate(invalid="ignore"):
            off = np.abs(norms - 1.0)
            degenerate = off > QUATERNION_DEGENERATE
        if bad is not None:
            degenerate &= ~bad
        if degenerate.any():
            _log_rows(container, degenerate, topic, events, "degenerate",
                      "orientation quaternion of norm far from 1", action, dropped)  # fmt: skip
            bad = degenerate if bad is None else bad | degenerate
        with np.errstate(invalid="ignore"):
            fix = (off > QUATERNION_ROUNDOFF) & ~(off > QUATERNION_DEGENERATE)
        if fix.any():
            q = np.array(container.orientation, dtype=np.float64)
            q[fix] /= norms[fix, None]
            container = replace(container, orientation=q)
    if bad is None:
        return container, None
    return without_rows(container, bad), bad


def _log_rows(container: Any, mask: np.ndarray, topic: str, events: InputEvents, what: str,
              problem: str, action: str, dropped: Callable[[list[int]], None] | None
              ) -> None:  # fmt: skip
    stamps = np.asarray(container.stamps_ns, dtype=np.int64)
    if dropped is not None:
        dropped(stamps[mask].tolist())
    for a, b in stretches(mask):
        events(what, f"{topic}: stamp {stamp_span(stamps[a : b + 1])}: {problem}; {action}",
               error=True)  # fmt: skip


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
