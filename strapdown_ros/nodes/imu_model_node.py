"""``imu_model_node``: the scenario's IMU error model, live (docs/interface.md §4).

A thin rclpy shell around :class:`~strapdown_ros.stages.imu_errors.ImuErrorsStage`, the
object ``strapdown-sim generate`` feeds: raw ideal Imu payloads in (default ``/variation/imu``),
in batches, serialized measured ones out (default ``/variation/imu_measured``), byte for byte the
bag's. One node runs one model of ``imu_errors`` (parameter ``model``, its index); ``run``
starts one node per model, the first named ``imu_model_node``, model i ``imu_model_node_<i>``.
Gaps, order and restarts: the stage module. Parameters, exit status (0 done, 1 failure, 2 invalid
parameter or scenario): docs/nodes.md.
"""

from __future__ import annotations

from typing import Any

from strapdown_ros.bag import cdr
from strapdown_ros.nodes._batched import StageInputNode
from strapdown_ros.nodes._tf import derived_outputs
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_int,
    declare_scenario,
    declare_string,
)
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.imu_errors import ImuErrorsStage, imu_errors_topics
from strapdown_ros.stages.intake import format_stamp
from strapdown_ros.stages.tf import TFStage

NODE_NAME = "imu_model_node"


class ImuModelNode(StageInputNode):
    """Ideal Imu in; measured Imu out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        self.model = declare_int(self, "model", 0, "which imu_errors model (its index)", 0)
        # ScenarioError if the scenario has no such model
        default_in, default_out = imu_errors_topics(scenario, self.model)
        self.input_topic = declare_string(
            self, "input_topic", default_in, "ideal Imu topic (default imu_errors.input_topic)"
        )
        self.output_topic = declare_string(
            self, "output_topic", default_out, "measured Imu topic (imu_errors.output_topic)"
        )
        for name, topic in (("input_topic", self.input_topic), ("output_topic", self.output_topic)):
            if not topic:
                raise ParameterError(name, "must not be empty")
        if self.input_topic == self.output_topic:
            raise ParameterError("output_topic", f"equals the input topic {self.input_topic}")
        self.declare_batched_input("the last cycle")

        log = self.get_logger()
        self.stream = ImuErrorsStage(
            scenario,
            self.input_topic,
            self.output_topic,
            model=self.model,
            info=log.info,
            warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg),
        )
        # Δv / Δq beside the measured IMU (recording.increments), on the scenario's plan; an
        # output_topic parameter renames the measured stream (the sections reading it follow)
        planned = scenario
        if self.output_topic != default_out:
            names = dict(scenario.recording.topics, variation_imu_measured=self.output_topic)
            planned = scenario.with_recording(topics=names)
        plan = resolve_plan(planned)
        self.last_cycle = plan.last_cycle(self.input_topic)
        self.add_output(self.output_topic, cdr.IMU, "output_topic")
        self.frames = TFStage(plan, variation_tf=False)
        self.derived = derived_outputs(self, plan, [self.output_topic])
        for topic, msgtype in self.derived.items():
            self.add_output(topic, msgtype)
        self._subscription = None
        spec = self.stream.spec
        end = "" if self.last_cycle is None else f" up to cycle {self.last_cycle}"
        log.info(
            f"scenario {scenario.path} ({scenario.name}): IMU errors model {self.model}, "
            f"{'preset ' + spec.preset if spec.preset else 'without preset'}, seed "
            f"{spec.seed}, T = {scenario.period_ns} ns; input {self.input_topic}{end}; "
            f"output {self.output_topic}"
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        self._subscription = self.subscribe_input(self.input_topic, cdr.IMU, None, "input_topic")
        return self.input_topic

    def _process(self, items: list[Any]) -> None:
        out = self.stream.on_payloads([payload for _, payload in items])
        published = [(self.output_topic, 0, data) for data in out]
        if self.derived and published:
            derived = self.frames.derive_items(published)
            published += [item for item in derived if item[0] in self.derived]
        self._publish(published)

    @property
    def finished(self) -> bool:
        """The last cycle of the scenario's input stream has been processed."""
        return self.last_cycle is not None and self.stream.last_cycle >= self.last_cycle

    def _idle_stop(self) -> None:
        timeout = self.run_control.idle_timeout_s
        self.get_logger().warning(
            f"no input for {timeout:g} s; stopping (last cycle "
            f"{self.stream.describe(self.stream.last_cycle)})"
            if self.last_cycle is not None
            else f"no input for {timeout:g} s; stopping"
        )

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        s = self.stream
        last = format_stamp(s.t0_ns + s.last_cycle * s.period_ns) if s.last_cycle else "none"
        return (
            f"published {s.published} measured messages on {self.output_topic} in {s.runs} "
            f"run(s), {wall_s:.3f} s of wall time (process CPU {cpu_s:.3f} s); last stamp {last}"
        )


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(ImuModelNode, NODE_NAME, args)
