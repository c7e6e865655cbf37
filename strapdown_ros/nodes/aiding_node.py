"""``aiding_node``: GNSS, barometer, magnetometer and wheel odometer, live.

A thin rclpy shell around :class:`~strapdown_ros.stages.aiding.AidingStage`, the object
``strapdown-sim generate`` feeds: raw truth Odometry payloads in (default
``/reference/odom``), in batches, serialized aiding messages out (``/gnss/fix``, ``/gnss/vel``,
``/baro/pressure``, ``/mag``, ``/wheel/twist`` for the enabled sensors), byte for byte the
bag's. A GNSS message with a latency is published with the first truth message at or after
``stamp + latency_s``. Models: docs/aiding.md; exit status (0 done, 1 failure, 2 invalid
parameter or scenario): docs/nodes.md.
"""

from __future__ import annotations

from typing import Any

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import merge_order
from strapdown_ros.config import ScenarioError
from strapdown_ros.nodes._batched import StageInputNode
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import ParameterError, declare_scenario, declare_string
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.aiding import AIDING_MSGTYPES, AidingStage, aiding_spec

NODE_NAME = "aiding_node"


class AidingNode(StageInputNode):
    """Truth Odometry in; aiding measurements out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        spec = aiding_spec(scenario)
        if spec is None or not spec.sensors():
            raise ScenarioError("aiding", "missing: the scenario enables no aiding sensor")
        self.truth_topic = declare_string(
            self,
            "truth_topic",
            scenario.recording.topics["reference_odom"],
            "truth Odometry topic (default recording.topics.reference_odom)",
        )
        if not self.truth_topic:
            raise ParameterError("truth_topic", "must not be empty")
        self.declare_batched_input("the last truth message")
        log = self.get_logger()
        self.stream = AidingStage(
            scenario, spec, truth_topic=self.truth_topic, warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg),
        )  # fmt: skip
        for topic in self.stream.topics:
            self.add_output(topic, AIDING_MSGTYPES[topic])
        plan = resolve_plan(scenario)
        self.last_truth_ns = plan.last_stamp(scenario.recording.topics["reference_odom"])
        self._subscription = None
        log.info(
            f"scenario {scenario.path} ({scenario.name}): aiding sensors "
            f"{', '.join(spec.sensors())}; input {self.truth_topic}; outputs "
            f"{', '.join(self.stream.topics)}"
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    def _subscribe(self) -> str:
        self._subscription = self.subscribe_input(
            self.truth_topic, cdr.ODOMETRY, None, "truth_topic"
        )
        return self.truth_topic

    def _process(self, items: list[Any]) -> None:
        batches = self.stream.on_payloads([payload for _, payload in items])
        self._publish(
            (batches[k].topic, t, batches[k].payloads[i]) for k, i, t in merge_order(batches)
        )

    @property
    def finished(self) -> bool:
        """The scenario's last truth message has been processed."""
        last = self.stream.last_truth_ns
        return last is not None and last >= self.last_truth_ns

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        counts = ", ".join(f"{t} {n}" for t, n in self.stream.published.items())
        return (
            f"published {counts} in {wall_s:.3f} s of wall time (process CPU {cpu_s:.3f} s)"
        )


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(AidingNode, NODE_NAME, args)
