"""``aided_node``: the reference aided INS (error-state Kalman filter), live.

A thin rclpy shell around :class:`~strapdown_ros.stages.aided.AidedStage`, the object
``strapdown-sim generate`` feeds: raw payloads of the measured IMU (default
``/reference/imu_measured``), the truth Odometry (``/reference/odom``) and the aiding topics
the filter uses (``/gnss/fix``, ``/gnss/vel``, ``/baro/pressure``, ``/mag``, ``/wheel/twist``)
in, in batches; serialized ``/aided/*`` messages out, byte for byte the bag's. The stage is
handed each input message with its bag log time (the header stamp plus the topic's log delay,
e.g. a GNSS latency, from the plan), so it waits for exactly the inputs it waits for in
``generate`` and its output does not depend on how DDS interleaves the topics. A message
that is malformed, non-finite, off its sensor's epochs, repeated, out of order or late is
dropped by the stage and logged. Filter: docs/aided.md; exit status (0 done, 1 failure, 2
invalid parameter or scenario): docs/nodes.md.
"""

from __future__ import annotations

from strapdown_ros.nodes._batched import TopicsStageNode
from strapdown_ros.nodes.lifecycle import run_node
from strapdown_ros.nodes.parameters import declare_scenario
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.aided import AidedStage, aided_input_topics, aided_topic_types
from strapdown_ros.stages.intake import format_stamp

NODE_NAME = "aided_node"


class AidedNode(TopicsStageNode):
    """Measured IMU, truth and aiding measurements in; the aided solution out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        log = self.get_logger()
        # ScenarioError (exit 2) when the scenario has no enabled aided section
        self.stream = AidedStage(
            scenario, info=log.info, warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg),
        )  # fmt: skip
        self.declare_batched_input("the last IMU cycle")
        plan = resolve_plan(scenario)
        self.input_types = {t: plan.topics[t].msgtype for t in aided_input_topics(scenario)}
        #: input topic → bag log time minus header stamp (ns): a GNSS latency
        self.log_delays = {t: plan.log_delays().get(t, 0) for t in self.input_types}
        self.last_imu_ns = plan.last_stamp(self.stream.imu_topic)
        types = aided_topic_types(scenario)
        for topic in self.stream.topics.values():
            self.add_output(topic, types[topic])
        log.info(
            f"scenario {scenario.path} ({scenario.name}): aided INS on "
            f"{', '.join(self.stream.sensors)}; inputs {', '.join(self.input_types)}; "
            f"{len(self.stream.topics)} outputs under {self.stream.spec.topic_prefix}"
        )

    # -- BatchedInputNode hooks -----------------------------------------------------------------

    @property
    def finished(self) -> bool:
        """The scenario's last IMU cycle has been processed (or an IMU gap ended the filter)."""
        done = self.stream.done_until
        if self.stream.stopped:
            return True
        return done is not None and self.last_imu_ns is not None and done >= self.last_imu_ns

    def _idle_stop(self) -> None:
        done = self.stream.done_until
        self.get_logger().warning(
            f"no input for {self.run_control.idle_timeout_s:g} s; stopping (processed up to "
            + ("nothing" if done is None else format_stamp(done)) + ")"
        )

    def _rejected(self) -> int:
        return len(self.stream.rejections)


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(AidedNode, NODE_NAME, args)
