"""The variation stage: a second IMU at a lever arm / on a scanning platform, streaming.

Savage 2020 Method 2 (and Method 1 offline), theory in docs/variation.md and
docs/theory/offsets.md.
"""

from __future__ import annotations

import dataclasses
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, merge_order, stream_batches
from strapdown_ros.config import Scenario
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.variation import OffsetArrays, generate_variation
from strapdown_ros.messages import ImuFields, OdometryFields, stream_from_messages

IMU, ODOM = "imu", "odom"


def variation_settings(scenario: Scenario) -> tuple[int, str]:
    """``variation.method`` (default 2) and ``variation.gravity`` (default ``full``)."""
    cfg = scenario.variation or {}
    return int(cfg.get("method", 2)), str(cfg.get("gravity", "full"))


def scenario_offsets(scenario: Scenario, samples: int) -> OffsetArrays:
    """Offsets of the scenario's ``variation`` section on the output cycle grid m = 0..N-1."""
    from strapdown_ros.core.offsets import offset_history

    history = offset_history(scenario.variation or {}, scenario.period_ns * 1e-9, samples - 1)
    return OffsetArrays(history.lever_arm, history.displacement, history.c_bvar_bref)


def variation_streams(scenario: Scenario, reference: Stream) -> tuple[Stream, Stream]:
    """The variation and the regenerated reference (zero offsets, same routines) of a scenario."""
    method, gravity = variation_settings(scenario)
    samples = reference.cycles + 1
    variation = generate_variation(reference, scenario_offsets(scenario, samples), method, gravity)
    regenerated = generate_variation(reference, OffsetArrays.zero(samples), method, gravity)
    return variation, regenerated


def variation_batches(scenario: Scenario, variation: Stream, regenerated: Stream) -> list[Batch]:
    """Serialized ``/variation/*`` and ``/variation/reference/*`` batches."""
    rec = scenario.recording
    frame = rec.frames["variation_imu"]
    batches = stream_batches(
        variation,
        imu_topic=rec.topics["variation_imu"],
        odom_topic=rec.topics["variation_odom"],
        fix_topic=rec.topics["variation_fix"],
        body_frame=frame,
        earth_frame=rec.frames["earth"],
    )
    batches += stream_batches(
        regenerated,
        imu_topic=rec.topics["variation_reference_imu"],
        odom_topic=rec.topics["variation_reference_odom"],
        fix_topic=None,
        body_frame=rec.frames["reference_imu"],
        earth_frame=rec.frames["earth"],
    )
    return batches


class _VariationStreamer:
    """Variation and regenerated reference computed piece by piece as the reference arrives.

    Works on the decoded reference messages (like ``variation_node``) and on windows that start
    one cycle before the last emitted even cycle (``lead=1``): the windows give bit-identical
    results to one vectorized run over the whole stream (Method 2 pairs are independent).
    """

    def __init__(self, scenario: Scenario, total: int) -> None:
        self.scenario = scenario
        self.method, self.gravity = variation_settings(scenario)
        self.offsets = scenario_offsets(scenario, total + 1)
        self.zero = OffsetArrays.zero(total + 1)
        self.imu: ImuFields | None = None
        self.odom: OdometryFields | None = None
        self.emitted = -1  # last variation cycle published (even), -1: none yet
        self.base = 0  # cycle of self.odom's first row (self.imu's first row is cycle base + 1)
        rec = scenario.recording
        self.imu_topic = rec.topics["reference_imu"]
        self.odom_topic = rec.topics["reference_odom"]

    def feed(self, batches: list[Batch], res: dict[str, Residuals]) -> list[Batch]:
        """Take one reference piece's batches; return the variation batches now computable."""
        by_topic = {b.topic: b for b in batches}
        imu_b, odom_b = by_topic[self.imu_topic], by_topic[self.odom_topic]
        imu = cdr.deserialize(imu_b.msgtype, imu_b.payloads)
        odom = cdr.deserialize(odom_b.msgtype, odom_b.payloads)
        self.imu = imu if self.imu is None else self.imu.append(imu)  # type: ignore[union-attr]
        self.odom = odom if self.odom is None else self.odom.append(odom)  # type: ignore[union-attr]
        avail = self.base + len(self.odom) - 1  # reference cycles base..avail are held
        last = (avail - 1) - (avail - 1) % 2  # last even cycle with its look-ahead sample
        if last < 2 or last <= self.emitted:
            return []
        lead = 0 if self.emitted < 0 else 1
        a = 0 if lead == 0 else self.emitted - 1
        b0 = self.base
        window = stream_from_messages(
            self.imu.rows(a - b0, last + 1 - b0),  # type: ignore[union-attr]
            self.odom.rows(a - b0, last + 2 - b0),
            self.scenario.gravity_model,
            e0_epoch_ns=self.scenario.start_time_ns,
        )
        sl = slice(a, last + 2)
        off = OffsetArrays(
            self.offsets.lever_arm[sl], self.offsets.displacement[sl], self.offsets.c_bvar_bref[sl]
        )
        zero = OffsetArrays(
            self.zero.lever_arm[sl], self.zero.displacement[sl], self.zero.c_bvar_bref[sl]
        )
        variation = generate_variation(window, off, self.method, self.gravity, lead)
        regenerated = generate_variation(window, zero, self.method, self.gravity, lead)
        res["variation"] = stream_residuals(variation)
        res["variation/reference"] = stream_residuals(regenerated)
        out = variation_batches(self.scenario, variation, regenerated)
        if lead:
            out = [_drop_up_to(b, variation.t0_ns) for b in out]  # truth already published
        self.emitted = last
        # keep only what the next window (from cycle last - 1) needs: memory stays bounded
        keep = last - 1 - self.base
        self.odom = self.odom.rows(keep, len(self.odom))
        self.imu = self.imu.rows(keep, len(self.imu))  # type: ignore[union-attr]
        self.base = last - 1
        return out


Log = Callable[[str], None]


#: An older stamp at most this many cycles behind the last one is a late message (dropped);
#: a larger backward jump means the input stream restarted (the solver starts afresh).
MAX_LATE_CYCLES = 10


#: Longest window (cycles) solved at once when the node catches up on a backlog.
MAX_WINDOW = 401


def format_stamp(stamp_ns: int) -> str:
    """``sec.nanosec`` of a stamp (ns since the epoch)."""
    return f"{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


def _concat(items: list) -> object:
    """One field container of several one-message containers of the same type."""
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


@dataclass
class Timing:
    """Processing time of the solved windows (wall and CPU seconds, one entry per window)."""

    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    decode_wall: float = 0.0
    decoded: int = 0

    def summary(self, cycles: int) -> str:
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


class VariationSolver:
    """The streaming variation (no rclpy): messages in, serialized messages out.

    Parameters
    ----------
    scenario : Scenario
        Supplies the cycle grid (``start_time_ns``, T), the gravitation model, the variation
        settings and the output topic/frame names (``recording``).
    cycles : int
        M, the scenario's last reference cycle; later stamps are ignored.
    offsets : OffsetArrays
        The scenario's offsets at cycles 0..M
        (:func:`~strapdown_ros.stages.variation.scenario_offsets`).
    info, warn, error : callables
        Loggers.

    :meth:`on_message` takes one raw payload of the Imu or Odometry input and returns the
    ``(topic, stamp_ns, payload)`` to publish, in merge order.

    Runs. A run is a stretch of consecutive, consistent reference cycles ``start..``; its
    output equals ``generate_variation`` on the reference restricted to those cycles (the first
    run of an uninterrupted stream from cycle 0: the offline output). A gap, a duplicate with
    different content, a frame change or an Imu/Odometry frame mismatch ends the run and
    starts a new one at the first cycle whose data is all consistent; the published output
    never overlaps between runs. An out-of-order message is dropped (the jump before it already
    started a new run); an identical duplicate is dropped.
    """

    def __init__(
        self,
        scenario: Scenario,
        cycles: int,
        offsets: OffsetArrays,
        info: Log = print,
        warn: Log = print,
        error: Log = print,
    ) -> None:
        self.scenario = scenario
        self.method, self.gravity = variation_settings(scenario)
        self.cycles = cycles
        self.offsets = offsets
        self.t0_ns = scenario.start_time_ns
        self.period_ns = scenario.period_ns
        self.earth_frame = scenario.recording.frames["earth"]
        self.info, self.warn, self.error = info, warn, error
        self.topics = {
            IMU: scenario.recording.topics["reference_imu"],
            ODOM: scenario.recording.topics["reference_odom"],
        }
        self.last: dict[str, int | None] = {IMU: None, ODOM: None}
        self.last_payload: dict[str, bytes] = {IMU: b"", ODOM: b""}
        self.buffer: dict[str, dict[int, object]] = {IMU: {}, ODOM: {}}
        self.run_start: int | None = None
        self.published: int | None = None  # last cycle published in the current run
        self.body_frame: str | None = None  # Imu frame id (= Odometry child) of the run
        self.runs = 0  # runs that published something
        self.published_cycles = 0
        self.timing = Timing()
        self._warned_beyond = False
        self._warned_frame = False

    # ------------------------------------------------------------------------------------------

    def stamp(self, m: int) -> str:
        return format_stamp(self.t0_ns + m * self.period_ns)

    def describe(self, m: int) -> str:
        return f"cycle {m} (stamp {self.stamp(m)})"

    @property
    def started(self) -> bool:
        return self.run_start is not None

    @property
    def finished(self) -> bool:
        """True when the current run cannot publish more cycles of the scenario."""
        if self.run_start is None:
            return False
        base = self.run_start if self.published is None else self.published
        return base + 3 > self.cycles

    def _first_run_cycle(self, kind: str, m: int) -> int:
        """First run start that needs no data of ``kind`` before cycle ``m``.

        A run starting at r uses Odometry r.. and Imu r+1.. (the increments after its state).
        """
        return m if kind == ODOM else m - 1

    def _reset(self) -> None:
        """Forget everything (the input restarted)."""
        self.last = {IMU: None, ODOM: None}
        self.last_payload = {IMU: b"", ODOM: b""}
        self.buffer = {IMU: {}, ODOM: {}}
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
        for kind, low in ((ODOM, start), (IMU, start + 1)):
            buf = self.buffer[kind]
            for m in [m for m in buf if m < low]:
                del buf[m]

    # ------------------------------------------------------------------------------------------

    def on_batch(self, items: list[tuple[str, bytes]]) -> list[tuple[str, int, bytes]]:
        """Raw payloads ``(kind, payload)`` in arrival order, then :meth:`advance`.

        The same as :meth:`on_message` with ``solve=False`` one by one followed by
        :meth:`advance`, but each topic's payloads are decoded with one CDR call (a batch that
        does not decode as a whole is decoded one by one, so each bad message is reported).
        """
        decoded: dict[str, list[object] | None] = {}
        for kind, msgtype in ((IMU, cdr.IMU), (ODOM, cdr.ODOMETRY)):
            payloads = [p for k, p in items if k == kind]
            decoded[kind] = None
            if payloads:
                t = time.perf_counter()
                try:
                    fields = cdr.deserialize(msgtype, payloads)
                except cdr.CdrError:
                    continue
                decoded[kind] = [fields.rows(i, i + 1) for i in range(len(payloads))]  # type: ignore[attr-defined]
                self.timing.decode_wall += time.perf_counter() - t
                self.timing.decoded += len(payloads)
        out: list[tuple[str, int, bytes]] = []
        index = {IMU: 0, ODOM: 0}
        for kind, payload in items:
            rows = decoded[kind]
            msg = None if rows is None else rows[index[kind]]
            index[kind] += 1
            out += self.on_message(kind, payload, solve=False, decoded=msg)
        return out + self.advance()

    def on_message(
        self, kind: str, payload: bytes, solve: bool = True, decoded: object | None = None
    ) -> list[tuple[str, int, bytes]]:
        """Take one raw payload of ``kind`` ('imu' | 'odom'); return what to publish.

        With ``solve=False`` the message is only buffered; a later :meth:`advance` solves
        everything pending in one window (how the node catches up when input piles up). A
        message that breaks the sequence (gap, repeat, jump) first flushes what the current run
        can still solve, so deferring never changes what is published.
        """
        last = self.last[kind]
        if not solve and last is not None and len(payload) >= 12:
            little = payload[1] & 1
            sec, nanosec = struct.unpack_from("<iI" if little else ">iI", payload, 4)
            stamp = sec * 1_000_000_000 + nanosec
            if stamp != self.t0_ns + (last + 1) * self.period_ns:
                return self.advance() + self._on_message(kind, payload, solve, decoded)
        return self._on_message(kind, payload, solve, decoded)

    def _on_message(
        self, kind: str, payload: bytes, solve: bool, decoded: object | None = None
    ) -> list[tuple[str, int, bytes]]:
        topic = self.topics[kind]
        msgtype = cdr.IMU if kind == IMU else cdr.ODOMETRY
        msg = decoded
        if msg is None:
            t = time.perf_counter()
            try:
                msg = cdr.deserialize(msgtype, [payload])
            except cdr.CdrError as exc:
                self.error(f"{topic}: rejected a message that is not a {msgtype} of the "
                           f"expected layout: {exc}")  # fmt: skip
                return []
            self.timing.decode_wall += time.perf_counter() - t
            self.timing.decoded += 1
        stamp = int(msg.stamps_ns[0])  # type: ignore[attr-defined]
        offset = stamp - self.t0_ns
        if offset < 0 or offset % self.period_ns:
            self.warn(
                f"{topic}: stamp {format_stamp(stamp)} is not on the scenario's cycle grid "
                f"(start {format_stamp(self.t0_ns)}, T = {self.period_ns} ns); dropped"
            )
            return []
        m = offset // self.period_ns
        if m > self.cycles or (kind == IMU and m == 0):
            if not self._warned_beyond:
                self._warned_beyond = True
                self.warn(
                    f"{topic}: {self.describe(m)} is outside the scenario's cycles "
                    f"({'1' if kind == IMU else '0'}..{self.cycles}); such messages are dropped"
                )
            return []

        last = self.last[kind]
        if last is None:
            self.last[kind], self.last_payload[kind] = m, bytes(payload)
            self.restart(self._first_run_cycle(kind, m), f"first message on {topic}")
        elif m == last + 1:
            self.last[kind], self.last_payload[kind] = m, bytes(payload)
        elif m == last:
            if bytes(payload) == self.last_payload[kind]:
                self.warn(f"{topic}: duplicate stamp {format_stamp(stamp)} (cycle {m}), "
                          "identical content; dropped")  # fmt: skip
                return []
            self.warn(f"{topic}: duplicate stamp {format_stamp(stamp)} (cycle {m}) "
                      "with different content; both dropped")  # fmt: skip
            self.buffer[kind].pop(m, None)
            self.restart(self._first_run_cycle(kind, m + 1), f"{topic}: duplicate")
            return []
        elif m < last - MAX_LATE_CYCLES:
            self.warn(
                f"{topic}: stamp {format_stamp(stamp)} (cycle {m}) jumps back "
                f"{last - m} cycles from {format_stamp(self.t0_ns + last * self.period_ns)} "
                f"(cycle {last}): the input restarted; starting afresh"
            )
            self._reset()
            self.last[kind], self.last_payload[kind] = m, bytes(payload)
            self.restart(self._first_run_cycle(kind, m), f"first message on {topic} after the jump")
        elif m < last:
            self.warn(
                f"{topic}: out-of-order stamp {format_stamp(stamp)} (cycle {m}) after "
                f"{format_stamp(self.t0_ns + last * self.period_ns)} (cycle {last}); dropped"
            )
            return []
        else:
            self.warn(
                f"{topic}: gap: stamp {format_stamp(stamp)} (cycle {m}) follows "
                f"{format_stamp(self.t0_ns + last * self.period_ns)} (cycle {last}); "
                f"{m - last - 1} cycle(s) missing"
            )
            self.last[kind], self.last_payload[kind] = m, bytes(payload)
            self.restart(self._first_run_cycle(kind, m), f"{topic}: gap")

        if kind == ODOM and msg.frame_id != self.earth_frame:  # type: ignore[attr-defined]
            self.error(
                f"{topic}: {self.describe(m)}: header.frame_id {msg.frame_id!r} is not the "  # type: ignore[attr-defined]
                f"Earth frame {self.earth_frame!r} (recording.frames.earth); rejected, the "
                f"solution restarts at cycle {m + 1}"
            )
            self.restart(m + 1, "", log=False)
            return []
        assert self.run_start is not None
        if m < self.run_start + (kind == IMU):
            return []  # before the current run (the other topic restarted it later)
        self.buffer[kind][m] = msg
        if not self._check_frames(m):
            return []
        return self.advance() if solve else []

    def _check_frames(self, m: int) -> bool:
        """Imu frame = Odometry child frame at cycle m, and constant within the run."""
        imu = self.buffer[IMU].get(m)
        odom = self.buffer[ODOM].get(m)
        if imu is not None and odom is not None and imu.frame_id != odom.child_frame_id:  # type: ignore[attr-defined]
            self.error(
                f"{self.describe(m)}: Imu frame_id {imu.frame_id!r} differs from the Odometry "  # type: ignore[attr-defined]
                f"child_frame_id {odom.child_frame_id!r}: the reference messages do not "  # type: ignore[attr-defined]
                f"describe one body; rejected, the solution restarts at cycle {m + 1}"
            )
            self.buffer[IMU].pop(m, None)
            self.buffer[ODOM].pop(m, None)
            self.restart(m + 1, "", log=False)
            return False
        for msg, name in ((imu, "Imu frame_id"), (odom, "Odometry child_frame_id")):
            if msg is None:
                continue
            frame = msg.frame_id if msg is imu else msg.child_frame_id  # type: ignore[attr-defined]
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
                self.error(
                    f"{self.describe(m)}: {name} {frame!r} differs from the run's body frame "
                    f"{self.body_frame!r}; rejected, the solution restarts at cycle {m + 1}"
                )
                self.buffer[IMU].pop(m, None)
                self.buffer[ODOM].pop(m, None)
                self.restart(m + 1, "", log=False)
                return False
        return True

    # ------------------------------------------------------------------------------------------

    def _catch_up_samples(self) -> int:
        """Odd window length 5 + 2k covering every consecutive cycle already received."""
        assert self.published is not None
        first = self.published - 1
        odom, imu = self.buffer[ODOM], self.buffer[IMU]
        last = first + 4
        while (
            last + 2 - first < MAX_WINDOW
            and last + 2 <= self.cycles
            and all(m in odom and m in imu for m in (last + 1, last + 2))
        ):
            last += 2
        return last - first + 1

    def _window(self, first: int, samples: int) -> tuple[object, object] | None:
        """Imu first+1.. and Odometry first.. of ``samples`` cycles, if all have arrived."""
        odom, imu = self.buffer[ODOM], self.buffer[IMU]
        cycles = range(first, first + samples)
        if not all(m in odom for m in cycles) or not all(m in imu for m in cycles[1:]):
            return None
        return _concat([imu[m] for m in cycles[1:]]), _concat([odom[m] for m in cycles])

    def advance(self) -> list[tuple[str, int, bytes]]:
        """Solve every window whose look-ahead has arrived; return the messages to publish."""
        out: list[tuple[str, int, bytes]] = []
        while self.run_start is not None and not self.finished:
            if self.published is None:
                first, samples, lead = self.run_start, 4, 0
            else:
                # When input has piled up (the node fell behind), solve every complete pair in
                # one longer window: lead=1 windows of any odd length give the same bits as the
                # 5-cycle ones, at a fraction of the per-cycle cost, so the node catches up.
                first, samples, lead = self.published - 1, self._catch_up_samples(), 1
            window = self._window(first, samples)
            if window is None:
                break
            wall, cpu = time.perf_counter(), time.thread_time()
            out += self._solve(first, samples, lead, *window)
            self.timing.wall.append(time.perf_counter() - wall)
            self.timing.cpu.append(time.thread_time() - cpu)
            new_last = first + samples - 2 if lead else first + 2
            self.runs += self.published is None
            self.published_cycles += new_last - (self.published if lead else first - 1)
            self.published = new_last
            for kind, low in ((ODOM, new_last - 1), (IMU, new_last)):
                buf = self.buffer[kind]
                for m in [m for m in buf if m < low]:
                    del buf[m]
        return out

    def _solve(
        self, first: int, samples: int, lead: int, imu: ImuFields, odom: OdometryFields
    ) -> list[tuple[str, int, bytes]]:
        reference = stream_from_messages(
            imu, odom, self.scenario.gravity_model, e0_epoch_ns=self.t0_ns
        )
        sl = slice(first, first + samples)
        offsets = OffsetArrays(
            self.offsets.lever_arm[sl], self.offsets.displacement[sl], self.offsets.c_bvar_bref[sl]
        )
        variation = generate_variation(reference, offsets, self.method, self.gravity, lead=lead)
        regenerated = generate_variation(
            reference, OffsetArrays.zero(samples), self.method, self.gravity, lead=lead
        )
        batches = variation_batches(self.scenario, variation, regenerated)
        if self.published is not None:
            done = self.t0_ns + self.published * self.period_ns
            batches = [_drop_up_to(b, done) for b in batches]
        return [
            (batches[k].topic, stamp, bytes(batches[k].payloads[i]))
            for k, i, stamp in merge_order(batches)
        ]
