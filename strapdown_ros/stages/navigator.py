"""The navigation stage: the navigator on messages, for ``generate`` and ``navigator_node``.

:class:`NavigatorStage` is the one streaming implementation: it takes the Imu and truth
Odometry messages of its input (raw payloads or decoded fields, in any chunking), checks them
(period, gaps, order, repeats, frames), runs the navigator of :mod:`strapdown_ros.core.
navigation` over each contiguous stretch (:class:`NavigatorRun`) and returns the serialized
``/navigator/*`` messages now complete. Conventions (runs, stamps, errors, ``/navigator/odom``):
docs/navigator.md; the node's behaviour: docs/nodes.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, merge_order
from strapdown_ros.config import Initial, Scenario, navigator_spec
from strapdown_ros.config.navigator import INPUT_STREAMS, OUTPUT_TOPICS, NavigatorSpec
from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.navigation import (
    NavState,
)
from strapdown_ros.logs import Log, quiet
from strapdown_ros.messages import (
    EarthState,
    ImuFields,
    OdometryFields,
    imu_increments,
    odometry_state,
)
from strapdown_ros.stages.intake import (
    InputEvents,
    decode_one,
    format_stamp,
    nonfinite_rows,
    screen,
    stamp_verdict,
    stretches,
    without_rows,
)
from strapdown_ros.stages.navigator_outputs import NavigatorOutputs
from strapdown_ros.stages.navigator_run import NavigatorRun, StreamError, build_navigator
from strapdown_ros.stages.navigator_truth import (
    TRUTH_KEEP,
    TruthStore,
    initial_state_from_scenario,
    initial_state_from_truth,
    state_rows,
)

__all__ = [
    "INPUT_STREAMS",
    "OUTPUT_TOPICS",
    "NavigatorStage",
    "NavigatorOutputs",
    "NavigatorRun",
    "StreamError",
    "build_navigator",
    "initial_state_from_scenario",
    "initial_state_from_truth",
    "navigate_messages",
]

Message = tuple[str, int, bytes]


@dataclass
class _Decoded:
    """One topic's part of an input chunk: fields (None: decode each payload alone)."""

    fields: Any
    stamps: I64
    payloads: Sequence[bytes | memoryview] | None = None
    states: EarthState | None = None  # truth in the Earth frame (None: wrong frame)


class NavigatorStage:
    """The streaming navigator: Imu and truth messages in, ``/navigator/*`` messages out.

    Input in arrival order and any chunking (:meth:`on_batch` raw payloads, :meth:`feed_fields`
    decoded fields, :meth:`feed_batches` a piece of ``generate``); the state is carried between
    calls and the output does not depend on the chunking. The input checks are here:

    * **Period.** T is ``period_ns`` if given, else the difference of the first two increasing
      IMU stamps; with ``nav_period_s`` > 0, N = T_nav / T must be a whole number.
    * **Start.** A run starts at a truth stamp ``t_s`` whose next IMU message ``t_s + T`` has
      arrived (``initialization: truth``), or at ``start_ns`` (``scenario``).
    * **Gaps.** A missing IMU message ends the run at its last complete cycle; a new run starts
      from the truth before the next message. Out-of-order and repeated messages are dropped;
      truth in another frame than ``earth_frame`` and malformed messages are rejected. Each is
      logged.

    Parameters
    ----------
    spec : NavigatorSpec
        Resolved ``navigator`` section (:func:`~strapdown_ros.config.navigator.
        resolve_navigator`).
    output_topics : mapping
        Output key (:data:`OUTPUT_TOPICS`) → topic name.
    initial : Initial, optional
        The scenario's initial state (``initialization: scenario``).
    start_ns : int, optional
        The scenario's start stamp (``initialization: scenario``).
    period_ns : int, optional
        IMU period T (ns) if known (``generate``); None: from the stamps.
    nav_period_s : float
        If > 0, ``T_nav`` (s) instead of ``spec.n``.
    end_ns : int, optional
        Last IMU stamp of the input stream, if known: :attr:`finished`.
    earth_frame : str
        Frame id of the truth Odometry and of ``/navigator/odom``.
    info, warn, error : callables
        Log sinks (default: silent).
    """

    def __init__(
        self,
        spec: NavigatorSpec,
        output_topics: Mapping[str, str],
        *,
        initial: Initial | None = None,
        start_ns: int | None = None,
        period_ns: int | None = None,
        nav_period_s: float = 0.0,
        end_ns: int | None = None,
        earth_frame: str = "earth",
        info: Log = quiet,
        warn: Log = quiet,
        error: Log = quiet,
    ) -> None:
        if not spec.resolved:
            raise ValueError("the navigator spec must be resolved (resolve_navigator)")
        if spec.initialization == "scenario" and (initial is None or start_ns is None):
            raise ValueError("initialization 'scenario' needs the initial state and start stamp")
        self.spec = spec
        self.n = spec.n
        self.output_topics = dict(output_topics)
        self.initial = initial
        self.start_ns = start_ns
        self.nav_period_s = nav_period_s
        self.end_ns = end_ns
        self.earth_frame = earth_frame
        self.info, self.warn, self.error = info, warn, error
        #: Input events by class (one log line each; counted for the node's summary).
        self.events = InputEvents(warn, error)
        self.period_ns: int | None = None
        self.first_imu: list[tuple[int, Any]] = []  # (stamp, fields) before T is known
        self.first_stamps: list[int] = []  # every stamp of the period search (gaps reported)
        self.imu_buffer: list[tuple[int, F64, F64]] = []  # waiting for a run
        self.truth = TruthStore(TRUTH_KEEP)
        self.run: NavigatorRun | None = None
        self.runs = 0
        self.published_outputs = 0
        self.last_output_ns: int | None = None
        self.failed: str | None = None
        #: End-of-output errors (m): ``horizontal_m``, ``vertical_m``, ``max_horizontal_m``.
        self.final_errors: dict[str, float] = {}
        self._flush_pending: list[NavigatorOutputs] = []
        self._diverged = False  # the current run produced a non-finite solution
        self.imu_frame: str | None = None  # frame_id of the Imu messages so far
        if period_ns is not None:
            self._set_period(int(period_ns), "given")

    @classmethod
    def for_scenario(
        cls, scenario: Scenario, spec: NavigatorSpec | None = None, **kwargs: Any
    ) -> NavigatorStage:
        """The stage of ``scenario``'s navigator (or of ``spec``, resolved), with its output
        topics, frames, initial state and start; ``kwargs`` as for the constructor."""
        spec = navigator_spec(scenario) if spec is None else spec
        if spec is None:
            raise ValueError(f"scenario {scenario.name!r} has no navigator section")
        topics = scenario.recording.topics
        kwargs.setdefault("earth_frame", scenario.recording.frames["earth"])
        return cls(
            spec,
            {k: topics[v] for k, v in OUTPUT_TOPICS.items()},
            initial=scenario.initial,
            start_ns=scenario.start_time_ns,
            **kwargs,
        )

    # -- state -------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        """Whether a run has started."""
        return self.run is not None or self.runs > 0

    @property
    def finished(self) -> bool:
        """True when the last output the input stream allows has been published."""
        if self.end_ns is None or self.run is None:
            return False
        nav = self.run.nav_period_ns
        last = self.run.start_ns + (self.end_ns - self.run.start_ns) // nav * nav
        return self.last_output_ns is not None and self.last_output_ns >= last

    # -- input -------------------------------------------------------------------------------

    def on_batch(self, items: Sequence[tuple[str, bytes | memoryview]]) -> list[Message]:
        """Raw payloads ``(kind, payload)`` (kind ``imu`` | ``truth``) in arrival order.

        Returns ``(topic, stamp_ns, payload)`` to publish, in order. Each topic's payloads are
        decoded with one CDR call; a chunk that does not decode as a whole (a malformed message,
        mixed frame ids) is taken message by message, so every message gets its own verdict.
        """
        is_imu = np.fromiter((k == "imu" for k, _ in items), dtype=bool, count=len(items))
        imu = self._decode(cdr.IMU, [p for k, p in items if k == "imu"])
        truth = self._decode(cdr.ODOMETRY, [p for k, p in items if k != "imu"])
        return self._messages(self._feed(is_imu, imu, truth))

    def on_imu(self, payload: bytes | memoryview) -> list[Message]:
        """One raw Imu payload (``on_batch([("imu", payload)])``)."""
        return self.on_batch([("imu", payload)])

    def on_truth(self, payload: bytes | memoryview) -> list[Message]:
        """One raw truth Odometry payload (``on_batch([("truth", payload)])``)."""
        return self.on_batch([("truth", payload)])

    def feed_fields(
        self,
        imu: ImuFields | None = None,
        truth: OdometryFields | None = None,
        is_imu: NDArray[np.bool_] | None = None,
    ) -> list[Message]:
        """Decoded messages: ``is_imu[k]`` says whether the k-th message received is the next
        Imu row or the next truth row (default: the truth rows, then the Imu rows)."""
        n_imu = 0 if imu is None else len(imu.stamps_ns)
        n_truth = 0 if truth is None else len(truth.stamps_ns)
        if is_imu is None:
            is_imu = np.repeat([False, True], [n_truth, n_imu])
        dec_imu = None if imu is None else self._decoded(imu)
        dec_truth = None if truth is None else self._decoded(truth)
        return self._messages(self._feed(np.asarray(is_imu, dtype=bool), dec_imu, dec_truth))

    def feed_batches(self, batches: Sequence[Batch]) -> list[Batch]:
        """A piece of ``generate``: the batches of the input topics among ``batches`` (truth
        first, then Imu); returns the ``/navigator/*`` batches now complete."""
        spec = self.spec
        by_topic = {b.topic: b for b in batches}
        imu_payloads = by_topic[spec.imu_topic].payloads if spec.imu_topic in by_topic else []
        truth_payloads: Sequence[bytes | memoryview] = []
        if spec.truth_topic and spec.truth_topic in by_topic:
            truth_payloads = by_topic[spec.truth_topic].payloads
        is_imu = np.repeat([False, True], [len(truth_payloads), len(imu_payloads)])
        groups = self._feed(
            is_imu,
            self._decode(cdr.IMU, list(imu_payloads)),
            self._decode(cdr.ODOMETRY, list(truth_payloads)),
        )
        if self.failed:
            raise StreamError(self.failed)
        return [b for group in groups for b in self._batches(group)]

    # -- decoding ----------------------------------------------------------------------------

    def _decode(self, msgtype: str, payloads: list[bytes | memoryview]) -> _Decoded | None:
        """All ``payloads`` decoded at once, or (if they do not) kept to be decoded one by one."""
        if not payloads:
            return None
        try:
            fields = cdr.deserialize(msgtype, payloads)
        except cdr.CdrError:
            return _Decoded(None, np.zeros(0, dtype=np.int64), payloads)
        # Truth states are made after the screen (_drop_nonfinite): never from a NaN or a
        # degenerate quaternion.
        return _Decoded(fields, np.asarray(fields.stamps_ns, dtype=np.int64), None)

    def _decoded(self, fields: Any) -> _Decoded:
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64)
        states = None
        if isinstance(fields, OdometryFields) and fields.frame_id == self.earth_frame:
            states = odometry_state(fields)
        return _Decoded(fields, stamps, None, states)

    # -- the one path ------------------------------------------------------------------------

    def _feed(
        self, is_imu: NDArray[np.bool_], imu: _Decoded | None, truth: _Decoded | None
    ) -> list[NavigatorOutputs]:
        """Messages in arrival order; returns the output groups now complete.

        Stretches that only extend the current run are added in blocks (no output in between);
        a message that could change the run (none yet, a gap, a repeat) or that is rejected
        takes the one-message path, after the block before it.
        """
        is_imu, imu, truth = self._drop_nonfinite(is_imu, imu, truth)
        if imu is not None and imu.fields is not None and imu.stamps.size:  # one frame id
            self._imu_frame_changed(imu.fields.frame_id, int(imu.stamps[0]))
        out: list[NavigatorOutputs] = []
        total = is_imu.size
        imu_before = np.concatenate([[0], np.cumsum(is_imu)])  # Imu rows before item k
        imu_items = np.flatnonzero(is_imu)
        truth_items = np.flatnonzero(~is_imu)
        imu_ok = imu is not None and imu.fields is not None
        truth_ok = truth is not None and truth.states is not None
        pos = 0
        while pos < total:
            end = total
            if not truth_ok:  # the next truth message is taken alone
                k = np.searchsorted(truth_items, pos)
                end = int(truth_items[k]) if k < truth_items.size else total
            r0, r1 = int(imu_before[pos]), int(imu_before[end])
            if r1 > r0:
                if not imu_ok or self.run is None or self.period_ns is None:
                    end = int(imu_items[r0])  # taken alone
                else:  # the Imu messages continuing the run exactly
                    expected = self.run.next_imu_ns + self.period_ns * np.arange(r1 - r0)
                    bad = np.flatnonzero(imu.stamps[r0:r1] != expected)  # type: ignore[union-attr]
                    if bad.size:
                        end = int(imu_items[r0 + int(bad[0])])
            self._add_block(pos, end, imu_before, imu, truth)
            if end < total:
                out += self._one(int(end), bool(is_imu[end]), imu_before, imu, truth)
            pos = end + 1
        return out + self._advance()

    def _drop_nonfinite(
        self, is_imu: NDArray[np.bool_], imu: _Decoded | None, truth: _Decoded | None
    ) -> tuple[NDArray[np.bool_], _Decoded | None, _Decoded | None]:
        """The input without its messages holding a NaN or an infinity (each stretch logged):
        a dropped Imu is a lost Imu message (the run ends at its last complete cycle), a
        dropped truth a lost truth message (the navigator runs on from its own state)."""
        keep = np.ones(is_imu.size, dtype=bool)
        parts = []
        for dec, flag in ((imu, True), (truth, False)):
            if dec is None or dec.fields is None:
                parts.append(dec)
                continue
            fields, bad = self._screen(dec.fields, flag)
            if bad is None:
                parts.append(self._decoded(fields))
                continue
            keep[np.flatnonzero(is_imu == flag)[bad]] = False
            parts.append(None if fields is None else self._decoded(fields))
        if keep.all():
            return is_imu, parts[0], parts[1]
        return is_imu[keep], parts[0], parts[1]

    def _screen(self, fields: Any, imu: bool) -> tuple[Any, NDArray[np.bool_] | None]:
        """:func:`~strapdown_ros.stages.intake.screen` of Imu (``imu``) or truth messages: a
        dropped Imu is a lost one (the run ends at its last complete cycle), a dropped truth a
        lost truth (the navigator runs on from its own state)."""
        if imu:
            topic = self.spec.imu_topic
            return screen(fields, topic, self.events, "treated as lost: the run ends at its "
                          "last complete cycle, a new one starts from the truth",
                          lambda stamps: self.events.dropped(topic, stamps))  # fmt: skip
        return screen(fields, self.spec.truth_topic, self.events, "treated as lost: the "
                      "navigator runs on from its own state (no error messages at that "
                      "stamp)")  # fmt: skip

    def _add_block(
        self,
        pos: int,
        end: int,
        imu_before: NDArray[np.int64],
        imu: _Decoded | None,
        truth: _Decoded | None,
    ) -> None:
        """Items ``pos..end-1``: truth rows (Earth frame) and Imu rows continuing the run."""
        if end <= pos:
            return
        r0, r1 = int(imu_before[pos]), int(imu_before[end])
        t0, t1 = pos - r0, end - r1
        if t1 > t0:
            assert truth is not None and truth.states is not None
            self._add_truth(state_rows(truth.states, slice(t0, t1)))
        if r1 > r0:
            assert imu is not None and self.run is not None and self.period_ns is not None
            inc = imu_increments(imu.fields.rows(r0, r1), self.period_ns)
            self.run.add_imu(inc.stamps_ns, inc.dalpha, inc.dv)

    def _one(
        self,
        k: int,
        is_imu: bool,
        imu_before: NDArray[np.int64],
        imu: _Decoded | None,
        truth: _Decoded | None,
    ) -> list[NavigatorOutputs]:
        """Item ``k`` alone (see :meth:`_feed`)."""
        if is_imu:
            row = int(imu_before[k])
            assert imu is not None
            if imu.fields is not None:
                return self._on_imu_fields(imu.fields.rows(row, row + 1))
            assert imu.payloads is not None
            fields = decode_one(cdr.IMU, imu.payloads[row], self.spec.imu_topic, self.events)
            if fields is None:
                return []
            fields, _ = self._screen(fields, True)
            return [] if fields is None else self._on_imu_fields(fields)
        row = k - int(imu_before[k])
        assert truth is not None
        if truth.fields is None:
            assert truth.payloads is not None
            fields = decode_one(cdr.ODOMETRY, truth.payloads[row], self.spec.truth_topic,
                                self.events)  # fmt: skip
            if fields is None:
                return []
            fields, _ = self._screen(fields, False)
            if fields is None:
                return []
            one = self._decoded(fields)
            if one.states is None:
                self._wrong_frame(fields.frame_id)
                return []
            self._add_truth(one.states)
            return self._advance()
        if truth.states is None:
            self._wrong_frame(truth.fields.frame_id)
            return []
        self._add_truth(state_rows(truth.states, slice(row, row + 1)))
        return []

    def _imu_frame_changed(self, frame_id: str, stamp: int) -> bool:
        """Whether the Imu ``frame_id`` differs from the messages' before it (another body):
        then the run ends (its complete outputs are published) and a new one starts from the
        truth."""
        if self.imu_frame is None or frame_id == self.imu_frame:
            self.imu_frame = frame_id
            return False
        self.events(
            "wrong frame",
            f"{self.spec.imu_topic}: stamp {format_stamp(stamp)}: Imu frame_id {frame_id!r} "
            f"differs from {self.imu_frame!r} of the messages before (another body); the run "
            "ends and a new run starts from the truth",
            error=True,
        )
        self.imu_frame = frame_id
        if self.run is not None:
            self._flush_pending += self._outputs_of(self.run)
            self.run = None
        self.imu_buffer.clear()
        return True

    def _wrong_frame(self, frame_id: str) -> None:
        self.events(
            "wrong frame",
            f"{self.spec.truth_topic}: header.frame_id {frame_id!r} is not the Earth frame "
            f"{self.earth_frame!r}; dropped (treated as a lost truth message)",
            error=True,
        )

    def _set_period(self, period_ns: int, how: str = "from the stamps",
                    stamps: Sequence[int] = ()) -> bool:  # fmt: skip
        """Take ``period_ns`` as the IMU period T (and N from ``nav_period_s``); False if it
        cannot be. ``stamps``: the stamps the period was learned from, in arrival order; an
        interval among them longer than T (e.g. the very first one: 2T, a message lost
        before T was known) is a gap, logged like any other (:meth:`InputEvents.gap`), and the
        messages before it are not used (the run starts after it)."""
        if period_ns <= 0:
            return False
        if self.nav_period_s > 0:
            n = self.nav_period_s * 1e9 / period_ns
            if abs(n - round(n)) > 1e-6 or round(n) < 1:
                self.failed = (
                    f"nav_period_s = {self.nav_period_s:g} s is not a whole multiple of the IMU "
                    f"period T = {period_ns} ns {how}"
                )
                self.error(self.failed)
                return False
            self.n = int(round(n))
        self.period_ns = period_ns
        self.info(
            f"IMU period T = {period_ns} ns ({1e9 / period_ns:g} Hz) {how}; "
            f"T_nav = N T = {self.n} x T = {self.n * period_ns * 1e-9:g} s, P = {self.spec.p}"
        )
        used = stamps[-3] if len(stamps) >= 3 else None
        for a, b in zip(stamps[:-1], stamps[1:], strict=True):
            if b - a <= period_ns:
                continue
            lost = (b - a) // period_ns - 1 if (b - a) % period_ns == 0 else None
            self.events.gap(
                self.spec.imu_topic,
                range(a + period_ns, b, period_ns) if lost else [],
                f"{self.spec.imu_topic}: stamp {format_stamp(b)} follows {format_stamp(a)} "
                f"after {(b - a) / period_ns:g} T, before the IMU period was known ("
                + (f"{lost} message(s) missing" if lost else "off the grid of T")
                + "); the messages up to it are not used"
                + (f", the navigator starts at {format_stamp(used)}" if used is not None else ""),
                self.info,
            )
        return True

    def _add_truth(self, state: EarthState) -> None:
        """Keep truth rows (for run starts) and hand them to the current run."""
        self.truth.add(state)
        if self.run is not None:
            self.run.add_truth(state)

    def _on_imu_fields(self, fields: Any) -> list[NavigatorOutputs]:
        """One decoded Imu message; returns the output groups now complete."""
        stamp = int(fields.stamps_ns[0])
        self._imu_frame_changed(fields.frame_id, stamp)
        if self.period_ns is None:
            # T is the first interval seen twice in a row (one interval may span a gap).
            if self.failed:
                return []
            first = self.first_imu
            if first and stamp <= first[-1][0]:
                self.events(
                    "restart" if stamp < first[0][0] else "out-of-order stamp",
                    f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} does not follow "
                    f"{format_stamp(first[-1][0])} before the IMU period is known; the period "
                    "search starts again from it",
                )
                first.clear()
                self.first_stamps.clear()
            first.append((stamp, fields))
            self.first_stamps.append(stamp)
            if len(first) < 3:
                return []
            if first[-1][0] - first[-2][0] != first[-2][0] - first[-3][0]:
                del first[:-2]
                return []
            if not self._set_period(first[-1][0] - first[-2][0], stamps=self.first_stamps):
                return []
            held, self.first_imu = first, []
            for s, f in held:
                self._queue(s, f)
            return self._advance()
        self._queue(stamp, fields)
        return self._advance()

    def _queue(self, stamp: int, fields: Any) -> None:
        assert self.period_ns is not None
        inc = imu_increments(fields, self.period_ns)
        da, dv = inc.dalpha, inc.dv
        if self.run is not None:
            try:
                self.run.add_imu(inc.stamps_ns, da, dv)
                return
            except StreamError as exc:
                expected = self.run.next_imu_ns
                verdict = stamp_verdict(stamp, expected - self.period_ns, self.period_ns)
                if verdict in ("duplicate", "out-of-order"):
                    self.events(f"{verdict} stamp", f"{self.spec.imu_topic}: {exc}; dropped")
                    return
                if verdict == "restart":
                    self.events(
                        "restart",
                        f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} jumps back from "
                        f"{format_stamp(expected - self.period_ns)}: the source restarted; "
                        f"the run that started at {format_stamp(self.run.start_ns)} ends and "
                        "a new run starts from the truth",
                    )
                else:
                    self.events.gap(
                        self.spec.imu_topic,
                        range(expected, stamp, self.period_ns),
                        f"{self.spec.imu_topic}: {exc} "
                        f"({(stamp - expected) // self.period_ns} message(s) missing after "
                        f"{format_stamp(expected - self.period_ns)}); the run that started at "
                        f"{format_stamp(self.run.start_ns)} ends at its last complete cycle "
                        "and a new run starts from the truth before the next message",
                        self.info,
                    )
                self._flush_pending = self._outputs_of(self.run)
                self.run = None
        if self.imu_buffer and stamp <= self.imu_buffer[-1][0]:
            if stamp_verdict(stamp, self.imu_buffer[-1][0], self.period_ns) == "restart":
                self.imu_buffer.clear()  # the source restarted before a run could start
            else:
                self.events(
                    "out-of-order stamp",
                    f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} out of order; dropped",
                )
                return
        if self.imu_buffer and stamp != self.imu_buffer[-1][0] + self.period_ns:
            self.imu_buffer.clear()  # a gap before any run started: restart the search
        self.imu_buffer.append((stamp, da, dv))

    # -- runs --------------------------------------------------------------------------------

    def _try_start(self) -> None:
        if self.run is not None or self.period_ns is None or not self.imu_buffer:
            return
        spec, t = self.spec, self.period_ns
        if spec.initialization == "scenario":
            assert self.start_ns is not None and self.initial is not None
            while self.imu_buffer and self.imu_buffer[0][0] < self.start_ns + t:
                self.imu_buffer.pop(0)
            if not self.imu_buffer or self.imu_buffer[0][0] != self.start_ns + t:
                if self.imu_buffer and not self.failed:
                    self.failed = (
                        f"initialization 'scenario' needs the IMU message at "
                        f"{format_stamp(self.start_ns + t)} (scenario start + T); the first one "
                        f"received is {format_stamp(self.imu_buffer[0][0])}"
                    )
                    self.error(self.failed)
                return
            self._start(self.start_ns, initial_state_from_scenario(self.initial, spec), None)
            return
        truth = self.truth.sorted()
        if truth is None:
            return
        # The first truth stamp s (in stamp order) whose next IMU message s + T is buffered;
        # the IMU messages before s + T (or, without one, before the last s + T) are dropped.
        stamps = np.asarray(truth.stamps_ns, dtype=np.int64)
        buffered = np.array([b[0] for b in self.imu_buffer], dtype=np.int64)
        hits = np.flatnonzero(np.isin(stamps + t, buffered))
        cut = int(stamps[hits[0]] if hits.size else stamps[-1]) + t
        del self.imu_buffer[: int(np.searchsorted(buffered, cut))]
        if hits.size:
            row = int(hits[0])
            self._start(
                int(stamps[row]),
                initial_state_from_truth(truth, row, spec),
                np.asarray(truth.omega_eb_b)[row],
            )

    def _start(self, start_ns: int, initial: NavState, omega: F64 | None) -> None:
        assert self.period_ns is not None
        spec = self.spec
        self.run = NavigatorRun(
            spec, start_ns, self.period_ns, initial, bool(spec.truth_topic), omega,
            self.earth_frame, self.n,
        )  # fmt: skip
        truth = self.truth.sorted()
        if truth is not None:
            after = np.flatnonzero(np.asarray(truth.stamps_ns) >= start_ns)
            if after.size:
                self.run.add_truth(state_rows(truth, after))
        buf, self.imu_buffer = self.imu_buffer, []
        if buf:
            self.run.add_imu(
                np.array([b[0] for b in buf], dtype=np.int64),
                np.concatenate([b[1] for b in buf]),
                np.concatenate([b[2] for b in buf]),
            )
        self.runs += 1
        how = "truth" if spec.initialization == "truth" else "the scenario's initial state"
        self.info(f"run {self.runs} starts at {format_stamp(start_ns)} (initial state from {how})")

    def _advance(self) -> list[NavigatorOutputs]:
        flushed, self._flush_pending = self._flush_pending, []
        self._try_start()
        if self.run is None:
            return flushed
        groups = self._outputs_of(self.run)
        if self._diverged:  # its state is not finite: a new run from the truth
            self._diverged = False
            self.info(f"the run that started at {format_stamp(self.run.start_ns)} diverged; a "
                      "new run starts from the truth before the next IMU message")  # fmt: skip
            self.run = None
        return [*flushed, *groups]

    def _outputs_of(self, run: NavigatorRun) -> list[NavigatorOutputs]:
        groups = []
        while True:
            out = self._output_group(run)
            if out is None:
                return groups
            groups.append(out)

    def _output_group(self, run: NavigatorRun) -> NavigatorOutputs | None:
        out = run.outputs()
        for stamp in run.truth_lost:
            self.events(
                "truth lost",
                f"{self.spec.truth_topic}: no truth at output stamp {format_stamp(stamp)} (a "
                "later one arrived); the output is published without its error messages and "
                "the navigator runs on from its own state",
            )
        run.truth_lost.clear()
        if out is None:
            return None
        out = self._finite_outputs(out)
        if out is None:
            return self._output_group(run)
        self.published_outputs += len(out)
        self.last_output_ns = int(out.odom.stamps_ns[-1])
        if out.error_position is not None:
            dr = np.asarray(out.error_position.vector)
            horizontal = np.hypot(dr[:, 0], dr[:, 1])
            self.final_errors = {
                "horizontal_m": float(horizontal[-1]),
                "vertical_m": float(abs(dr[-1, 2])),
                "max_horizontal_m": max(
                    self.final_errors.get("max_horizontal_m", 0.0), float(horizontal.max())
                ),
            }
        return out

    def _finite_outputs(self, out: NavigatorOutputs) -> NavigatorOutputs | None:
        """``out`` without the outputs holding a non-finite number (a diverged solution, e.g.
        an unstable vertical channel): never published, each stretch logged."""
        # The odometry holds the whole solution (the fix and, with finite truth, the errors are
        # computed from it): checking it is enough.
        bad = nonfinite_rows(out.odom)
        if bad is None:
            return None if len(out) == 0 else out
        stamps = np.asarray(out.odom.stamps_ns, dtype=np.int64)
        for a, b in stretches(bad):
            self.events(
                "non-finite output",
                f"{self.output_topics['odom']}: the solution at {format_stamp(int(stamps[a]))}"
                + (f"..{format_stamp(int(stamps[b]))}" if b > a else "")
                + " is not finite (the navigator diverged); not published",
                error=True,
            )
        self._diverged = True
        if bad.all():
            return None
        kept = {k: without_rows(f, bad) for k, f in out.items()}
        return NavigatorOutputs(**kept)

    # -- serialization -----------------------------------------------------------------------

    def _batches(self, group: NavigatorOutputs) -> list[Batch]:
        return [batch(self.output_topics[k], f) for k, f in group.items()]

    def _messages(self, groups: list[NavigatorOutputs]) -> list[Message]:
        out: list[Message] = []
        for group in groups:
            batches = self._batches(group)
            out += [
                (batches[b].topic, int(batches[b].stamps_ns[i]), batches[b].payloads[i])
                for b, i, _ in merge_order(batches)
            ]
        return out


def navigate_messages(
    spec: NavigatorSpec,
    imu: ImuFields,
    truth: OdometryFields | None,
    earth_frame: str = "earth",
    output_topics: Mapping[str, str] | None = None,
    initial: Initial | None = None,
    start_ns: int | None = None,
) -> dict[str, list[bytes]]:
    """What ``navigator_node`` publishes for whole topics received in stamp order (truth
    before Imu at equal stamps): output key (:data:`OUTPUT_TOPICS`) → payloads.

    ``spec``: resolved; ``initial``, ``start_ns``: for ``initialization: scenario``. Used by
    ``strapdown-sim replay`` to check a live replay.
    """
    topics = dict(output_topics or {k: k for k in OUTPUT_TOPICS})
    stage = NavigatorStage(
        spec, topics, initial=initial, start_ns=start_ns, earth_frame=earth_frame
    )
    n_truth = 0 if truth is None else len(truth.stamps_ns)
    stamps = np.concatenate(
        [np.asarray(truth.stamps_ns if truth is not None else [], dtype=np.int64),
         np.asarray(imu.stamps_ns, dtype=np.int64)]
    )  # fmt: skip
    order = np.argsort(stamps, kind="stable")
    out: dict[str, list[bytes]] = {}
    by_topic = {v: k for k, v in topics.items()}
    for topic, _, payload in stage.feed_fields(imu, truth, order >= n_truth):
        out.setdefault(by_topic[topic], []).append(bytes(payload))
    return out
