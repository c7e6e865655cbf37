"""``trajectory_node``: publishes a scenario's reference stream live (docs/interface.md §4, §6).

It publishes exactly the messages ``strapdown-sim generate`` writes for the reference stream,
in the same order: the very CDR payloads of
:func:`strapdown_ros.stages.trajectory.reference_batch_chunks` (pieces of
:func:`~strapdown_ros.stages.trajectory.reference_batches`), in
:func:`~strapdown_ros.bag.batches.merge_order`, published raw. The message with stamp ``t`` is
published at wall time ``start + (t - t0) / rate_factor``. Parameters and behaviour:
docs/nodes.md.

Exit status: 0 done (or stopped by SIGINT/SIGTERM), 1 failure while running (e.g. no
subscriber within ``wait_timeout_s``), 2 invalid parameter or scenario.
"""

from __future__ import annotations

import array
import queue
import threading
import time
from collections.abc import Callable, Iterator

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node

from strapdown_ros.bag.batches import Batch, merge_order
from strapdown_ros.bag.cdr import TF_MESSAGE
from strapdown_ros.bag.playback import pacing_stats
from strapdown_ros.core.stream import Stream
from strapdown_ros.nodes._tf import derived_outputs, static_qos
from strapdown_ros.nodes.flow import DEFAULT_WINDOW, FlowGate
from strapdown_ros.nodes.handshake import declare_subscriber_counts, wait_for_subscriptions
from strapdown_ros.nodes.lifecycle import EXIT_FAILURE, EXIT_OK, drain_publishers, run_node
from strapdown_ros.nodes.message_types import message_class
from strapdown_ros.nodes.pacing import Pacer
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_bool,
    declare_int,
    declare_number,
    declare_scenario,
    declare_string,
    declare_string_array,
)
from strapdown_ros.nodes.qos import qos_from_parameters
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.tf import TFStage
from strapdown_ros.stages.trajectory import reference_batch_chunks

NODE_NAME = "trajectory_node"
TIME_SOURCES = ("sim", "wall")
#: Topic parameters and the scenario's recording.topics key each defaults to.
TOPIC_PARAMETERS = {
    "imu_topic": "reference_imu",
    "odom_topic": "reference_odom",
    "fix_topic": "reference_fix",
    "clock_topic": "clock",
}
MSGTYPES = {
    "clock": "rosgraph_msgs/msg/Clock",
    "reference_odom": "nav_msgs/msg/Odometry",
    "reference_fix": "sensor_msgs/msg/NavSatFix",
    "reference_imu": "sensor_msgs/msg/Imu",
}
#: Seconds to wait for the subscribers' acknowledgements when done, then the grace period.
DRAIN_TIMEOUT_S = 10.0
GRACE_S = 0.5
#: Longest time without servicing rclpy (parameter services, ...) while publishing.
SPIN_EVERY_S = 0.05
#: The same under flow control: the consumers' reports are taken at least this often.
FLOW_SPIN_EVERY_S = 0.005
#: Paced runs: say so while publishing when a message goes out this late, at most every
#: LATE_EVERY_S (``strapdown-sim run`` relays the line).
LATE_WARNING_S = 0.5
LATE_EVERY_S = 2.0


class _Pieces:
    """Computes the reference pieces in a background thread, at most ``depth`` ahead."""

    _END = object()

    def __init__(self, items: Iterator[tuple[Stream, list[Batch]]], depth: int = 2) -> None:
        self._items = items
        self._queue: queue.Queue[object] = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="trajectory-pieces", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for item in self._items:
                while not self._stop.is_set():
                    try:
                        self._queue.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if self._stop.is_set():
                    return
            self._queue.put(self._END)
        except BaseException as exc:  # re-raised by get()
            self._queue.put(exc)

    def get(self, spin: Callable[[float], None]) -> tuple[Stream, list[Batch]] | None:
        """Next piece (``None`` at the end), spinning rclpy while it is being computed."""
        while True:
            try:
                item = self._queue.get(timeout=0.01)
                break
            except queue.Empty:
                spin(0.0)
        if item is self._END:
            return None
        if isinstance(item, BaseException):
            raise item
        return item  # type: ignore[return-value]

    def cancel(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)


class TrajectoryNode(Node):
    """Publishes the reference Imu / Odometry / NavSatFix (and /clock) of a scenario."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario = declare_scenario(self)
        self.time_source = declare_string(self, "time_source", "sim", "sim | wall")
        self.rate_factor = declare_number(
            self, "rate_factor", 1.0, "speed-up over real time; <= 0: as fast as possible"
        )
        self.publish_period_s = declare_number(
            self, "publish_period_s", 0.0,
            "publish in groups of this much data time (s): each message waits for its group's "
            "end, never early, at most this late; 0: every message at its own time",
        )  # fmt: skip
        if not 0 <= self.publish_period_s <= 1:
            raise ParameterError(
                "publish_period_s", f"must be >= 0 and <= 1, got {self.publish_period_s}"
            )
        if self.time_source not in TIME_SOURCES:
            raise ParameterError(
                "time_source",
                f"must be one of: {', '.join(TIME_SOURCES)}; got {self.time_source!r}",
            )

        topics = dict(scenario.recording.topics)
        for name, key in TOPIC_PARAMETERS.items():
            topic = declare_string(
                self, name, topics[key], f"topic (default recording.topics.{key})"
            )
            if not topic:
                raise ParameterError(name, "must not be empty")
            topics[key] = topic
        self.qos = qos_from_parameters(self)
        self.wait_for_subscribers = declare_int(
            self, "wait_for_subscribers", 0, "subscriptions to wait for before publishing", 0
        )
        self.subscribers_per_topic = declare_subscriber_counts(self)
        self.wait_for_all_topics = declare_bool(
            self, "wait_for_all_topics", True, "wait on every published topic, not only the IMU"
        )
        self.wait_timeout_s = declare_number(self, "wait_timeout_s", 10.0, "seconds to wait")
        self.exit_when_done = declare_bool(self, "exit_when_done", True, "exit after the last")
        self.flow_nodes = declare_string_array(
            self, "flow_nodes", "flow control: nodes whose progress reports pace the publishing"
        )
        self.flow_window = declare_int(
            self, "flow_window", DEFAULT_WINDOW, "flow control: messages a consumer may lag", 1
        )

        # The /clock batch exists exactly in 'sim' mode, whatever recording.clock says.
        self.scenario = scenario.with_recording(topics=topics, clock=self.time_source == "sim")
        self.plan = resolve_plan(self.scenario)
        self.plan.trajectory  # noqa: B018 - built now: validates the trajectory's parameters
        self.cycles = self.plan.cycles
        self.imu_topic = topics["reference_imu"]
        data_topics = [topics[k] for k in ("reference_odom", "reference_fix", "reference_imu")]
        all_topics = ([topics["clock"]] if self.scenario.recording.clock else []) + data_topics
        for topic in all_topics:
            if all_topics.count(topic) > 1:
                raise ParameterError(
                    _parameter_of(topic, topics), f"topic {topic} is used twice: {all_topics}"
                )

        self._msgtypes = self._topic_types()
        # TF (/tf_static, map -> base_link) and map-frame odometry of the reference
        self.frames = TFStage(self.plan, variation_tf=False)
        self._derived = derived_outputs(self, self.plan, list(self._msgtypes), static=True)
        self._static_topic = self._derived.pop(self.frames.tf_static_topic, None) and (
            self.frames.tf_static_topic
        )
        self._msgtypes.update(self._derived)
        self._publishers_by_topic = {}
        self.counts: dict[str, int] = {}
        self.errors = array.array("d")  # publish time - due time of each paced message (s)
        for topic, msgtype in self._msgtypes.items():
            try:
                self._publishers_by_topic[topic] = self.create_publisher(
                    message_class(msgtype), topic, self.qos
                )
            except Exception as exc:  # invalid topic name
                raise ParameterError(_parameter_of(topic, topics), str(exc)) from exc
            self.counts[topic] = 0
        if self._static_topic:  # latched, like tf2_ros' static broadcaster
            self._publishers_by_topic[self._static_topic] = self.create_publisher(
                message_class(TF_MESSAGE), self._static_topic, static_qos(self.qos)
            )
            self.counts[self._static_topic] = 0
        self._wait_topics = all_topics if self.wait_for_all_topics else [self.imu_topic]
        self.gate: FlowGate | None = None
        if self.flow_nodes:
            self.gate = FlowGate(self, self._msgtypes, self.flow_nodes, self.flow_window)

        self.get_logger().info(
            f"scenario {scenario.path} ({scenario.name}): {self.cycles} cycles at "
            f"{scenario.rate_hz:g} Hz, {self.cycles / scenario.rate_hz:g} s; time_source "
            f"{self.time_source}, rate_factor {self.rate_factor:g}"
            + (
                f", flow control on {', '.join(self.flow_nodes)} (window {self.flow_window})"
                if self.gate is not None
                else ""
            )
            + "; topics "
            + ", ".join(p.topic_name for p in self._publishers_by_topic.values())
        )

    def _topic_types(self) -> dict[str, str]:
        """Topic -> message type of what :func:`reference_batches` produces, in batch order."""
        topics = self.scenario.recording.topics
        out = {topics["clock"]: MSGTYPES["clock"]} if self.scenario.recording.clock else {}
        for key in ("reference_odom", "reference_fix", "reference_imu"):
            out[topics[key]] = MSGTYPES[key]
        return out

    # -----------------------------------------------------------------------------------------

    def run(self, executor: Executor) -> int:
        """Publish the whole stream; return the exit status."""
        last_spin = [time.monotonic()]

        def spin(timeout_s: float) -> None:
            executor.spin_once(timeout_sec=timeout_s)
            last_spin[0] = time.monotonic()

        pieces = _Pieces(self._with_frames(reference_batch_chunks(self.plan)))
        try:
            if not self._wait_for_subscribers(spin):
                return EXIT_FAILURE
            if self._static_topic:
                static = self.frames.static_batch()
                assert static is not None
                self._publishers_by_topic[self._static_topic].publish(static.payloads[0])
                self.counts[self._static_topic] += 1
            pacer: Pacer | None = None
            gate = self.gate
            # With flow control the pace is an upper bound, not a schedule: no pacing errors.
            paced = self.rate_factor > 0 and gate is None
            errors, counts = self.errors, self.counts
            ok = self.context.ok
            spin_every = SPIN_EVERY_S if gate is None else FLOW_SPIN_EVERY_S
            wall_start = time.monotonic()
            t_first = t_last = 0
            next_late = 0.0
            self.get_logger().info("publishing")
            while (item := pieces.get(spin)) is not None:
                _, batches = item
                for b in batches:
                    if self._msgtypes.get(b.topic) != b.msgtype:
                        raise RuntimeError(f"unexpected batch {b.topic} ({b.msgtype})")
                pubs = [self._publishers_by_topic[b.topic] for b in batches]
                for k, i, stamp in merge_order(batches):
                    topic = batches[k].topic
                    if pacer is None:
                        group_ns = round(self.publish_period_s * 1e9)
                        pacer = Pacer(self.rate_factor, stamp, group_ns=group_ns)
                        wall_start, t_first = pacer.start, stamp
                    pacer.wait(stamp, spin)
                    if gate is not None and counts[topic] >= gate.limits[topic]:
                        # The pace resumes from here: a stall is not caught up in a burst.
                        pacer.start += gate.wait(topic, counts[topic], spin, ok)
                    # SIGINT / SIGTERM (rclpy's signal handlers); ok() is not free: every 64th
                    if not counts[topic] & 63 and not ok():
                        raise ExternalShutdownException()
                    if paced:
                        errors.append(time.monotonic() - pacer.release(stamp))
                    pubs[k].publish(batches[k].payloads[i])
                    counts[topic] += 1
                    t_last = stamp
                    if time.monotonic() - last_spin[0] > spin_every:
                        spin(0.0)
                        if paced and errors[-1] > LATE_WARNING_S and last_spin[0] > next_late:
                            next_late = last_spin[0] + LATE_EVERY_S
                            self.get_logger().warning(
                                f"behind real time: publishing {errors[-1]:.2f} s late "
                                f"({(stamp - t_first) * 1e-9:.1f} s of data published)"
                            )
            elapsed = time.monotonic() - wall_start
            self._log_summary(elapsed, (t_last - t_first) * 1e-9, pacer)
            self._drain(spin)
            if not self.exit_when_done:
                self.get_logger().info("done; exit_when_done is false, spinning until shutdown")
                while rclpy.ok(context=self.context):
                    spin(1.0)
            return EXIT_OK
        finally:
            pieces.cancel()

    def _with_frames(self, pieces):
        """The reference pieces with their derived batches (TF, map odometry) appended."""
        for piece, batches in pieces:
            derived = [b for b in self.frames.feed_batches(batches) if b.topic in self._derived]
            yield piece, batches + derived

    def _wait_for_subscribers(self, spin: Callable[[float], None]) -> bool:
        wanted = self.wait_for_subscribers
        if wanted <= 0 and not self.subscribers_per_topic:
            return True
        topics = set(self._wait_topics) | set(self.subscribers_per_topic)
        pubs = [p for t, p in self._publishers_by_topic.items() if t in topics]
        return wait_for_subscriptions(
            self, pubs, wanted, self.wait_timeout_s, spin, self.subscribers_per_topic
        )

    def _drain(self, spin: Callable[[float], None]) -> None:
        """Let the subscribers receive everything: acknowledgements, then a grace period."""
        pubs = list(self._publishers_by_topic.values())
        waited = drain_publishers(self, pubs, spin, DRAIN_TIMEOUT_S, GRACE_S)
        if waited is not None:
            self.get_logger().info(f"all messages acknowledged after {waited:.3f} s")

    def _log_summary(self, elapsed: float, span: float, pacer: Pacer | None) -> None:
        total = sum(self.counts.values())
        lines = [
            f"published {total} messages: {span:.3f} s of data in {elapsed:.3f} s of wall "
            f"time ({span / max(elapsed, 1e-9):.2f}x real time)"
        ]
        if self.gate is not None:
            g = self.gate
            lines.append(
                f"flow control: waited {g.stalled_s:.3f} s in {g.stalls} stall(s) for the "
                f"consumers (window {g.window} messages)"
            )
        if pacer is not None and self.rate_factor > 0 and self.gate is None:
            st = pacing_stats(self.errors)
            lines.append(
                f"max lateness {pacer.max_lateness_s * 1e3:.3f} ms (pacing error publish - "
                f"{'due' if pacer.group_ns == 0 else 'release at the end of its group'} "
                f"over {st.count} messages: p50 {st.p50 * 1e3:.3f} ms, p99 {st.p99 * 1e3:.3f} "
                f"ms, max {st.max * 1e3:.3f} ms)"
            )
        lines += [f"  {t}: {n}" for t, n in self.counts.items()]
        self.get_logger().info("\n".join(lines))


def _parameter_of(topic: str, topics: dict[str, str]) -> str:
    for name, key in TOPIC_PARAMETERS.items():
        if topics.get(key) == topic:
            return name
    return "imu_topic"


def main(args: list[str] | None = None) -> int:
    """Run the node; return the exit status (0 done, 1 failure, 2 invalid input)."""
    return run_node(TrajectoryNode, NODE_NAME, args)
