"""``navigator_node``: the navigation stage, live (docs/interface.md §4).

A thin rclpy shell around :class:`~strapdown_ros.stages.navigator.NavigatorStage` — the very
object ``strapdown-sim generate`` feeds, so ``/navigator/*`` are published with the bag's
bytes. It subscribes raw to an IMU topic and, optionally, a truth Odometry topic, hands the
payloads over in batches and publishes what the stage returns. Settings: the scenario's
``navigator`` section (if any) with the node's parameters overriding it, validated as one
:class:`~strapdown_ros.config.navigator.NavigatorSpec`. Parameters and behaviour (rate, start,
gaps): docs/nodes.md. Exit status: 0 done (or SIGINT/SIGTERM), 1 failure while running, 2
invalid parameter or scenario.
"""

from __future__ import annotations

from typing import Any

from strapdown_ros.bag import cdr
from strapdown_ros.config import DEFAULT_TOPICS, Scenario, ScenarioError
from strapdown_ros.config.base import validate_section
from strapdown_ros.config.navigator import OUTPUT_TOPICS, NavigatorSpec, resolve_navigator
from strapdown_ros.nodes._batched import BatchedInputNode
from strapdown_ros.nodes._tf import derived_outputs
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_int,
    declare_number,
    declare_scenario,
    declare_string,
)
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.navigator import NavigatorStage
from strapdown_ros.stages.tf import SolverWithTF, TFStage

NODE_NAME = "navigator_node"

#: String parameters overriding the scenario's section ("": keep it) and their descriptions.
STRING_PARAMETERS = {
    "algorithm": "multirate | simultaneous",
    "mode": "paper | exact",
    "imu_topic": "input Imu topic (default navigator.imu_topic, /variation/imu)",
    "truth_topic": "truth Odometry topic; '-' for none",
    "initialization": "truth | scenario",
}


def navigator_section(scenario: Scenario | None, overrides: dict[str, Any]) -> NavigatorSpec:
    """The node's navigator settings: the scenario's section (or the defaults) with the
    parameter values ``overrides`` (section key → value), validated and resolved.

    Raises
    ------
    ParameterError
        Naming the parameter (or the section key) at fault.
    """
    section: dict[str, Any] = {}
    if scenario is not None and scenario.navigator is not None:
        section = scenario.navigator.model_dump(exclude_unset=True)
    section.update(overrides)
    topics = scenario.recording.topics if scenario is not None else DEFAULT_TOPICS
    gravity = scenario.gravity_model if scenario is not None else "j2"
    try:
        spec = validate_section(NavigatorSpec, section, "navigator")
        sections = None if scenario is None else scenario.sections()
        measured = () if scenario is None else scenario.measured_imu_topics()
        spec = resolve_navigator(spec, topics, gravity, sections, measured)
    except ScenarioError as exc:
        key = exc.key.removeprefix("navigator.")
        root = key.split(".")[0].split("[")[0]
        raise ParameterError(root if root in overrides else key, exc.problem) from None
    if spec.initialization == "scenario" and (scenario is None or scenario.initial is None):
        raise ParameterError("initialization", "'scenario' needs a scenario with 'initial'")
    return spec


class NavigatorNode(BatchedInputNode):
    """IMU (and truth) in; navigation solution and errors out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario: Scenario | None = declare_scenario(self, False, "its navigator section")
        overrides: dict[str, Any] = {}
        for name, desc in STRING_PARAMETERS.items():
            value = declare_string(self, name, "", desc)
            if value:
                overrides[name] = "" if value == "-" else value
        for name in ("n", "p"):
            value = declare_int(self, name, 0, f"{name.upper()} (0: the scenario's or 10/2)", 0)
            if value:
                overrides[name] = value
        nav_period_s = declare_number(
            self, "nav_period_s", 0.0, "T_nav (s), a multiple of the IMU period (overrides n)"
        )
        if nav_period_s < 0:
            raise ParameterError("nav_period_s", f"must be >= 0, got {nav_period_s}")
        spec = navigator_section(scenario, overrides)
        topics = scenario.recording.topics if scenario is not None else DEFAULT_TOPICS
        out_topics = {
            key: declare_string(
                self, f"{key}_topic", topics[rec_key], f"output topic (recording.topics.{rec_key})"
            )
            for key, rec_key in OUTPUT_TOPICS.items()
        }
        self.declare_batched_input("the last output")

        plan = None
        if scenario is not None:  # the scenario with the node's output names
            names = dict(scenario.recording.topics, navigator_odom=out_topics["odom"])
            plan = resolve_plan(scenario.with_recording(topics=names))
        log = self.get_logger()
        self.solver = NavigatorStage(
            spec,
            out_topics,
            initial=scenario.initial if scenario is not None else None,
            start_ns=scenario.start_time_ns if scenario is not None else None,
            nav_period_s=nav_period_s,
            end_ns=plan.last_stamp(spec.imu_topic) if plan is not None else None,
            earth_frame=scenario.recording.frames["earth"] if scenario is not None else "earth",
            info=log.info,
            warn=lambda m: log.warning(m),
            error=lambda m: log.error(m),
        )
        self.spec = spec
        for key, topic in out_topics.items():
            if key.startswith("error") and not spec.truth_topic:
                continue
            msgtype = {"odom": cdr.ODOMETRY, "fix": cdr.NAVSATFIX}.get(key, cdr.VECTOR3_STAMPED)
            self.add_output(topic, msgtype, f"{key}_topic")
        if plan is not None:  # map -> navigator and the map-frame odometry
            frames = TFStage(plan, variation_tf=False)
            derived = derived_outputs(self, plan, [out_topics["odom"]])
            for topic, msgtype in derived.items():
                self.add_output(topic, msgtype)
            self.solver = SolverWithTF(self.solver, frames, derived)
        self._subs: list = []
        log.info(
            f"{spec.algorithm} navigator, mode {spec.mode}, N = "
            f"{'T_nav/T' if nav_period_s else spec.n}, P = {spec.p}; input {spec.imu_topic}"
            + (f" + truth {spec.truth_topic}" if spec.truth_topic else "")
            + "; output " + ", ".join(self.output_pubs)
        )  # fmt: skip

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        spec = self.spec
        inputs = [(spec.imu_topic, cdr.IMU, "imu", "imu_topic")]
        if spec.truth_topic:
            inputs.append((spec.truth_topic, cdr.ODOMETRY, "truth", "truth_topic"))
        for topic, msgtype, kind, param in inputs:
            self._subs.append(self.subscribe_input(topic, msgtype, kind, param))
        return " and ".join(str(topic) for topic, *_ in inputs)

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


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(NavigatorNode, NODE_NAME, args)
