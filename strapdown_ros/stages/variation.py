"""The variation stage: a second IMU at a lever arm / on a scanning platform, streaming.

One object, :class:`VariationStage`, computes the variation and the regenerated reference from
the reference Imu/Odometry messages for both ``strapdown-sim generate`` (decoded pieces, one
large window per piece) and ``variation_node`` (raw payloads in batches, windows of at most
:data:`MAX_WINDOW` cycles). Savage 2020 Method 2 (and Method 1 offline); theory in
docs/variation.md and docs/theory/offsets.md, the node's behaviour in docs/nodes.md.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, merge_order
from strapdown_ros.config import Scenario
from strapdown_ros.config.variation import VariationSpec
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.variation import OffsetArrays, generate_variation
from strapdown_ros.logs import Log
from strapdown_ros.messages import ImuFields, OdometryFields, stream_from_messages
from strapdown_ros.stages.intake import (
    InputEvents,
    decode_one,
    format_stamp,
    screen,
    stamp_verdict,
)
from strapdown_ros.stages.recording_batches import named_stream_batches

__all__ = [
    "IMU",
    "MAX_WINDOW",
    "ODOM",
    "Timing",
    "VariationStage",
    "scenario_offsets",
    "variation_batches",
    "variation_settings",
    "variation_streams",
]

IMU, ODOM = "imu", "odom"
Message = tuple[str, int, bytes]  # (topic, stamp_ns, serialized payload)


#: Longest window (cycles) the live node solves at once when it catches up on a backlog.
MAX_WINDOW = 401


def _spec(scenario: Scenario) -> VariationSpec:
    return scenario.variation if scenario.variation is not None else VariationSpec()


def variation_settings(scenario: Scenario) -> tuple[int, str]:
    """``variation.method`` (default 2) and ``variation.gravity`` (default ``full``)."""
    spec = _spec(scenario)
    return spec.method, spec.gravity


def scenario_offsets(scenario: Scenario, samples: int) -> OffsetArrays:
    """Offsets of the scenario's ``variation`` section on the output cycle grid m = 0..N-1."""
    history = _spec(scenario).offset_model().history(scenario.period_ns * 1e-9, samples - 1)
    return OffsetArrays(history.lever_arm, history.displacement, history.c_bvar_bref)


def variation_streams(scenario: Scenario, reference: Stream) -> tuple[Stream, Stream]:
    """The variation and the regenerated reference (zero offsets) of a whole reference stream."""
    method, gravity = variation_settings(scenario)
    samples = reference.cycles + 1
    variation = generate_variation(reference, scenario_offsets(scenario, samples), method, gravity)
    regenerated = generate_variation(reference, OffsetArrays.zero(samples), method, gravity)
    return variation, regenerated


def variation_batches(scenario: Scenario, variation: Stream, regenerated: Stream) -> list[Batch]:
    """Serialized ``/variation/*`` and ``/variation/reference/*`` batches (recording names)."""
    batches = named_stream_batches(scenario, variation, "variation", "variation_imu")
    batches += named_stream_batches(
        scenario, regenerated, "variation_reference", "reference_imu", fix=False
    )
    return batches


def _concat(items: Sequence[Any]) -> Any:
    """One field container of several containers of the same type (strings of the first)."""
    if len(items) == 1:
        return items[0]
    first = items[0]
    values = {}
    for f in dataclasses.fields(first):
        value = getattr(first, f.name)
        if isinstance(value, str):
            values[f.name] = value
        else:
            values[f.name] = np.concatenate([np.asarray(getattr(i, f.name)) for i in items])
    return type(first)(**values)


def _drop_up_to(b: Batch, stamp_ns: int) -> Batch:
    keep = int(np.searchsorted(b.stamps_ns, stamp_ns, side="right"))
    return Batch(b.topic, b.msgtype, b.stamps_ns[keep:], list(b.payloads[keep:]))


def _ignore(_: str) -> None:
    pass


def _raise(message: str) -> None:
    raise RuntimeError(f"variation stage: unexpected reference input: {message}")


@dataclass
class Timing:
    """Processing time of the solved windows (wall and CPU seconds, one entry per window)."""

    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    decode_wall: float = 0.0
    decoded: int = 0

    def summary(self, cycles: int) -> str:
        """One line: wall time per window, CPU per published cycle, decoding per message."""
        if not self.wall:
            return "no window solved"
        w = np.asarray(self.wall) * 1e3
        per_cycle_cpu = sum(self.cpu) * 1e3 / max(cycles, 1)
        return (
            f"{len(w)} windows: wall per window mean {w.mean():.2f} ms, median "
            f"{np.median(w):.2f} ms, p99 {np.percentile(w, 99):.2f} ms, max {w.max():.2f} ms; "
            f"CPU per published cycle {per_cycle_cpu:.2f} ms; decoding "
            f"{self.decode_wall * 1e3 / max(self.decoded, 1):.3f} ms per message"
        )


class _Rows:
    """Messages of one input by cycle: pieces ``(first cycle, field container)``, increasing."""

    def __init__(self) -> None:
        self.pieces: list[tuple[int, Any]] = []

    def add(self, m0: int, rows: Any) -> None:
        """Append messages of cycles ``m0..`` (after every cycle held)."""
        self.pieces.append((m0, rows))

    def _find(self, m: int) -> int:
        for i, (m0, rows) in enumerate(self.pieces):
            if m0 <= m < m0 + len(rows):
                return i
        return -1

    def frames(self, m: int) -> Any:
        """The container holding cycle ``m`` (its frame ids), None if ``m`` is not held."""
        i = self._find(m)
        return None if i < 0 else self.pieces[i][1]

    def discard(self, m: int) -> None:
        """Forget cycle ``m``."""
        i = self._find(m)
        if i < 0:
            return
        m0, rows = self.pieces[i]
        n = len(rows)
        parts = []
        if m > m0:
            parts.append((m0, rows.rows(0, m - m0)))
        if m + 1 < m0 + n:
            parts.append((m + 1, rows.rows(m + 1 - m0, n)))
        self.pieces[i : i + 1] = parts

    def drop_below(self, low: int) -> None:
        """Forget the cycles before ``low``."""
        kept = []
        for m0, rows in self.pieces:
            n = len(rows)
            if m0 + n <= low:
                continue
            kept.append((m0, rows) if m0 >= low else (low, rows.rows(low - m0, n)))
        self.pieces = kept

    def contiguous_end(self, a: int) -> int:
        """Last cycle c such that every cycle a..c is held (a - 1: ``a`` is not held)."""
        end = a - 1
        for m0, rows in self.pieces:
            if m0 <= end + 1 < m0 + len(rows):
                end = m0 + len(rows) - 1
        return end

    def take(self, a: int, b: int) -> Any:
        """The messages of cycles ``a..b-1`` (all held) as one container."""
        parts = []
        for m0, rows in self.pieces:
            n = len(rows)
            lo, hi = max(a, m0), min(b, m0 + n)
            if lo < hi:
                parts.append(rows if hi - lo == n else rows.rows(lo - m0, hi - m0))
        return _concat(parts)


@dataclass
class _Input:
    """One input's messages in a call: decoded rows (None: decode each payload), payloads."""

    kind: str
    fields: Any
    payloads: list[bytes] | None
    positions: np.ndarray  # arrival order of each message among all inputs of the call

    def __len__(self) -> int:
        return int(self.positions.shape[0])


class VariationStage:
    """The streaming variation: reference messages in, serialized variation messages out.

    Parameters
    ----------
    scenario : Scenario
        Cycle grid (``start_time_ns``, T), gravitation model, the ``variation`` section
        (method, gravity, offsets) and the output topic/frame names (``recording``).
    cycles : int
        M, the scenario's last reference cycle; later stamps are dropped.
    max_window : int or None
        Longest window (cycles) solved at once; None: everything available (offline; the only
        choice for Method 1, whose windows are ``generate``'s pieces).
    residuals : bool
        Keep the one-step residuals of every solved window (see :meth:`feed_batches`).
    info, warn, error : callables
        Loggers.

    Input, in any chunking (the output is the same bits): decoded messages with :meth:`feed`
    (``generate``) or raw CDR payloads with :meth:`on_batch` / :meth:`on_message` (the node).
    Messages are taken in arrival order; consecutive, consistent messages are accepted in bulk,
    anything else one by one with the checks below, every pending window being solved before
    such a message can change the run (so deferring the solution never changes the output).

    Runs. A run is a stretch of consecutive, consistent reference cycles ``start..``; its
    output equals ``generate_variation`` on the reference restricted to those cycles (the first
    run of an uninterrupted stream from cycle 0: the offline output). A gap, a duplicate with
    different content, a frame change or an Imu/Odometry frame mismatch ends the run and starts
    a new one at the first cycle whose data is all consistent; the output never overlaps
    between runs. An out-of-order message (at most
    :data:`~strapdown_ros.stages.intake.MAX_LATE_CYCLES` back) is dropped, a
    larger backward jump restarts everything (the input restarted); an identical duplicate is
    dropped; stamps off the cycle grid or beyond cycle M are dropped.
    """

    def __init__(
        self,
        scenario: Scenario,
        cycles: int,
        *,
        max_window: int | None = MAX_WINDOW,
        residuals: bool = False,
        info: Log = _ignore,
        warn: Log = print,
        error: Log = print,
    ) -> None:
        self.scenario = scenario
        self.method, self.gravity = variation_settings(scenario)
        if self.method == 1 and max_window is not None:
            raise ValueError(
                "variation.method: Method 1 runs offline only (max_window=None): its velocity "
                "recursion restarts at every window"
            )
        self.cycles = cycles
        self.max_window = max_window
        self.offsets = scenario_offsets(scenario, cycles + 1)
        self.t0_ns = scenario.start_time_ns
        self.period_ns = scenario.period_ns
        self.earth_frame = scenario.recording.frames["earth"]
        self.info, self.warn, self.error = info, warn, error
        #: Input events by class (one log line each; counted for the node's summary).
        self.events = InputEvents(warn, error)
        self.topics = {
            IMU: scenario.recording.topics["reference_imu"],
            ODOM: scenario.recording.topics["reference_odom"],
        }
        self.last: dict[str, int | None] = {IMU: None, ODOM: None}
        self.last_payload: dict[str, bytes | None] = {IMU: None, ODOM: None}
        self.last_row: dict[str, Any] = {IMU: None, ODOM: None}
        self.buffer = {IMU: _Rows(), ODOM: _Rows()}
        self.run_start: int | None = None
        self.published: int | None = None  # last cycle published in the current run
        self.body_frame: str | None = None  # Imu frame id (= Odometry child) of the run
        self.runs = 0  # runs that published something
        self.published_cycles = 0
        self.timing = Timing()
        self._warned_beyond = False
        self._warned_frame = False
        self._windows: list[list[Batch]] = []  # solved, not yet handed out
        self._residuals: dict[str, list[Residuals]] | None = (
            {"variation": [], "variation/reference": []} if residuals else None
        )

    @classmethod
    def offline(cls, scenario: Scenario, cycles: int) -> VariationStage:
        """The stage as ``generate`` runs it: whole pieces per window, residuals kept, and any
        irregular input (impossible from the reference stage) an error."""
        return cls(scenario, cycles, max_window=None, residuals=True, warn=_raise, error=_raise)

    # -- state -----------------------------------------------------------------------------------

    def stamp(self, m: int) -> str:
        """``sec.nanosec`` of cycle ``m``."""
        return format_stamp(self.t0_ns + m * self.period_ns)

    def describe(self, m: int) -> str:
        """``cycle m (stamp s.ns)``."""
        return f"cycle {m} (stamp {self.stamp(m)})"

    @property
    def started(self) -> bool:
        """A run has started (the first usable message arrived)."""
        return self.run_start is not None

    @property
    def finished(self) -> bool:
        """True when the current run cannot publish more cycles of the scenario."""
        if self.run_start is None:
            return False
        base = self.run_start if self.published is None else self.published
        return base + 3 > self.cycles

    # -- input: decoded (generate) -------------------------------------------------------------

    def feed(
        self, imu: ImuFields | None = None, odom: OdometryFields | None = None, solve: bool = True
    ) -> list[Batch]:
        """Take decoded reference messages (in stamp order per topic; Odometry before Imu at
        equal stamps); return the output batches now computable (one per topic)."""
        n_imu = 0 if imu is None else len(imu)
        n_odom = 0 if odom is None else len(odom)
        keys = [np.zeros(0, np.int64)]  # arrival order: by stamp, each topic's order kept
        for fields in (odom, imu):
            if fields is not None and len(fields):
                keys.append(np.maximum.accumulate(np.asarray(fields.stamps_ns, dtype=np.int64)))
        order = np.argsort(np.concatenate(keys), kind="stable")
        positions = np.empty(order.shape[0], dtype=np.int64)
        positions[order] = np.arange(order.shape[0])
        inputs = [
            _Input(ODOM, odom, None, positions[:n_odom]),
            _Input(IMU, imu, None, positions[n_odom : n_odom + n_imu]),
        ]
        self._ingest(inputs)
        if solve:
            self._advance()
        return self._take_batches()

    def feed_batches(self, batches: Sequence[Batch]) -> list[Batch]:
        """:meth:`feed` with the reference batches of a ``generate`` piece (other topics are
        ignored)."""
        by_topic = {b.topic: b for b in batches}
        decoded = {}
        for kind in (IMU, ODOM):
            b = by_topic.get(self.topics[kind])
            decoded[kind] = None if b is None else cdr.deserialize(b.msgtype, b.payloads)
        return self.feed(decoded[IMU], decoded[ODOM])

    def take_residuals(self) -> dict[str, Residuals]:
        """One-step residuals of the windows solved since the last call, by stream
        (``variation``, ``variation/reference``; kept with ``residuals=True``)."""
        out: dict[str, Residuals] = {}
        for name, parts in (self._residuals or {}).items():
            if parts:
                out[name] = Residuals(
                    attitude=np.concatenate([p.attitude for p in parts]),
                    velocity=np.concatenate([p.velocity for p in parts]),
                    position=np.concatenate([p.position for p in parts]),
                )
            parts.clear()
        return out

    # -- input: raw payloads (the node) --------------------------------------------------------

    def on_batch(self, items: Sequence[tuple[str, bytes]]) -> list[Message]:
        """Raw payloads ``(kind, payload)`` ('imu' | 'odom') in arrival order; return what to
        publish, in merge order. Each input's payloads are decoded with one CDR call (a batch
        that does not decode as a whole is decoded one by one, so each bad message is
        reported)."""
        self._push(items)
        self._advance()
        return self._take_messages()

    def on_message(self, kind: str, payload: bytes, solve: bool = True) -> list[Message]:
        """One raw payload; with ``solve=False`` it is only buffered (see :meth:`advance`)."""
        self._push([(kind, payload)])
        if solve:
            self._advance()
        return self._take_messages()

    def advance(self) -> list[Message]:
        """Solve every window whose look-ahead has arrived; return the messages to publish."""
        self._advance()
        return self._take_messages()

    def _push(self, items: Sequence[tuple[str, bytes]]) -> None:
        inputs = []
        for kind, msgtype in ((ODOM, cdr.ODOMETRY), (IMU, cdr.IMU)):
            idx = [i for i, (k, _) in enumerate(items) if k == kind]
            payloads = [items[i][1] for i in idx]
            fields = None
            if payloads:
                t = time.perf_counter()
                try:
                    fields = cdr.deserialize(msgtype, payloads)
                except cdr.CdrError:
                    fields = None  # decoded one by one below, each bad message reported
                else:
                    self.timing.decode_wall += time.perf_counter() - t
                    self.timing.decoded += len(payloads)
            inputs.append(_Input(kind, fields, payloads, np.asarray(idx, dtype=np.int64)))
        self._ingest(inputs)

    # -- checks --------------------------------------------------------------------------------

    #: What the stage does with a message that :func:`~strapdown_ros.stages.intake.screen`
    #: rejects (a NaN or an infinity, a degenerate orientation quaternion).
    _REJECTED = "dropped (a lost message: the solution restarts after it)"

    def _drop_nonfinite(self, inp: _Input) -> _Input:
        """``inp`` without its messages that are not fit to use (a NaN or an infinity, an
        orientation quaternion of degenerate norm: the shared intake's
        :func:`~strapdown_ros.stages.intake.screen`, each stretch logged); a dropped message
        is a lost one (the run restarts after it). A small departure from unit norm is
        normalized in the fields."""
        if inp.fields is None:
            return inp
        topic = self.topics[inp.kind]
        fields, bad = screen(inp.fields, topic, self.events, self._REJECTED,
                             lambda stamps: self.events.dropped(topic, stamps))  # fmt: skip
        if bad is None:
            return dataclasses.replace(inp, fields=fields)
        keep = np.flatnonzero(~bad)
        payloads = None if inp.payloads is None else [inp.payloads[k] for k in keep]
        return _Input(inp.kind, fields, payloads, inp.positions[keep])

    def _ingest(self, inputs: list[_Input]) -> None:
        """Take the messages in arrival order: the consistent ones in bulk, others one by one."""
        inputs = [self._drop_nonfinite(i) for i in inputs if len(i)]
        inputs = [i for i in inputs if len(i)]
        done = {i.kind: 0 for i in inputs}
        while True:
            clean = {i.kind: done[i.kind] + self._clean_count(i, done[i.kind]) for i in inputs}
            stop, odd = np.iinfo(np.int64).max, None
            for i in inputs:
                if clean[i.kind] < len(i) and int(i.positions[clean[i.kind]]) < stop:
                    stop, odd = int(i.positions[clean[i.kind]]), i
            for i in inputs:
                end = int(np.searchsorted(i.positions, stop)) if odd is not None else len(i)
                if end > done[i.kind]:
                    self._accept(i, done[i.kind], end)
                    done[i.kind] = end
            if odd is None:
                return
            self._advance()  # what the run can publish before this message changes anything
            r = done[odd.kind]
            row = None if odd.fields is None else odd.fields.rows(r, r + 1)
            self._one(odd.kind, row, None if odd.payloads is None else bytes(odd.payloads[r]))
            done[odd.kind] = r + 1

    def _clean_count(self, inp: _Input, start: int) -> int:
        """How many messages from ``start`` simply continue the run (accepted in bulk)."""
        kind, f = inp.kind, inp.fields
        last = self.last[kind]
        if f is None or last is None or self.run_start is None or self.body_frame is None:
            return 0
        if kind == ODOM:
            if f.frame_id != self.earth_frame or f.child_frame_id != self.body_frame:
                return 0
        elif f.frame_id != self.body_frame:
            return 0
        if last + 1 < self.run_start + (kind == IMU):
            return 0
        n = min(len(inp) - start, self.cycles - last)
        if n <= 0:
            return 0
        first = self.t0_ns + (last + 1) * self.period_ns
        if n <= 8:  # the node's usual batch: cheaper without numpy
            for k, stamp in enumerate(f.stamps_ns[start : start + n].tolist()):
                if stamp != first + k * self.period_ns:
                    return k
            return n
        stamps = np.asarray(f.stamps_ns[start : start + n], dtype=np.int64)
        expected = first + np.arange(n, dtype=np.int64) * self.period_ns
        bad = np.flatnonzero(stamps != expected)
        return int(bad[0]) if bad.size else n

    def _accept(self, inp: _Input, start: int, stop: int) -> None:
        """Messages ``start..stop-1`` of ``inp`` continue the run: buffer them."""
        kind = inp.kind
        m0 = self.last[kind] + 1  # type: ignore[operator]
        f = inp.fields
        self.buffer[kind].add(m0, f if start == 0 and stop == len(f) else f.rows(start, stop))
        self.last[kind] = m0 + stop - start - 1
        self.last_row[kind] = (f, stop - 1)  # a row is made only to compare a duplicate
        self.last_payload[kind] = None if inp.payloads is None else bytes(inp.payloads[stop - 1])

    def _first_run_cycle(self, kind: str, m: int) -> int:
        """First run start that needs no data of ``kind`` before cycle ``m``.

        A run starting at r uses Odometry r.. and Imu r+1.. (the increments after its state).
        """
        return m if kind == ODOM else m - 1

    def _reset(self) -> None:
        """Forget everything (the input restarted)."""
        self.last = {IMU: None, ODOM: None}
        self.last_payload = {IMU: None, ODOM: None}
        self.last_row = {IMU: None, ODOM: None}
        self.buffer = {IMU: _Rows(), ODOM: _Rows()}
        self.run_start = self.published = self.body_frame = None

    def restart(self, start: int, reason: str, log: bool = True) -> None:
        """Start a new run at cycle ``start`` unless the current one starts there or later."""
        if self.run_start is not None and self.run_start >= start:
            return
        if not log:
            pass
        elif self.run_start is not None:
            done = (
                f"published up to {self.describe(self.published)}"
                if self.published is not None
                else "nothing published in that run"
            )
            self.warn(
                f"{reason}: restarting the solution at {self.describe(start)} ({done}); the "
                "new run starts with a one-sided velocity constraint and differs from an "
                "uninterrupted offline run"
            )
        elif start > 0:
            self.warn(
                f"{reason}: the solution starts at {self.describe(start)} and differs from the "
                "offline run (which starts at cycle 0)"
            )
        else:
            self.info(f"{reason}: the solution starts at {self.describe(start)}")
        self.run_start = start
        self.published = None
        self.body_frame = None
        self.buffer[ODOM].drop_below(start)
        self.buffer[IMU].drop_below(start + 1)

    def _same(self, kind: str, row: Any, payload: bytes | None) -> bool:
        if payload is not None and self.last_payload[kind] is not None:
            return payload == self.last_payload[kind]
        last = self.last_row[kind]
        if isinstance(last, tuple):
            last = last[0].rows(last[1], last[1] + 1)
        return last is not None and row.equals(last)

    def _one(self, kind: str, msg: Any, payload: bytes | None) -> None:
        """One message that does not simply continue the run (first, gap, repeat, frames...)."""
        if msg is None:
            msg = self._decode(kind, payload)  # type: ignore[arg-type]
            if msg is None:
                return
        m = self._cycle(kind, int(msg.stamps_ns[0]))
        if m is None or not self._follow(kind, m, msg, payload):
            return
        if kind == ODOM and msg.frame_id != self.earth_frame:
            self.events(
                "wrong frame",
                f"{self.topics[kind]}: {self.describe(m)}: header.frame_id {msg.frame_id!r} is "
                f"not the Earth frame {self.earth_frame!r} (recording.frames.earth); rejected, "
                f"the solution restarts at cycle {m + 1}",
                error=True,
            )
            self.restart(m + 1, "", log=False)
            return
        assert self.run_start is not None
        if m < self.run_start + (kind == IMU):
            return  # before the current run (the other topic restarted it later)
        self.buffer[kind].add(m, msg)
        self._check_frames(m)

    def _decode(self, kind: str, payload: bytes) -> Any:
        """One payload decoded; None if it is malformed or not finite (logged, dropped)."""
        topic = self.topics[kind]
        t = time.perf_counter()
        msg = decode_one(cdr.IMU if kind == IMU else cdr.ODOMETRY, payload, topic, self.events)
        if msg is None:
            return None
        self.timing.decode_wall += time.perf_counter() - t
        self.timing.decoded += 1
        msg, _ = screen(msg, topic, self.events, self._REJECTED,
                        lambda stamps: self.events.dropped(topic, stamps))  # fmt: skip
        return msg

    def _cycle(self, kind: str, stamp: int) -> int | None:
        """The scenario cycle of ``stamp``; None if it is off the grid or outside the cycles
        (logged, dropped)."""
        topic = self.topics[kind]
        offset = stamp - self.t0_ns
        if offset < 0 or offset % self.period_ns:
            self.events(
                "off-grid stamp",
                f"{topic}: stamp {format_stamp(stamp)} is not on the scenario's cycle grid "
                f"(start {format_stamp(self.t0_ns)}, T = {self.period_ns} ns); dropped",
            )
            return None
        m = offset // self.period_ns
        if m > self.cycles or (kind == IMU and m == 0):
            if not self._warned_beyond:
                self._warned_beyond = True
                self.warn(
                    f"{topic}: {self.describe(m)} is outside the scenario's cycles "
                    f"({'1' if kind == IMU else '0'}..{self.cycles}); such messages are dropped"
                )
            return None
        return m

    def _follow(self, kind: str, m: int, msg: Any, payload: bytes | None) -> bool:
        """Cycle ``m`` after the topic's last (:func:`~strapdown_ros.stages.intake.
        stamp_verdict`): remembered, the run restarted where it must; False if dropped."""
        topic, last = self.topics[kind], self.last[kind]
        verdict = stamp_verdict(m, last, 1)
        stamp = format_stamp(self.t0_ns + m * self.period_ns)
        if last is None or verdict == "next":
            self._remember(kind, m, msg, payload)
            if last is None:
                self.restart(self._first_run_cycle(kind, m), f"first message on {topic}")
            return True
        after = f"{format_stamp(self.t0_ns + last * self.period_ns)} (cycle {last})"
        if verdict == "duplicate":
            if self._same(kind, msg, payload):
                self.events("duplicate stamp", f"{topic}: duplicate stamp {stamp} (cycle {m}), "
                            "identical content; dropped")  # fmt: skip
                return False
            self.events("duplicate stamp", f"{topic}: duplicate stamp {stamp} (cycle {m}) "
                        "with different content; both dropped")  # fmt: skip
            self.buffer[kind].discard(m)
            self.restart(self._first_run_cycle(kind, m + 1), f"{topic}: duplicate")
            return False
        if verdict == "restart":
            self.events("restart", f"{topic}: stamp {stamp} (cycle {m}) jumps back {last - m} "
                        f"cycles from {after}: the input restarted; starting afresh")  # fmt: skip
            self._reset()
            self._remember(kind, m, msg, payload)
            self.restart(self._first_run_cycle(kind, m), f"first message on {topic} after the jump")
            return True
        if verdict == "out-of-order":
            self.events("out-of-order stamp", f"{topic}: out-of-order stamp {stamp} (cycle {m}) "
                        f"after {after}; dropped")  # fmt: skip
            return False
        self.events.gap(
            topic,
            (self.t0_ns + k * self.period_ns for k in range(last + 1, m)),
            f"{topic}: gap: stamp {stamp} (cycle {m}) follows {after}; "
            f"{m - last - 1} cycle(s) missing",
            self.info,
        )
        self._remember(kind, m, msg, payload)
        self.restart(self._first_run_cycle(kind, m), f"{topic}: gap")
        return True

    def _remember(self, kind: str, m: int, msg: Any, payload: bytes | None) -> None:
        self.last[kind], self.last_row[kind], self.last_payload[kind] = m, msg, payload

    def _check_frames(self, m: int) -> bool:
        """Imu frame = Odometry child frame at cycle m, and constant within the run."""
        imu = self.buffer[IMU].frames(m)
        odom = self.buffer[ODOM].frames(m)
        if imu is not None and odom is not None and imu.frame_id != odom.child_frame_id:
            return self._reject_frames(
                m,
                f"Imu frame_id {imu.frame_id!r} differs from the Odometry child_frame_id "
                f"{odom.child_frame_id!r}: the reference messages do not describe one body",
            )
        for msg, name in ((imu, "Imu frame_id"), (odom, "Odometry child_frame_id")):
            if msg is None:
                continue
            frame = msg.frame_id if msg is imu else msg.child_frame_id
            if self.body_frame is None:
                self.body_frame = frame
                expected = self.scenario.recording.frames["reference_imu"]
                if frame != expected and not self._warned_frame:
                    self._warned_frame = True
                    self.warn(
                        f"the reference body frame is {frame!r}, not recording.frames."
                        f"reference_imu {expected!r}; the output carries the scenario's frames"
                    )
            elif frame != self.body_frame:
                return self._reject_frames(
                    m, f"{name} {frame!r} differs from the run's body frame {self.body_frame!r}"
                )
        return True

    def _reject_frames(self, m: int, why: str) -> bool:
        """Cycle ``m``'s messages rejected for their frames (a ``wrong frame`` event); the
        solution restarts at the next cycle. Returns False (not accepted)."""
        self.events(
            "wrong frame",
            f"{self.describe(m)}: {why}; rejected, the solution restarts at cycle {m + 1}",
            error=True,
        )
        self.buffer[IMU].discard(m)
        self.buffer[ODOM].discard(m)
        self.restart(m + 1, "", log=False)
        return False

    # -- solving -------------------------------------------------------------------------------

    def _samples(self, first: int, base: int) -> int | None:
        """Longest window from ``first`` (``base`` + 2k samples) whose messages have arrived."""
        end = min(
            self.buffer[ODOM].contiguous_end(first),
            self.buffer[IMU].contiguous_end(first + 1),
            self.cycles,
        )
        available = end - first + 1
        if available < base:
            return None
        samples = base + 2 * ((available - base) // 2)
        if self.max_window is not None:
            cap = self.max_window - (self.max_window - base) % 2
            samples = max(base, min(samples, cap))
        return samples

    def _advance(self) -> None:
        while self.run_start is not None and not self.finished:
            if self.published is None:
                first, lead = self.run_start, 0  # the run starts: cycles first..first+2 at least
                samples = self._samples(first, 4)
            else:
                # lead=1 windows of any odd length give the same bits as the 5-cycle ones
                # (Method 2 pairs are independent), so a backlog is solved in long windows.
                first, lead = self.published - 1, 1
                samples = self._samples(first, 5)
            if samples is None:
                break
            wall, cpu = time.perf_counter(), time.thread_time()
            self._windows.append(self._solve(first, samples, lead))
            self.timing.wall.append(time.perf_counter() - wall)
            self.timing.cpu.append(time.thread_time() - cpu)
            new_last = first + samples - 2
            self.runs += self.published is None
            self.published_cycles += new_last - (self.published if lead else first - 1)
            self.published = new_last
            self.buffer[ODOM].drop_below(new_last - 1)
            self.buffer[IMU].drop_below(new_last)

    def _solve(self, first: int, samples: int, lead: int) -> list[Batch]:
        imu = self.buffer[IMU].take(first + 1, first + samples)
        odom = self.buffer[ODOM].take(first, first + samples)
        reference = stream_from_messages(
            imu, odom, self.scenario.gravity_model, e0_epoch_ns=self.t0_ns
        )
        sl = slice(first, first + samples)
        o = self.offsets
        offsets = OffsetArrays(o.lever_arm[sl], o.displacement[sl], o.c_bvar_bref[sl])
        variation = generate_variation(reference, offsets, self.method, self.gravity, lead=lead)
        regenerated = generate_variation(
            reference, OffsetArrays.zero(samples), self.method, self.gravity, lead=lead
        )
        if self._residuals is not None:
            self._residuals["variation"].append(stream_residuals(variation))
            self._residuals["variation/reference"].append(stream_residuals(regenerated))
        batches = variation_batches(self.scenario, variation, regenerated)
        if self.published is not None:
            done = self.t0_ns + self.published * self.period_ns
            batches = [_drop_up_to(b, done) for b in batches]
        return batches

    # -- output --------------------------------------------------------------------------------

    def _take_messages(self) -> list[Message]:
        out: list[Message] = []
        for batches in self._windows:
            out += [
                (batches[k].topic, stamp, bytes(batches[k].payloads[i]))
                for k, i, stamp in merge_order(batches)
            ]
        self._windows = []
        return out

    def _take_batches(self) -> list[Batch]:
        windows, self._windows = self._windows, []
        if len(windows) == 1:
            return windows[0]
        merged: dict[str, list[Batch]] = {}
        for batches in windows:
            for b in batches:
                merged.setdefault(b.topic, []).append(b)
        return [
            Batch(
                topic,
                parts[0].msgtype,
                np.concatenate([np.asarray(p.stamps_ns, dtype=np.int64) for p in parts]),
                [payload for p in parts for payload in p.payloads],
            )
            for topic, parts in merged.items()
        ]
