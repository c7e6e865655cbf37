"""The run loop shared by the nodes that compute from their input (variation, navigator, IMU model).

:class:`BatchedInputNode` holds what the three nodes do alike: the start-up handshake (wait for
the output subscriptions, then subscribe), input in batches (:class:`~strapdown_ros.nodes.
batching.InputBatch`), the stop conditions (done, ``idle_timeout_s``, a failure, a signal), the
summary and the drain of the publishers. A subclass says what its input, processing and summary
are by overriding the hooks below.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterable
from operator import itemgetter
from typing import Any

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node

from strapdown_ros.nodes.batching import InputBatch, declare_batch_period
from strapdown_ros.nodes.handshake import wait_for_subscriptions
from strapdown_ros.nodes.lifecycle import (
    EXIT_FAILURE,
    EXIT_OK,
    RunControl,
    declare_run_control,
    drain_publishers,
)
from strapdown_ros.nodes.message_types import message_class
from strapdown_ros.nodes.parameters import ParameterError, declare_bool
from strapdown_ros.nodes.qos import qos_from_parameters

__all__ = ["BatchedInputNode", "StageInputNode", "TopicsStageNode"]

#: Seconds to wait for the subscribers' acknowledgements when done, then the grace period.
DRAIN_TIMEOUT_S = 10.0
GRACE_S = 0.5


class BatchedInputNode(Node):
    """A node whose callbacks only buffer raw input that :meth:`run` processes in batches.

    Subclasses call :meth:`declare_batched_input` in ``__init__``, create their publishers
    with :meth:`add_output` (:attr:`output_pubs`: topic → publisher), subscribe with
    :meth:`subscribe_input` (or :meth:`_buffer` callbacks) and
    override :meth:`_subscribe`, :meth:`_idle_stop` and :meth:`_summary` (and :meth:`_failure`
    if the input can make the node give up). By default a batch goes to ``self.solver`` (an
    object with ``on_batch(items) -> [(topic, stamp_ns, payload)]``, ``started`` and
    ``finished``); a node without one overrides :meth:`_process` and :attr:`finished`, and
    :attr:`started` (or is a :class:`StageInputNode`). :meth:`_publish` sends serialized
    outputs and counts them per topic.
    """

    batch: InputBatch
    run_control: RunControl
    #: Batches :meth:`_process` has taken so far.
    batches_processed = 0

    def declare_batched_input(self, done: str) -> None:
        """Declare the QoS (:attr:`qos`), ``batch_period_s`` and the run-control parameters
        (``done``: what "done" means for this node, for the parameter description)."""
        self.qos = qos_from_parameters(self)
        self.batch = InputBatch(declare_batch_period(self))
        self.run_control = declare_run_control(self, done)
        self.output_pubs: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.report_progress = declare_bool(
            self, "report_progress", False,
            "publish the input taken / output published per topic for flow control "
            "(nodes/flow.py)",
        )  # fmt: skip
        self.taken: dict[str, int] = {}  # input topic → messages processed (progress reports)
        self._callback_kinds: dict[int, Any] = {}  # id(callback) → kind

    def add_output(self, topic: str, msgtype: str, param: str | None = None) -> None:
        """Create the publisher of output ``topic`` (``pkg/msg/Name``, QoS :attr:`qos`).

        An invalid topic name raises :class:`ParameterError` naming ``param`` (the parameter
        that set it; None: what ``create_publisher`` raises).
        """
        try:
            self.output_pubs[topic] = self.create_publisher(
                message_class(msgtype), topic, self.qos
            )
        except Exception as exc:
            if param is None:
                raise
            raise ParameterError(param, str(exc)) from exc
        self.counts[topic] = 0

    def subscribe_input(self, topic: str, msgtype: str, kind: Any, param: str) -> Any:
        """Subscribe raw to input ``topic`` with a :meth:`_buffer` callback of ``kind``.

        An invalid topic name raises :class:`ParameterError` naming ``param``.
        """
        try:
            return self.create_subscription(
                message_class(msgtype), topic, self._buffer(kind), self.qos, raw=True
            )
        except Exception as exc:
            raise ParameterError(param, str(exc)) from exc

    def _buffer(self, kind: Any) -> Callable[[bytes], None]:
        """A raw-subscription callback that only buffers ``(kind, payload)`` for the loop."""

        def on_message(payload: bytes) -> None:
            self.batch.add((kind, payload))

        self._callback_kinds[id(on_message)] = kind
        return on_message

    def _input_topics(self) -> dict[Any, str]:
        """kind → input topic of the subscriptions made with :meth:`_buffer` callbacks."""
        return {
            self._callback_kinds[id(s.callback)]: s.topic_name
            for s in self.subscriptions
            if id(s.callback) in self._callback_kinds
        }

    def _publish(self, items: Iterable[tuple[str, int, bytes]]) -> None:
        """Publish serialized outputs ``(topic, stamp_ns, payload)`` in order; count them."""
        pubs, counts = self.output_pubs, self.counts
        for topic, _, data in items:
            pubs[topic].publish(data)
            counts[topic] += 1

    # -- hooks ---------------------------------------------------------------------------------

    def _subscribe(self) -> str:
        """Create the input subscriptions; return what was subscribed (for the log)."""
        raise NotImplementedError

    def _process(self, items: list[Any]) -> None:
        """Process (and publish the outputs of) one batch of buffered input."""
        self._publish(self.solver.on_batch(items))  # type: ignore[attr-defined]

    @property
    def started(self) -> bool:
        """The first input message has been processed."""
        return bool(self.solver.started)  # type: ignore[attr-defined]

    @property
    def finished(self) -> bool:
        """The last output the scenario's input allows has been published."""
        return bool(self.solver.finished)  # type: ignore[attr-defined]

    def _failure(self) -> str | None:
        """Why the node must stop with exit status 1 (None: it need not)."""
        return None

    def _idle_stop(self) -> None:
        """Log that the node stops after ``idle_timeout_s`` without input."""
        self.get_logger().warning(
            f"no input for {self.run_control.idle_timeout_s:g} s; stopping before the end"
        )

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        """The end-of-run summary (wall and process CPU seconds since the first input)."""
        raise NotImplementedError

    @property
    def input_events(self) -> Any:
        """The stage's :class:`~strapdown_ros.stages.intake.InputEvents` (None: none)."""
        return getattr(getattr(self, "solver", None), "events", None)

    def interrupted_summary(self) -> str:
        """The summary when a signal stopped the node (``run_node`` logs it)."""
        if not hasattr(self, "batch"):
            return ""
        t0 = getattr(self, "_run_t0", None)
        wall = time.monotonic() - t0[0] if t0 else 0.0
        cpu = time.process_time() - t0[1] if t0 else 0.0
        return self._full_summary(wall, cpu, interrupted=True)

    def _full_summary(self, wall_s: float, cpu_s: float, interrupted: bool = False) -> str:
        """:meth:`_summary`, the input messages received and the input events by class."""
        lines = [self._summary(wall_s, cpu_s)]
        if interrupted:
            lines.insert(0, "interrupted by a signal before the end of the input")
        events = self.input_events
        lines.append(
            f"received {self.batch.received} input messages; "
            + (events.summary() if events is not None else "input events: not counted")
        )
        return "\n".join(lines)

    # -- the loop ------------------------------------------------------------------------------

    def run(self, executor: Executor) -> int:
        """Process the input until done (or a signal); return the exit status."""

        def spin(timeout_s: float) -> None:
            executor.spin_once(timeout_sec=timeout_s)

        rc = self.run_control
        pubs = list(self.output_pubs.values())
        if rc.wait_for_subscribers > 0 or rc.subscribers_per_topic:
            if not wait_for_subscriptions(
                self, pubs, rc.wait_for_subscribers, rc.wait_timeout_s, spin,
                rc.subscribers_per_topic,
            ):  # fmt: skip
                return EXIT_FAILURE
        self.get_logger().info(f"subscribed to {self._subscribe()}")
        reporter = None
        if self.report_progress:
            from strapdown_ros.nodes.flow import ProgressReporter

            topic_of = self._input_topics()
            self.taken = dict.fromkeys(topic_of.values(), 0)
            reporter = ProgressReporter(self, lambda: (self.taken, self.counts))
            reporter.report()
        batch = self.batch
        batch.last_input = time.monotonic()
        wall_start: float | None = None
        cpu_start = 0.0
        self._run_t0 = (time.monotonic(), time.process_time())
        status = EXIT_OK
        while rclpy.ok(context=self.context):
            # Messages wait at most batch_period_s (or until the input pauses); a node that
            # fell behind takes longer batches (same output), so it catches up by itself.
            batch.spin(spin)
            if batch.due():
                items = batch.take()
                self._process(items)
                self.batches_processed += 1
                if reporter is not None:
                    for kind, n in Counter(map(itemgetter(0), items)).items():
                        self.taken[topic_of[kind]] += n
            if reporter is not None:
                reporter.maybe_report()
            failure = self._failure()
            if failure:
                self.get_logger().error(f"stopping: {failure}")
                status = EXIT_FAILURE
                break
            if wall_start is None and self.started:
                wall_start, cpu_start = time.monotonic(), time.process_time()
            if not rc.exit_when_done or not self.started:
                continue
            if self.finished:
                break
            if time.monotonic() - batch.last_input > rc.idle_timeout_s:
                self._idle_stop()
                break
        wall = time.monotonic() - wall_start if wall_start is not None else 0.0
        cpu = time.process_time() - cpu_start if wall_start is not None else 0.0
        if not rclpy.ok(context=self.context):
            raise ExternalShutdownException()  # run_node logs interrupted_summary()
        if reporter is not None:
            reporter.report()
        if status == EXIT_OK:
            self.get_logger().info(self._full_summary(wall, cpu))
        drain_publishers(self, pubs, spin, DRAIN_TIMEOUT_S, GRACE_S)
        return status


class StageInputNode(BatchedInputNode):
    """A :class:`BatchedInputNode` whose :meth:`_process` feeds a stage ``self.stream`` itself
    (no ``solver``): started once it has processed a batch; its input events the stage's."""

    stream: Any

    @property
    def started(self) -> bool:
        return self.batches_processed > 0

    @property
    def input_events(self) -> Any:
        """The stage's input events (counted in the end-of-run summary)."""
        return self.stream.events


class TopicsStageNode(StageInputNode):
    """A :class:`StageInputNode` whose stage takes serialized batches of several topics
    (``feed_batches``): each buffered message becomes part of its topic's batch, stamped with
    its header stamp plus the topic's log delay (:attr:`log_delays`, default 0), and the
    stage's output batches are published in stamp order. Subclasses set :attr:`input_types`
    (topic → ``pkg/msg/Name``) before :meth:`run` and say :meth:`_rejected` for the summary."""

    input_types: dict[str, str]
    log_delays: dict[str, int] = {}  # noqa: RUF012 - read only; a subclass sets its own

    def _subscribe(self) -> str:
        self._input_subs = [self.subscribe_input(topic, msgtype, topic, "scenario")
                            for topic, msgtype in self.input_types.items()]  # fmt: skip
        return ", ".join(self.input_types)

    def _process(self, items: list[Any]) -> None:
        from strapdown_ros.bag.batches import Batch, merge_order
        from strapdown_ros.nodes.batching import header_stamps

        by_topic: dict[str, list[bytes | memoryview]] = {}
        for topic, payload in items:
            by_topic.setdefault(topic, []).append(payload)
        batches = [
            Batch(topic, self.input_types[topic],
                  header_stamps(payloads) + self.log_delays.get(topic, 0), payloads)
            for topic, payloads in by_topic.items()
        ]  # fmt: skip
        out = self.stream.feed_batches(batches)
        self._publish((out[k].topic, t, out[k].payloads[i]) for k, i, t in merge_order(out))

    def _rejected(self) -> int:
        """Measurements the stage's χ² gate rejected so far."""
        raise NotImplementedError

    def _summary(self, wall_s: float, cpu_s: float) -> str:
        counts = ", ".join(f"{t} {n}" for t, n in self.stream.published.items())
        return (
            f"published {counts} in {wall_s:.3f} s of wall time (process CPU {cpu_s:.3f} s); "
            f"{self._rejected()} measurement(s) rejected by the χ² gate"
        )
