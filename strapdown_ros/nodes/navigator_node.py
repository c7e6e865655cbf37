"""``navigator_node``: the multirate b–l split navigator, live (SPEC §4, issue 5).

It subscribes raw to an IMU topic (default ``/variation/imu``) and, optionally, a truth
Odometry topic (default ``/variation/odom``), decodes every payload with the project's CDR
codec, and feeds a :class:`~strapdown_ros.navigator.NavigatorRun` — the very object
``strapdown-sim generate`` feeds — so ``/navigator/odom``, ``/navigator/fix`` and
``/navigator/error/{position,velocity,attitude}`` are published with the same bytes as the
bag's. :class:`NavigatorSolver` holds that logic and no rclpy; the node wraps it.

* **Rate.** T is detected from the stamps of the first two consecutive IMU messages (SPEC §2)
  and N from ``n`` or from ``nav_period_s`` (which must be a whole multiple of T).
* **Start.** A run starts at a truth stamp ``t_s`` whose next IMU message ``t_s + T`` has
  arrived (``initialization: truth``), or at the scenario's start (``scenario``).
* **Gaps.** A missing IMU message ends the run (logged with the stamps); a new run starts from
  the truth at the stamp before the next IMU message — nothing is integrated across a gap.
  Out-of-order and repeated messages are logged and dropped.

Parameters and behaviour: docs/nodes.md. Exit status: 0 done (or SIGINT/SIGTERM), 1 failure
while running, 2 invalid parameter or scenario.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, merge_order
from strapdown_ros.messages import EarthState, imu_increments, odometry_state
from strapdown_ros.navigator import (
    INPUT_STREAMS,
    OUTPUT_TOPICS,
    NavigatorRun,
    NavigatorSettings,
    StreamError,
    initial_state_from_scenario,
    initial_state_from_truth,
    parse_navigator,
)
from strapdown_ros.nodes._batched import BatchedInputNode
from strapdown_ros.nodes._common import (
    ParameterError,
    declare_int,
    declare_number,
    declare_scenario,
    declare_string,
    message_class,
    qos_from_parameters,
    run_node,
)
from strapdown_ros.scenario import DEFAULT_TOPICS, Scenario, ScenarioError

NODE_NAME = "navigator_node"
#: Truth messages kept for (re)starting runs.
TRUTH_KEEP = 4096

Log = Callable[[str], None]


def format_stamp(stamp_ns: int) -> str:
    """``sec.nanosec`` of a stamp (ns since the epoch)."""
    return f"{stamp_ns // 1_000_000_000}.{stamp_ns % 1_000_000_000:09d}"


class NavigatorSolver:
    """The streaming navigator (no rclpy): raw payloads in, serialized outputs out.

    Parameters
    ----------
    settings : NavigatorSettings
        Algorithm, mode, N, P, topics, initialization, initial errors.
    output_topics : dict
        Output key (:data:`~strapdown_ros.navigator.OUTPUT_TOPICS`) → topic name.
    scenario_initial : mapping or None
        The scenario's ``initial`` section (``initialization: scenario``).
    start_ns : int or None
        The scenario's start stamp (``initialization: scenario``).
    nav_period_s : float
        If > 0, ``T_nav`` (s): N = T_nav / T must be an integer (checked when T is known).
    end_ns : int or None
        Last IMU stamp of the input stream, if known (the scenario's): :attr:`finished`.
    earth_frame : str
        Odometry frame id.
    """

    def __init__(
        self,
        settings: NavigatorSettings,
        output_topics: dict[str, str],
        scenario_initial: dict[str, Any] | None = None,
        start_ns: int | None = None,
        nav_period_s: float = 0.0,
        end_ns: int | None = None,
        earth_frame: str = "earth",
        info: Log = print,
        warn: Log = print,
        error: Log = print,
    ) -> None:
        self.settings = settings
        self.output_topics = output_topics
        self.scenario_initial = scenario_initial
        self.start_ns = start_ns
        self.nav_period_s = nav_period_s
        self.end_ns = end_ns
        self.earth_frame = earth_frame
        self.info, self.warn, self.error = info, warn, error
        self.period_ns: int | None = None
        self.first_imu: tuple[int, Any] | None = None  # (stamp, fields) before T is known
        self.imu_buffer: list[tuple[int, np.ndarray, np.ndarray]] = []  # waiting for a run
        self.truth: dict[int, EarthState] = {}
        self.run: NavigatorRun | None = None
        self.runs = 0
        self.published_outputs = 0
        self.last_output_ns: int | None = None
        self.failed: str | None = None
        self._flush_pending: list[tuple[str, int, bytes]] = []

    # -- helpers -------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        return self.run is not None or self.runs > 0

    @property
    def finished(self) -> bool:
        """True when the last output the input stream allows has been published."""
        if self.end_ns is None or self.run is None:
            return False
        nav = self.run.nav_period_ns
        last = self.run.start_ns + (self.end_ns - self.run.start_ns) // nav * nav
        return self.last_output_ns is not None and self.last_output_ns >= last

    def _set_period(self, period_ns: int) -> bool:
        if period_ns <= 0:
            return False
        if self.nav_period_s > 0:
            n = self.nav_period_s * 1e9 / period_ns
            if abs(n - round(n)) > 1e-6 or round(n) < 1:
                self.failed = (
                    f"nav_period_s = {self.nav_period_s:g} s is not a whole multiple of the IMU "
                    f"period T = {period_ns} ns detected from the stamps"
                )
                self.error(self.failed)
                return False
            self.settings = dataclasses.replace(self.settings, n=int(round(n)))
        self.period_ns = period_ns
        self.info(
            f"IMU period T = {period_ns} ns ({1e9 / period_ns:g} Hz) from the stamps; "
            f"T_nav = N T = {self.settings.n} x T = {self.settings.n * period_ns * 1e-9:g} s, "
            f"P = {self.settings.p}"
        )
        return True

    # -- input -------------------------------------------------------------------------------

    def on_truth(self, payload: bytes) -> list[tuple[str, int, bytes]]:
        """One raw Odometry payload of the truth topic; returns what to publish."""
        try:
            fields = cdr.deserialize(cdr.ODOMETRY, [payload])
        except cdr.CdrError as exc:
            self.error(f"{self.settings.truth_topic}: rejected a malformed Odometry: {exc}")
            return []
        if not self._earth_frame_ok(fields):
            return []
        self._add_truth(odometry_state(fields))  # type: ignore[arg-type]
        return self._advance()

    def on_imu(self, payload: bytes) -> list[tuple[str, int, bytes]]:
        """One raw Imu payload; returns what to publish."""
        try:
            fields = cdr.deserialize(cdr.IMU, [payload])
        except cdr.CdrError as exc:
            self.error(f"{self.settings.imu_topic}: rejected a malformed Imu: {exc}")
            return []
        return self._on_imu_fields(fields)

    def on_batch(self, items: list[tuple[str, bytes]]) -> list[tuple[str, int, bytes]]:
        """Raw payloads ``(kind, payload)`` (kind 'imu' | 'truth') in arrival order.

        Returns what :meth:`on_imu` / :meth:`on_truth` called one by one return, in the same
        order (the same bytes; tested), at a fraction of the cost: each topic's payloads are
        decoded with one CDR call, and outputs are collected once per batch while the run
        simply continues. A message that could change the run (no run yet, a gap, a repeat)
        takes the one-by-one path, which flushes the run's pending outputs first. A batch
        that does not decode as a whole (a malformed message, mixed frame ids) is taken one by
        one, so every message gets its own verdict.
        """
        imu = self._decode_rows(cdr.IMU, [p for k, p in items if k == "imu"])
        truth = self._decode_rows(cdr.ODOMETRY, [p for k, p in items if k == "truth"])
        states = None  # a wrong frame id: one by one, each message is reported
        if truth is not None and truth[0].frame_id == self.earth_frame:
            states = odometry_state(truth[0])
        out: list[tuple[str, int, bytes]] = []
        i_imu = i_truth = 0
        for kind, payload in items:
            if kind == "truth":
                i, i_truth = i_truth, i_truth + 1
                if states is None:
                    out += self.on_truth(payload)
                    continue
                self._add_truth(EarthState(*(a[i : i + 1] for a in states)))
                continue
            i, i_imu = i_imu, i_imu + 1
            if imu is None:
                out += self.on_imu(payload)
                continue
            fields, stamps = imu
            run = self.run
            if run is None or self.period_ns is None or int(stamps[i]) != run.next_imu_ns:
                out += self._on_imu_fields(fields.rows(i, i + 1))  # type: ignore[attr-defined]
            else:
                self._queue(int(stamps[i]), fields.rows(i, i + 1))  # type: ignore[attr-defined]
        return out + self._advance()

    @staticmethod
    def _decode_rows(msgtype: str, payloads: list[bytes]) -> tuple[Any, np.ndarray] | None:
        """All ``payloads`` decoded at once (fields, stamps), or None if they do not decode."""
        if not payloads:
            return None
        try:
            fields = cdr.deserialize(msgtype, payloads)
        except cdr.CdrError:
            return None
        return fields, np.asarray(fields.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]

    def _earth_frame_ok(self, fields: Any) -> bool:
        if fields.frame_id == self.earth_frame:
            return True
        self.error(
            f"{self.settings.truth_topic}: header.frame_id "
            f"{fields.frame_id!r} is not the Earth frame {self.earth_frame!r}; dropped"
        )
        return False

    def _add_truth(self, state: EarthState) -> None:
        """Keep one truth row (for run starts) and hand it to the current run."""
        stamp = int(state.stamps_ns[0])
        self.truth[stamp] = state
        if len(self.truth) > TRUTH_KEEP:
            for s in sorted(self.truth)[: len(self.truth) - TRUTH_KEEP]:
                del self.truth[s]
        if self.run is not None:
            self.run.add_truth(state)

    def _on_imu_fields(self, fields: Any) -> list[tuple[str, int, bytes]]:
        """One decoded Imu message; returns what to publish."""
        stamp = int(fields.stamps_ns[0])
        if self.period_ns is None:
            if self.failed:
                return []
            if self.first_imu is None or stamp <= self.first_imu[0]:
                self.first_imu = (stamp, fields)
                return []
            if not self._set_period(stamp - self.first_imu[0]):
                return []
            first_stamp, first_fields = self.first_imu
            self._queue(first_stamp, first_fields)
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
                if stamp < expected:
                    self.warn(f"{self.settings.imu_topic}: {exc}; dropped")
                    return
                self.warn(
                    f"{self.settings.imu_topic}: {exc} "
                    f"({(stamp - expected) // self.period_ns} message(s) missing after "
                    f"{format_stamp(expected - self.period_ns)}); the run that started at "
                    f"{format_stamp(self.run.start_ns)} ends at its last complete cycle and a "
                    "new run starts from the truth before the next message"
                )
                self._flush_pending = self._outputs_of(self.run)
                self.run = None
        if self.imu_buffer and stamp <= self.imu_buffer[-1][0]:
            self.warn(
                f"{self.settings.imu_topic}: stamp {format_stamp(stamp)} out of order; dropped"
            )
            return
        if self.imu_buffer and stamp != self.imu_buffer[-1][0] + self.period_ns:
            self.imu_buffer.clear()  # a gap before any run started: restart the search
        self.imu_buffer.append((stamp, da, dv))

    # -- runs --------------------------------------------------------------------------------

    def _try_start(self) -> None:
        if self.run is not None or self.period_ns is None or not self.imu_buffer:
            return
        st, t = self.settings, self.period_ns
        if st.initialization == "scenario":
            assert self.start_ns is not None and self.scenario_initial is not None
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
            initial = initial_state_from_scenario(self.scenario_initial, st)
            self._start(self.start_ns, initial, None)
            return
        for s in sorted(self.truth):
            while self.imu_buffer and self.imu_buffer[0][0] < s + t:
                self.imu_buffer.pop(0)
            if not self.imu_buffer:
                return
            if self.imu_buffer[0][0] == s + t:
                state = self.truth[s]
                self._start(s, initial_state_from_truth(state, 0, st), state.omega_eb_b[0])
                return

    def _start(self, start_ns: int, initial: Any, omega: Any) -> None:
        assert self.period_ns is not None
        st = self.settings
        self.run = NavigatorRun(
            st, start_ns, self.period_ns, initial, bool(st.truth_topic), omega, self.earth_frame
        )
        for s in sorted(self.truth):
            if s >= start_ns:
                self.run.add_truth(self.truth[s])
        buf, self.imu_buffer = self.imu_buffer, []
        if buf:
            self.run.add_imu(
                np.array([b[0] for b in buf], dtype=np.int64),
                np.concatenate([b[1] for b in buf]),
                np.concatenate([b[2] for b in buf]),
            )
        self.runs += 1
        how = "truth" if st.initialization == "truth" else "the scenario's initial state"
        self.info(f"run {self.runs} starts at {format_stamp(start_ns)} (initial state from {how})")

    def _advance(self) -> list[tuple[str, int, bytes]]:
        flushed, self._flush_pending = self._flush_pending, []
        self._try_start()
        if self.run is None:
            return flushed
        return flushed + self._outputs_of(self.run)

    def _outputs_of(self, run: NavigatorRun) -> list[tuple[str, int, bytes]]:
        out = run.outputs()
        if out is None:
            return []
        batches: list[Batch] = [batch(self.output_topics[k], f) for k, f in out.items()]
        self.published_outputs += len(out)
        self.last_output_ns = int(out.odom.stamps_ns[-1])
        return [
            (batches[b].topic, int(batches[b].stamps_ns[i]), batches[b].payloads[i])
            for b, i, _ in merge_order(batches)
        ]


class NavigatorNode(BatchedInputNode):
    """IMU (and truth) in; navigation solution and errors out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario: Scenario | None = declare_scenario(self, False, "its navigator section")
        section: dict[str, Any] = {}
        topics = dict(DEFAULT_TOPICS)
        gravity = "j2"
        if scenario is not None:
            section = dict(scenario.navigator or {})
            topics = dict(scenario.recording.topics)
            gravity = scenario.gravity_model
        # Parameters override the scenario's navigator section (empty/0: keep it).
        for name, default, desc in (
            ("algorithm", "", "multirate | simultaneous"),
            ("mode", "", "paper | exact"),
            ("imu_topic", "", "input Imu topic (default navigator.imu_topic, /variation/imu)"),
            ("truth_topic", "", "truth Odometry topic; '-' for none"),
            ("initialization", "", "truth | scenario"),
        ):
            value = declare_string(self, name, default, desc)
            if value:
                section[name] = "" if value == "-" else value
        for name in ("n", "p"):
            value = declare_int(self, name, 0, f"{name.upper()} (0: the scenario's or 10/2)", 0)
            if value:
                section[name] = value
        nav_period_s = declare_number(
            self, "nav_period_s", 0.0, "T_nav (s), a multiple of the IMU period (overrides n)"
        )
        if nav_period_s < 0:
            raise ParameterError("nav_period_s", f"must be >= 0, got {nav_period_s}")
        try:
            settings = parse_navigator(
                section, topics, gravity,
                None if scenario is None else {"variation": scenario.variation,
                                               "imu_errors": scenario.imu_errors},
            )  # fmt: skip
        except ScenarioError as exc:
            raise ParameterError(exc.key.removeprefix("navigator."), exc.problem) from None
        if settings.initialization == "scenario" and (scenario is None or scenario.initial is None):
            raise ParameterError("initialization", "'scenario' needs a scenario with 'initial'")
        out_topics: dict[str, str] = {}
        for key, rec_key in OUTPUT_TOPICS.items():
            out_topics[key] = declare_string(
                self, f"{key}_topic", topics[rec_key], f"output topic (recording.topics.{rec_key})"
            )
        self.qos = qos_from_parameters(self)
        self.declare_batched_input("the last output")

        end_ns = None
        if scenario is not None:
            end_ns = _input_end_ns(scenario, settings.imu_topic)
        log = self.get_logger()
        self.solver = NavigatorSolver(
            settings,
            out_topics,
            scenario.initial.as_dict() if scenario and scenario.initial else None,
            scenario.start_time_ns if scenario else None,
            nav_period_s,
            end_ns,
            scenario.recording.frames["earth"] if scenario else "earth",
            info=log.info,
            warn=lambda m: log.warning(m),
            error=lambda m: log.error(m, throttle_duration_sec=1.0),
        )
        self.settings = settings
        for key, topic in out_topics.items():
            if key.startswith("error") and not settings.truth_topic:
                continue
            msgtype = {"odom": cdr.ODOMETRY, "fix": cdr.NAVSATFIX}.get(key, cdr.VECTOR3_STAMPED)
            try:
                self.add_output(topic, message_class(msgtype), self.qos)
            except Exception as exc:
                raise ParameterError(f"{key}_topic", str(exc)) from exc
        self._subs: list = []
        log.info(
            f"{settings.algorithm} navigator, mode {settings.mode}, N = "
            f"{'T_nav/T' if nav_period_s else settings.n}, P = {settings.p}; input "
            f"{settings.imu_topic}" + (f" + truth {settings.truth_topic}" if settings.truth_topic
                                       else "") + "; output " + ", ".join(self.output_pubs)
        )  # fmt: skip

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        st = self.settings
        inputs = [(st.imu_topic, cdr.IMU, "imu", "imu_topic")]
        if st.truth_topic:
            inputs.append((st.truth_topic, cdr.ODOMETRY, "truth", "truth_topic"))
        for topic, msgtype, kind, param in inputs:
            try:
                self._subs.append(
                    self.create_subscription(
                        message_class(msgtype), topic, self._buffer(kind), self.qos, raw=True
                    )
                )
            except Exception as exc:
                raise ParameterError(param, str(exc)) from exc
        return " and ".join(topic for topic, *_ in inputs)

    def _failure(self) -> str | None:
        return self.solver.failed

    def _idle_stop(self) -> None:
        # Without a scenario the end of the input is unknown: stopping on idle is the normal end.
        self.get_logger().info(f"no input for {self.run_control.idle_timeout_s:g} s; stopping")

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        s = self.solver
        lines = [
            f"published {s.published_outputs} navigation outputs in {s.runs} run(s) in "
            f"{wall_s:.3f} s of wall time; process CPU {cpu_s:.3f} s"
        ]
        lines += [f"  {t}: {n}" for t, n in self.counts.items()]
        return "\n".join(lines)


def _input_end_ns(scenario: Scenario, imu_topic: str) -> int | None:
    """Last IMU stamp of the scenario's stream on ``imu_topic`` (None if unknown)."""
    from strapdown_ros.reference import build_trajectory, output_cycles

    cycles = output_cycles(scenario, build_trajectory(scenario))
    key = next((k for k, v in scenario.recording.topics.items() if v == imu_topic), None)
    if key not in INPUT_STREAMS:
        return None
    last = cycles if key == "reference_imu" else cycles - 1 - (cycles - 1) % 2
    return scenario.start_time_ns + last * scenario.period_ns


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(NavigatorNode, NODE_NAME, args)
