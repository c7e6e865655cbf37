"""``imu_model_node``: the scenario's IMU error model, live (SPEC §4, issue 7).

It subscribes raw to an ideal Imu topic (default ``/variation/imu``), decodes every payload
with the project's CDR codec, feeds it to a :class:`~strapdown_ros.imu_model.MeasuredImuStream`
— the object ``strapdown-sim generate`` feeds with the same messages — and publishes the
serialized result raw on the measured topic (default ``/variation/imu_measured``). The model
is applied message by message with its state carried (random generator, bias processes,
quantization residual); applied in chunks it is bit-identical to the whole-stream application,
so the published messages equal the bag's byte for byte.

* **Gaps.** A missing cycle is logged (WARN, with the stamps) and the model is advanced over
  it: later cycles keep the noise and bias processes of an uninterrupted run, but the
  quantizer lacks the missing increments, so the quantized values may differ from the bag's by
  one quantum from then on (two on the first message after the gap). An input starting after
  cycle 1 is handled the same way.
* **Order.** An older stamp (out of order or duplicate) is logged and dropped; cycle 1 after
  later cycles means the input restarted, and the model restarts from its seed. A stamp off
  the scenario's cycle grid is rejected (ERROR).

Behaviour: docs/theory/imu_errors.md; the scenario section: docs/scenarios.md. Parameters:
``scenario`` (required), ``overrides``, ``duration_s``, ``input_topic`` / ``output_topic``
(default: the section's, else ``recording.topics``), ``qos_reliability``, ``qos_depth``,
``exit_when_done`` (after the last cycle of the scenario's input stream), ``idle_timeout_s``,
``wait_for_subscribers``, ``wait_timeout_s``, ``subscribers_per_topic``. Exit status: 0 done
(or SIGINT/SIGTERM), 1 failure while running, 2 invalid parameter or scenario.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node

from strapdown_ros.bag import cdr
from strapdown_ros.imu_model import MeasuredImuStream, format_stamp, imu_model_topics
from strapdown_ros.nodes._common import (
    EXIT_FAILURE,
    EXIT_OK,
    InputBatch,
    ParameterError,
    declare_batch_period,
    declare_number,
    declare_run_control,
    declare_string,
    declare_string_array,
    drain_publishers,
    message_class,
    qos_from_parameters,
    run_node,
    wait_for_subscriptions,
)
from strapdown_ros.scenario import Scenario, load_scenario

NODE_NAME = "imu_model_node"
#: Seconds to wait for the subscribers' acknowledgements when done, then the grace period.
DRAIN_TIMEOUT_S = 10.0
GRACE_S = 0.5


def last_input_cycle(scenario: Scenario, input_topic: str) -> int | None:
    """Last cycle the scenario publishes on ``input_topic`` (None: not one of its IMU topics).

    The reference IMU ends at cycle M, the variation streams at the last even cycle < M.
    """
    from strapdown_ros.reference import build_trajectory, output_cycles

    key = next((k for k, v in scenario.recording.topics.items() if v == input_topic), None)
    if key not in ("reference_imu", "variation_imu", "variation_reference_imu"):
        return None
    cycles = output_cycles(scenario, build_trajectory(scenario))
    return cycles if key == "reference_imu" else cycles - 1 - (cycles - 1) % 2


class ImuModelNode(Node):
    """Ideal Imu in; measured Imu out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        path = declare_string(self, "scenario", "", "scenario YAML file (required)")
        overrides = declare_string_array(self, "overrides", "scenario overrides dotted.key=value")
        duration_s = declare_number(self, "duration_s", 0.0, "duration (s); 0 = the scenario's")
        if not path:
            raise ParameterError("scenario", "is required (the path of a scenario YAML file)")
        if duration_s < 0:
            raise ParameterError("duration_s", f"must be >= 0, got {duration_s}")
        scenario = load_scenario(path, overrides, duration_s if duration_s > 0 else None)
        default_in, default_out = imu_model_topics(scenario)  # ScenarioError if no imu_errors
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
        self.qos = qos_from_parameters(self)
        self.batch = InputBatch(declare_batch_period(self))
        run_control = declare_run_control(self, "the last cycle")
        self.exit_when_done = run_control.exit_when_done
        self.idle_timeout_s = run_control.idle_timeout_s
        self.wait_for_subscribers = run_control.wait_for_subscribers
        self.wait_timeout_s = run_control.wait_timeout_s
        self.subscribers_per_topic = run_control.subscribers_per_topic

        log = self.get_logger()
        self.stream = MeasuredImuStream(
            scenario,
            self.input_topic,
            self.output_topic,
            info=log.info,
            warn=lambda msg: log.warning(msg),
            error=lambda msg: log.error(msg, throttle_duration_sec=1.0),
        )
        self.last_cycle = last_input_cycle(scenario, self.input_topic)
        try:
            self.publisher = self.create_publisher(
                message_class(cdr.IMU), self.output_topic, self.qos
            )
        except Exception as exc:  # invalid topic name
            raise ParameterError("output_topic", str(exc)) from exc
        self._subscription = None
        self.started = False
        params = self.stream.params
        end = "" if self.last_cycle is None else f" up to cycle {self.last_cycle}"
        log.info(
            f"scenario {scenario.path} ({scenario.name}): IMU errors "
            f"{'preset ' + params.preset if params.preset else 'without preset'}, seed "
            f"{params.seed}, T = {scenario.period_ns} ns; input {self.input_topic}{end}; "
            f"output {self.output_topic}"
        )

    def _subscribe(self) -> None:
        try:
            self._subscription = self.create_subscription(
                message_class(cdr.IMU), self.input_topic, self._on_message, self.qos, raw=True
            )
        except Exception as exc:
            raise ParameterError("input_topic", str(exc)) from exc

    def _on_message(self, payload: bytes) -> None:
        self.started = True
        self.batch.add(payload)  # processed in run(), batch by batch

    def _process(self) -> None:
        for data in self.stream.on_payloads(self.batch.take()):
            self.publisher.publish(data)

    @property
    def finished(self) -> bool:
        """The last cycle of the scenario's input stream has been processed."""
        return self.last_cycle is not None and self.stream.last_cycle >= self.last_cycle

    def run(self, executor: Executor) -> int:
        """Process the input until done (or a signal); return the exit status."""

        def spin(timeout_s: float) -> None:
            executor.spin_once(timeout_sec=timeout_s)

        if self.wait_for_subscribers > 0 or self.subscribers_per_topic:
            self.get_logger().info(
                f"waiting for {self.wait_for_subscribers} subscription(s) on {self.output_topic}"
            )
            if not wait_for_subscriptions(
                self,
                [self.publisher],
                self.wait_for_subscribers,
                self.wait_timeout_s,
                spin,
                self.subscribers_per_topic,
            ):
                return EXIT_FAILURE
        self._subscribe()
        self.get_logger().info(f"subscribed to {self.input_topic}")
        wall_start: float | None = None
        batch = self.batch
        batch.last_input = time.monotonic()
        while rclpy.ok(context=self.context):
            batch.spin(spin)
            if batch.due():
                self._process()
            if wall_start is None and self.started:
                wall_start = time.monotonic()
            if not self.exit_when_done or not self.started:
                continue
            if self.finished:
                break
            if time.monotonic() - batch.last_input > self.idle_timeout_s:
                self.get_logger().warning(
                    f"no input for {self.idle_timeout_s:g} s; stopping (last cycle "
                    f"{self.stream.describe(self.stream.last_cycle)})"
                    if self.last_cycle is not None
                    else f"no input for {self.idle_timeout_s:g} s; stopping"
                )
                break
        if not rclpy.ok(context=self.context):
            raise ExternalShutdownException()
        s = self.stream
        elapsed = time.monotonic() - (wall_start or time.monotonic())
        last = format_stamp(s.t0_ns + s.last_cycle * s.period_ns) if s.last_cycle else "none"
        self.get_logger().info(
            f"published {s.published} measured messages on {self.output_topic} in {s.runs} "
            f"run(s), {elapsed:.3f} s of wall time; last stamp {last}"
        )
        self._drain(spin)
        return EXIT_OK

    def _drain(self, spin: Callable[[float], None]) -> None:
        """Let the subscribers receive everything: acknowledgements, then a grace period."""
        drain_publishers(self, [self.publisher], spin, DRAIN_TIMEOUT_S, GRACE_S)


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(ImuModelNode, NODE_NAME, args)
