"""``navigator_node``: the multirate b–l split navigator, live (SPEC §4, issue 5).

It subscribes raw to an IMU topic (default ``/variation/imu``) and, optionally, a truth
Odometry topic (default ``/variation/odom``), decodes every payload with the project's CDR
codec, and feeds a :class:`~strapdown_ros.stages.navigation.NavigatorRun` — the very object
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

from typing import Any

from strapdown_ros.bag import cdr
from strapdown_ros.config import DEFAULT_TOPICS, Scenario, ScenarioError
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
from strapdown_ros.stages.navigation import (
    INPUT_STREAMS,
    OUTPUT_TOPICS,
    NavigatorSolver,
    parse_navigator,
)

NODE_NAME = "navigator_node"







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
    from strapdown_ros.stages.reference import build_trajectory, output_cycles

    cycles = output_cycles(scenario, build_trajectory(scenario))
    key = next((k for k, v in scenario.recording.topics.items() if v == imu_topic), None)
    if key not in INPUT_STREAMS:
        return None
    last = cycles if key == "reference_imu" else cycles - 1 - (cycles - 1) % 2
    return scenario.start_time_ns + last * scenario.period_ns


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(NavigatorNode, NODE_NAME, args)
