"""``transfer_node``: transfer alignment of the variation (slave) IMU's INS, live.

A thin rclpy shell around :class:`~strapdown_ros.stages.transfer.TransferStage`, the object
``strapdown-sim generate`` feeds: raw payloads of the slave IMU (``transfer_alignment.imu_topic``,
default ``/variation/imu_measured``), the master Odometry (``/reference/odom``) and the slave
truth (``/variation/odom``) in, in batches; serialized ``/transfer/*`` messages out, byte for
byte the bag's. The stage processes an epoch once every input it needs has arrived, so its
output does not depend on how DDS interleaves the topics; a missing slave IMU cycle or a
non-finite input stops the node with an error line and exit status 1, the outputs published
before it standing. Filter and outputs: docs/transfer_alignment.md; exit status (0 done,
1 failure, 2 invalid parameter or scenario): docs/nodes.md.
"""

from __future__ import annotations

from typing import Any

from strapdown_ros.nodes._batched import TopicsStageNode
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import declare_scenario
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.transfer import TransferStage, transfer_input_topics

NODE_NAME = "transfer_node"


class TransferNode(TopicsStageNode):
    """Slave IMU, master state and slave truth in; the slave solution and mounting out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        log = self.get_logger()
        plan = resolve_plan(scenario)
        # ScenarioError (exit 2) when the scenario has no enabled transfer_alignment section
        self.stream = TransferStage(scenario, plan.variation_cycles, info=log.info)
        self.declare_batched_input("the last transfer epoch")
        self.input_types = {t: plan.topics[t].msgtype for t in transfer_input_topics(scenario)}
        for topic in self.stream.topics.values():
            self.add_output(topic, plan.topics[topic].msgtype)
        log.info(
            f"scenario {scenario.path} ({scenario.name}): transfer alignment every "
            f"{self.stream.P} cycles ({self.stream.count} epochs); inputs "
            f"{', '.join(self.input_types)}; {len(self.stream.topics)} outputs under "
            f"{self.stream.spec.topic_prefix}"
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    @property
    def input_events(self) -> Any:
        """None: the stage trusts its inputs (they come from the chain) and counts no events."""
        return None

    @property
    def finished(self) -> bool:
        """Every epoch of the scenario has been published."""
        return self.stream.k >= self.stream.count

    def _idle_stop(self) -> None:
        s = self.stream
        self.get_logger().warning(
            f"no input for {self.run_control.idle_timeout_s:g} s; stopping after {s.k} of "
            f"{s.count} epochs (slave IMU up to cycle {s._imu_last}, master up to cycle "
            f"{s._master_last})"
        )

    def _rejected(self) -> int:
        return self.stream.rejections


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(TransferNode, NODE_NAME, args)
