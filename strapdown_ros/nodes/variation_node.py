"""``variation_node``: the variation and the regenerated reference, live (SPEC §4, §6).

It subscribes raw to the reference Imu and Odometry topics, decodes every payload with the
project's CDR codec, pairs Imu m with Odometry m by stamp (``m = (stamp - start_time) / T``, the
scenario's cycle grid) and, as soon as the look-ahead cycle 2n+1 of an even cycle 2n has
arrived, solves the pair (2n-1, 2n) with :func:`~strapdown_ros.core.variation.generate_variation`
on the 5-cycle window 2n-3..2n+1 (``lead=1``; at the start of a run the window is cycles 0..3,
``lead=0``, giving cycles 0..2) twice: with the scenario's offsets at the absolute cycles (the
variation) and with zero offsets (the regenerated reference). The new messages are serialized
by the same :func:`~strapdown_ros.dataset.variation_batches` as ``strapdown-sim generate`` and
published raw in :func:`~strapdown_ros.bag.batches.merge_order`. Because every window
reproduces the vectorized offline solution bit for bit, the published messages are identical to
the bag's, byte for byte. Input is taken in batches (:class:`~strapdown_ros.nodes._common.
InputBatch`): the output lags the input by 1–2 cycles plus at most ``batch_period_s``.

A gap, a duplicate with different content or an out-of-order stamp breaks that equivalence: it
is logged (WARN, with the stamps) and the solution restarts from the next consistent cycle as a
new run (``lead=0``, one-sided velocity constraint), which then differs from an uninterrupted
offline run by design. :class:`VariationSolver` holds that logic and no rclpy; the node wraps it.
Parameters and behaviour: docs/nodes.md.

Exit status: 0 done (or stopped by SIGINT/SIGTERM), 1 failure while running, 2 invalid
parameter or scenario.
"""

from __future__ import annotations

import dataclasses
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, merge_order
from strapdown_ros.core.variation import GRAVITY_MODES, OffsetArrays, generate_variation
from strapdown_ros.dataset import scenario_offsets, variation_batches, variation_settings
from strapdown_ros.messages import ImuFields, OdometryFields, stream_from_messages
from strapdown_ros.nodes._batched import BatchedInputNode
from strapdown_ros.nodes._common import (
    ParameterError,
    declare_scenario,
    declare_string,
    message_class,
    qos_from_parameters,
    run_node,
)
from strapdown_ros.reference import build_trajectory, output_cycles
from strapdown_ros.scenario import Scenario, ScenarioError

NODE_NAME = "variation_node"
IMU, ODOM = "imu", "odom"
#: Input topic parameters and the recording.topics key each defaults to.
INPUT_PARAMETERS = {
    "reference_imu_topic": "reference_imu",
    "reference_odom_topic": "reference_odom",
}
#: Output topic parameters and the recording.topics key each defaults to.
OUTPUT_PARAMETERS = {
    "variation_imu_topic": "variation_imu",
    "variation_odom_topic": "variation_odom",
    "variation_fix_topic": "variation_fix",
    "variation_reference_imu_topic": "variation_reference_imu",
    "variation_reference_odom_topic": "variation_reference_odom",
}

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
        The scenario's offsets at cycles 0..M (:func:`~strapdown_ros.dataset.scenario_offsets`).
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


# ----------------------------------------------------------------------------------------------


class VariationNode(BatchedInputNode):
    """Reference Imu/Odometry in; variation and regenerated reference out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        if scenario.variation is None:
            raise ScenarioError("variation", "missing: the scenario defines no variation")
        method, gravity = _check_settings(scenario)
        cycles = output_cycles(scenario, build_trajectory(scenario))
        try:
            offsets = scenario_offsets(scenario, cycles + 1)
        except ValueError as exc:  # offsets name the dotted key: "variation.x: problem"
            key, sep, problem = str(exc).partition(": ")
            raise ScenarioError(key if sep else "variation", problem if sep else str(exc)) from None

        topics = dict(scenario.recording.topics)
        names: dict[str, str] = {}
        for name, key in {**INPUT_PARAMETERS, **OUTPUT_PARAMETERS}.items():
            topic = declare_string(
                self, name, topics[key], f"topic (default recording.topics.{key})"
            )
            if not topic:
                raise ParameterError(name, "must not be empty")
            topics[key] = topic
            names[topic] = name
        used = [topics[k] for k in {**INPUT_PARAMETERS, **OUTPUT_PARAMETERS}.values()]
        for topic in used:
            if used.count(topic) > 1:
                raise ParameterError(names[topic], f"topic {topic} is used twice: {used}")
        self.qos = qos_from_parameters(self)
        # A window costs ~2.3 ms of CPU plus ~0.1 ms per cycle (numpy call overhead on small
        # arrays dominates): batches of batch_period_s (default 10 ms) keep 1 kHz affordable.
        self.declare_batched_input("the last cycle")

        recording = dataclasses.replace(scenario.recording, topics=topics)
        self.scenario = dataclasses.replace(scenario, recording=recording)
        log = self.get_logger()
        self.solver = VariationSolver(
            self.scenario,
            cycles,
            offsets,
            info=log.info,
            warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg, throttle_duration_sec=1.0),
        )
        self.inputs = {IMU: topics["reference_imu"], ODOM: topics["reference_odom"]}
        for key in OUTPUT_PARAMETERS.values():
            topic = topics[key]
            msgtype = cdr.NAVSATFIX if key.endswith("fix") else cdr.IMU
            msgtype = cdr.ODOMETRY if key.endswith("odom") else msgtype
            try:
                self.add_output(topic, message_class(msgtype), self.qos)
            except Exception as exc:  # invalid topic name
                raise ParameterError(names[topic], str(exc)) from exc
        self._input_subscriptions: list = []
        m_var = cycles - 1 - (cycles - 1) % 2
        log.info(
            f"scenario {scenario.path} ({scenario.name}): reference cycles 0..{cycles} at "
            f"{scenario.rate_hz:g} Hz, variation cycles 0..{m_var}, method {method}, gravity "
            f"{gravity}; input {self.inputs[IMU]}, {self.inputs[ODOM]}; output "
            + ", ".join(self.output_pubs)
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        for kind, topic in self.inputs.items():
            msgtype = cdr.IMU if kind == IMU else cdr.ODOMETRY
            try:
                sub = self.create_subscription(
                    message_class(msgtype), topic, self._buffer(kind), self.qos, raw=True
                )
            except Exception as exc:
                param = next(p for p, k in INPUT_PARAMETERS.items() if k == f"reference_{kind}")
                raise ParameterError(param, str(exc)) from exc
            self._input_subscriptions.append(sub)
        return f"{self.inputs[IMU]} and {self.inputs[ODOM]}"

    def _idle_stop(self) -> None:
        self.get_logger().warning(
            f"no input for {self.run_control.idle_timeout_s:g} s; stopping before the end of "
            f"the scenario (last published: cycle {self.solver.published})"
        )

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        s = self.solver
        total = sum(self.counts.values())
        lines = [
            f"published {total} messages ({s.published_cycles} cycles, {s.runs} run(s)) in "
            f"{wall_s:.3f} s of wall time; process CPU {cpu_s:.3f} s "
            f"({100 * cpu_s / max(wall_s, 1e-9):.0f} % of one core)",
            f"processing: {s.timing.summary(s.published_cycles)}",
        ]
        lines += [f"  {t}: {n}" for t, n in self.counts.items()]
        return "\n".join(lines)


def _check_settings(scenario: Scenario) -> tuple[int, str]:
    """``variation.method`` / ``gravity`` the node supports (ScenarioError naming the key)."""
    cfg = scenario.variation or {}
    try:
        method, gravity = variation_settings(scenario)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(
            "variation.method", f"must be 1 or 2, got {cfg.get('method')!r}"
        ) from exc
    if method == 1:
        raise ScenarioError(
            "variation.method",
            "variation_node implements Method 2 only (Method 1's velocity recursion runs "
            "through the whole stream); use strapdown-sim generate for Method 1",
        )
    if method != 2:
        raise ScenarioError("variation.method", f"must be 1 or 2, got {method!r}")
    if gravity not in GRAVITY_MODES:
        raise ScenarioError(
            "variation.gravity", f"must be one of {', '.join(GRAVITY_MODES)}, got {gravity!r}"
        )
    return method, gravity


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(VariationNode, NODE_NAME, args)
