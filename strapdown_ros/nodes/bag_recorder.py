"""``bag_recorder``: records topics into a rosbag2 directory, durable up to the last flush.

It subscribes raw (serialized payloads, nothing is deserialized) to a configured topic list —
by default every topic of docs/interface.md §4 the scenario produces (:func:`strapdown_ros.topics.
produced_topics`) that its ``recording.include``/``recording.exclude`` select — and writes
the payloads with :class:`~strapdown_ros.bag.recording.Recording`
into an mcap (default) or sqlite3 bag: Fast DDS' trailing alignment padding is stripped and the
log time is the header stamp, so the bag's messages are byte-identical to what
``strapdown-sim generate`` writes for the same scenario. Topics are subscribed when their first
publisher is discovered, with a QoS matching the publishers' (``qos_reliability: auto``:
RELIABLE when every publisher is, TRANSIENT_LOCAL likewise) and a deep queue; the publishers'
offered QoS profiles are stored in the bag. Callbacks run on rclpy's ``EventsExecutor``
(spun with ``spin_once``), which takes tens of thousands of messages per second.

The bag is flushed every ``flush_period_s`` (mcap: the chunk is closed and written; sqlite3:
the transaction is committed); after a SIGKILL everything flushed can be recovered with
``strapdown-sim bag repair DIR``. On SIGINT/SIGTERM (or ``max_duration_s``, or
``stop_when_done``) the recorder takes what is still queued, closes the bag (summary and
``metadata.yaml``) and logs the message count of every topic. Parameters: docs/recording.md.

Exit status: 0 recorded (also when stopped by a signal), 1 failure while recording (e.g. a write
error; the bag is closed as far as possible), 2 invalid parameter or scenario.
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos

from strapdown_ros.bag.cdr import TF_MESSAGE
from strapdown_ros.bag.incremental import IncrementalBagWriter
from strapdown_ros.bag.payload import PayloadError, PayloadInspector
from strapdown_ros.bag.qos import DEFAULT_QOS, offered_profiles
from strapdown_ros.bag.recording import LOG_TIMES, Handler, Recording
from strapdown_ros.bag.selection import SelectionError, TopicSelection
from strapdown_ros.bag.writer import STORAGES, BagWriteError, check_compression, looks_like_bag
from strapdown_ros.config import load_scenario
from strapdown_ros.nodes._tf import tf_unavailable
from strapdown_ros.nodes.lifecycle import EXIT_FAILURE, EXIT_OK, run_node
from strapdown_ros.nodes.message_types import message_class
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_bool,
    declare_int,
    declare_number,
    declare_string,
    declare_string_array,
)
from strapdown_ros.nodes.qos import describe_qos, qos_profile
from strapdown_ros.nodes.signals import SignalStop
from strapdown_ros.plan import resolve_plan
from strapdown_ros.plan.metadata import bag_custom_data
from strapdown_ros.stages.tf import STATIC_QOS, TFStage
from strapdown_ros.topics import spec_topics

NODE_NAME = "bag_recorder"
RELIABILITIES = ("auto", "reliable", "best_effort")
#: After a stop request: spin until a pass brings no message (but at most drain_timeout_s).
QUIET_S = 0.05
#: Seconds between looks at the publishers once every topic is subscribed (only new
#: publishers' QoS is checked then; each look asks the graph about every topic).
SETTLED_DISCOVERY_S = 2.0
#: Seconds between the looks at how far behind the wall clock the topics are (lag_warning_s).
LAG_EVERY_S = 1.0
#: Messages "taken" reported for a topic the recorder does not record (flow control).
NOT_HELD_BACK = 1 << 60


@dataclass
class _Topic:
    """One recorded topic: its type, subscription and publishers seen."""

    name: str
    msgtype: str | None
    subscription: object | None = None
    handler: Handler | None = None
    offered: list[Qos] = field(default_factory=list)
    warned: set[str] = field(default_factory=set)


class BagRecorder(SignalStop, Node):
    """Records a topic list into a rosbag2 directory (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        scenario_path = declare_string(self, "scenario", "", "scenario YAML file (topic list)")
        overrides = declare_string_array(self, "overrides", "scenario overrides dotted.key=value")
        duration_s = declare_number(self, "duration_s", 0.0, "duration (s); 0 = the scenario's")
        topic_specs = declare_string_array(self, "topics", "topics to record: NAME[=pkg/msg/Type]")
        output = declare_string(self, "output", "", "bag directory to write (required)")
        storage = declare_string(self, "storage", "", "mcap | sqlite3 (default: scenario's)")
        compression = declare_string(
            self, "compression", "", "MCAP chunk compression none | zstd | lz4 (default: "
            "scenario's, else none)",
        )  # fmt: skip
        self.force = declare_bool(self, "force", False, "replace an existing bag directory")
        self.flush_period_s = declare_number(self, "flush_period_s", 1.0, "seconds per flush")
        self.fsync = declare_bool(self, "fsync", False, "fsync the data file at every flush")
        self.log_time = declare_string(self, "log_time", "header", "header | receive")
        self.reliability = declare_string(
            self, "qos_reliability", "auto", "auto | reliable | best_effort"
        )
        self.depth = declare_int(
            self, "qos_depth", 0, "subscription queue depth; 0 = KEEP_ALL", minimum=0
        )
        self.discovery_period_s = declare_number(
            self, "discovery_period_s", 0.1, "seconds between looks for new publishers"
        )
        self.max_duration_s = declare_number(
            self, "max_duration_s", 0.0, "stop after this many seconds; 0 = until a signal"
        )
        self.stop_when_done = declare_bool(
            self, "stop_when_done", False, "stop when every recorded topic lost its publishers"
        )
        self.progress_period_s = declare_number(
            self, "progress_period_s", 10.0, "seconds between progress lines; 0 = none"
        )
        self.lag_warning_s = declare_number(
            self, "lag_warning_s", 0.0,
            "real-time runs: warn when a topic's data is this far behind the wall clock; 0 = off",
        )  # fmt: skip
        self.drain_timeout_s = declare_number(
            self, "drain_timeout_s", 2.0, "at a stop, longest time taking queued messages"
        )
        self.report_progress = declare_bool(
            self, "report_progress", False,
            "publish the messages recorded per topic for flow control (nodes/flow.py)",
        )  # fmt: skip
        if not output:
            raise ParameterError("output", "is required (the bag directory to write)")
        for name, value in (
            ("flush_period_s", self.flush_period_s),
            ("discovery_period_s", self.discovery_period_s),
        ):
            if value <= 0:
                raise ParameterError(name, f"must be > 0, got {value}")
        for name, value in (
            ("max_duration_s", self.max_duration_s),
            ("progress_period_s", self.progress_period_s),
            ("lag_warning_s", self.lag_warning_s),
            ("drain_timeout_s", self.drain_timeout_s),
        ):
            if value < 0:
                raise ParameterError(name, f"must be >= 0, got {value}")
        if self.log_time not in LOG_TIMES:
            raise ParameterError(
                "log_time", f"must be one of: {', '.join(LOG_TIMES)}; got {self.log_time!r}"
            )
        if self.reliability not in RELIABILITIES:
            raise ParameterError(
                "qos_reliability",
                f"must be one of: {', '.join(RELIABILITIES)}; got {self.reliability!r}",
            )

        scenario = (
            load_scenario(scenario_path, overrides, duration_s if duration_s > 0 else None)
            if scenario_path else None
        )  # fmt: skip
        plan = resolve_plan(scenario) if scenario is not None else None
        if storage == "":
            storage = scenario.recording.storage if scenario is not None else "mcap"
        if storage not in STORAGES:
            raise ParameterError("storage", f"must be one of: mcap, sqlite3; got {storage!r}")
        self.storage = storage
        if compression == "":
            compression = scenario.recording.compression if scenario is not None else "none"
        try:
            check_compression(storage, compression)
        except BagWriteError as exc:
            raise ParameterError("compression", str(exc)) from exc
        self.compression = compression
        self.output = Path(output).absolute()
        if self.output.exists() and not self.force:
            raise ParameterError("output", f"{self.output} exists already (set force:=true)")
        if self.output.exists() and not _replaceable(self.output):
            raise ParameterError("output", f"{self.output} exists and is not a bag directory")

        #: the scenario's topics that recording.include/exclude leave out
        self._excluded: list[str] = []
        if topic_specs:
            wanted = _parse_topics(topic_specs)
        elif plan is not None:  # the scenario's topics that recording.include/exclude select
            types = plan.topic_types()
            try:
                selected = TopicSelection.of_recording(plan.scenario.recording).check(types)
            except SelectionError as exc:
                raise ParameterError("scenario", str(exc)) from exc
            wanted = {t: types[t] for t in selected}
            self._excluded = [t for t in types if t not in wanted]
        else:
            wanted = dict(spec_topics())
        # Without tf2_msgs, /tf and /tf_static cannot be received: derived here from the recorded
        # Odometry with the code generate uses (same bytes), and said so in the bag.
        self._derive: TFStage | None = None
        self._derived_tf: dict[str, Handler | None] = {}
        if plan is not None and not topic_specs:
            tf_topics = [n for n, m in wanted.items() if m == TF_MESSAGE]
            error = tf_unavailable() if tf_topics else None
            if error is not None:
                self._derive = TFStage(plan)
                for name in tf_topics:
                    wanted.pop(name)
                    self._derived_tf[name] = None
                self.get_logger().warning(
                    f"tf2_msgs/msg/TFMessage is not importable ({error}): "
                    f"{', '.join(tf_topics)} cannot be received; they are derived from the "
                    "recorded Odometry with the code generate uses (TFStage), and the bag's "
                    "custom_data says so (tf: derived by bag_recorder)"
                )
        self.topics: dict[str, _Topic] = {}
        for name, msgtype in wanted.items():
            if msgtype is not None:
                self._check_type("topics", name, msgtype)
            self.topics[name] = _Topic(name, msgtype)
        self.custom_data = {"generator": "strapdown_ros", "recorder": NODE_NAME}
        #: topic → bag log time minus header stamp (ns), e.g. a GNSS receiver's latency
        self.log_delays: dict[str, int] = {}
        if plan is not None:
            self.log_delays = plan.log_delays()
            self.custom_data = {**bag_custom_data(plan), "recorder": NODE_NAME}
        if self._derive is not None:
            self.custom_data["tf"] = "derived by bag_recorder from the recorded Odometry"
        self.recording: Recording | None = None
        self._stop_reason: str | None = None
        #: [the node's clock follows /clock (use_sim_time)], refreshed at every discovery pass.
        self._sim_time = [self.get_clock().ros_time_is_active]
        self.get_logger().info(
            f"recording {len(self.topics)} topic(s) into {self.output} ({self.storage}"
            + (f", {self.compression} chunks" if self.compression != "none" else "") + "), "
            f"flush every {self.flush_period_s:g} s: " + ", ".join(self.topics)
        )

    @staticmethod
    def _check_type(param: str, topic: str, msgtype: str) -> None:
        try:
            message_class(msgtype)
            PayloadInspector(msgtype)
        except (ValueError, PayloadError) as exc:
            raise ParameterError(param, f"{topic}: {exc}") from exc

    # -- discovery and subscriptions -----------------------------------------------------------

    def _discover(self) -> None:
        """Subscribe to topics whose first publisher appeared; warn about incompatible ones."""
        names_types = None
        for t in self.topics.values():
            infos = self.get_publishers_info_by_topic(t.name)
            if t.subscription is not None:
                self._check_new_publishers(t, infos)
                continue
            if not infos and self.reliability == "auto":
                continue
            if t.msgtype is None:
                if names_types is None:
                    names_types = dict(self.get_topic_names_and_types())
                types = names_types.get(t.name, [])
                if len(types) != 1:
                    continue  # not discovered yet (or ambiguous: warned below when it matters)
                t.msgtype = types[0]
            graph_types = {i.topic_type for i in infos}
            if graph_types and graph_types != {t.msgtype}:
                self._warn_once(
                    t, "type", f"{t.name}: publishers offer {sorted(graph_types)}, recording "
                    f"{t.msgtype} only; not subscribing"
                )
                continue
            self._subscribe(t, infos)

    def _subscribe(self, t: _Topic, infos: list) -> None:
        assert self.recording is not None and t.msgtype is not None
        qos = self._subscription_qos(infos)
        t.offered = offered_profiles(infos)
        try:
            t.handler = self.recording.handler(
                t.name, t.msgtype, lambda t=t: self._offered(t), self.log_delays.get(t.name, 0)
            )
        except PayloadError as exc:
            self._warn_once(t, "inspector", f"{t.name}: cannot record {t.msgtype}: {exc}")
            return
        handler, clock, sim = t.handler, self.get_clock(), self._sim_time
        time_ns = time.time_ns

        def on_message(payload: bytes) -> None:
            # The node's clock is the system clock unless use_sim_time is on: time.time_ns()
            # then gives the same receive time at a fraction of clock.now()'s cost.
            handler(payload, clock.now().nanoseconds if sim[0] else time_ns())

        derive, tf_handlers = self._derive, self._derived_tf
        if derive is not None and t.name in derive.odom_topics:

            def on_message(payload: bytes) -> None:  # noqa: F811  (and the TF derived from it)
                now = clock.now().nanoseconds if sim[0] else time_ns()
                handler(payload, now)
                for topic, _, data in derive.derive_items([(t.name, 0, payload)]):
                    record = tf_handlers.get(topic)
                    if record is not None:
                        record(data, now)

        t.subscription = self.create_subscription(
            message_class(t.msgtype), t.name, on_message, qos, raw=True
        )
        self.get_logger().info(
            f"subscribed to {t.name} ({t.msgtype}, {describe_qos(qos)}, "
            f"{len(infos)} publisher(s))"
        )

    def _offered(self, t: _Topic) -> list[Qos]:
        """Offered QoS profiles to store for ``t`` (asked for with its first message)."""
        if not t.offered:  # subscribed before any publisher was seen
            infos = self.get_publishers_info_by_topic(t.name)
            t.offered = offered_profiles(infos)
        return t.offered

    def _subscription_qos(self, infos: list) -> QoSProfile:
        if self.reliability == "auto":
            reliable = all(
                i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos
            )
        else:
            reliable = self.reliability == "reliable"
        transient = bool(infos) and all(
            i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos
        )
        return qos_profile(
            max(self.depth, 1), reliable=reliable, transient_local=transient,
            keep_all=self.depth == 0,
        )  # fmt: skip

    def _check_new_publishers(self, t: _Topic, infos: list) -> None:
        sub_qos = t.subscription.qos_profile  # type: ignore[attr-defined]
        for i in infos:
            if (
                sub_qos.reliability == ReliabilityPolicy.RELIABLE
                and i.qos_profile.reliability != ReliabilityPolicy.RELIABLE
            ):
                self._warn_once(
                    t, f"qos:{i.node_namespace}/{i.node_name}",
                    f"{t.name}: publisher {i.node_name} is BEST_EFFORT but the recorder "
                    "subscribed RELIABLE: its messages are not recorded",
                )

    def _warn_once(self, t: _Topic, key: str, text: str) -> None:
        if key not in t.warned:
            t.warned.add(key)
            self.get_logger().warning(text)

    def _publishers_gone(self) -> bool:
        subscribed = [t for t in self.topics.values() if t.subscription is not None]
        return bool(subscribed) and all(
            t.subscription.get_publisher_count() == 0  # type: ignore[attr-defined]
            for t in subscribed
        )

    # -- main loop -----------------------------------------------------------------------------

    def run(self, executor) -> int:
        """Record until a signal, ``max_duration_s`` or ``stop_when_done``; return the status."""
        # Our own handlers: a signal only sets a flag, so that the queued messages are still
        # taken and the bag is closed properly (rclpy's would shut the context down first).
        self.take_stop_signals()

        try:
            writer = IncrementalBagWriter(
                self.output,
                storage=self.storage,
                compression=self.compression,
                force=self.force,
                custom_data=self.custom_data,
                fsync=self.fsync,
            ).open()
        except (BagWriteError, OSError) as exc:  # OSError: read-only or full file system
            self.get_logger().error(f"cannot create the bag: {exc}")
            return EXIT_FAILURE
        self.recording = Recording(
            writer, log_time=self.log_time, flush_period_s=self.flush_period_s
        )
        if self._derive is not None:  # derived TF (tf2_msgs missing): /tf_static at once
            static = self._derive.tf_static_topic
            for name in self._derived_tf:
                qos = [STATIC_QOS] if name == static else [DEFAULT_QOS]
                self._derived_tf[name] = self.recording.handler(
                    name, TF_MESSAGE, lambda qos=qos: qos
                )
            batch = self._derive.static_batch()
            record = self._derived_tf.get(static)
            if batch is not None and record is not None:
                record(batch.payloads[0], self.get_clock().now().nanoseconds)
        gc.collect()
        gc.freeze()  # long-lived objects out of the collector's full passes (shorter pauses)
        status = EXIT_OK
        start = time.monotonic()
        try:
            status = self._record(executor, start)
        except (BagWriteError, OSError) as exc:  # OSError: a full disk, a vanished mount
            self.get_logger().error(
                f"recording failed: {exc}; the messages flushed so far are kept in "
                f"{self.output} (`strapdown-sim bag repair {self.output}` makes it readable)"
            )
            status = EXIT_FAILURE
        finally:
            self._close(time.monotonic() - start)
        return status

    def _record(self, executor, start: float) -> int:
        recording = self.recording
        assert recording is not None
        next_discovery = next_progress = next_settled = next_lag = time.monotonic()
        reporter = None
        if self.report_progress:
            from strapdown_ros.nodes.flow import ProgressReporter

            stats = recording.stats
            # the topics it leaves out it never holds back (a flow gate needs a consumer each)
            free = dict.fromkeys(self._excluded, NOT_HELD_BACK)
            reporter = ProgressReporter(
                self, lambda: ({**free, **{t: s.count for t, s in stats.items()}}, {})
            )
        while self._stop_reason is None:
            executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            recording.tick()
            if reporter is not None:
                reporter.maybe_report(now)
            if now >= next_discovery:
                self._sim_time[0] = self.get_clock().ros_time_is_active
                if now >= next_settled:
                    self._discover()
                    if all(t.subscription is not None for t in self.topics.values()):
                        next_settled = now + max(SETTLED_DISCOVERY_S, self.discovery_period_s)
                next_discovery = now + self.discovery_period_s
                if self.stop_when_done and self._publishers_gone():
                    self._stop_reason = "every publisher is gone"
            if self.lag_warning_s > 0 and now >= next_lag:
                next_lag = now + LAG_EVERY_S
                self._warn_lag()
            if self.progress_period_s > 0 and now >= next_progress:
                if now > start:
                    self._log_progress()
                next_progress = now + self.progress_period_s
            if self.max_duration_s > 0 and now - start >= self.max_duration_s:
                self._stop_reason = f"max_duration_s = {self.max_duration_s:g} s"
        self.get_logger().info(f"stopping ({self._stop_reason}); taking queued messages")
        deadline = time.monotonic() + self.drain_timeout_s
        while time.monotonic() < deadline:
            before = recording.message_count
            executor.spin_once(timeout_sec=QUIET_S)
            if recording.message_count == before:
                break
        return EXIT_OK

    def _warn_lag(self) -> None:
        """Log the topics whose data is more than ``lag_warning_s`` behind the wall clock
        (real-time runs; only while messages still arrive: not after the end of the data)."""
        rec = self.recording
        assert rec is not None
        now = self.get_clock().now().nanoseconds if self._sim_time[0] else time.time_ns()
        if rec.last_receive_ns is None or now - rec.last_receive_ns > LAG_EVERY_S * 1e9:
            return
        late = {t: s for t, s in rec.lags_s(now).items() if s > self.lag_warning_s}
        if late:
            self.get_logger().warning(
                "behind real time: "
                + ", ".join(f"{t} {s:.2f} s" for t, s in sorted(late.items(), key=lambda x: -x[1]))
            )

    def _log_progress(self) -> None:
        rec = self.recording
        assert rec is not None
        flushed = rec.flushed_counts
        self.get_logger().info(
            f"progress: {rec.message_count} messages received, {sum(flushed.values())} flushed "
            "(" + ", ".join(f"{t} {n}" for t, n in flushed.items()) + ")"
        )

    def _close(self, elapsed: float) -> None:
        rec = self.recording
        if rec is None:
            return
        try:
            path = rec.close()
        except (BagWriteError, OSError) as exc:
            self.get_logger().error(
                f"cannot finish the bag: {exc}; `strapdown-sim bag repair {self.output}` "
                "recovers what was flushed"
            )
            return
        total = rec.message_count
        span = rec.receive_span_s
        lines = [
            f"recorded {total} messages on {len(rec.stats)} topic(s) in {elapsed:.3f} s into "
            f"{path}; first to last message {span:.3f} s ({total / max(span, 1e-9):.0f} msgs/s)",
            *rec.summary(),
        ]
        silent = [t for t in self.topics if t not in rec.stats or rec.stats[t].count == 0]
        if silent:
            lines.append("no messages on: " + ", ".join(silent))
        self.get_logger().info("\n".join(lines))


# ---------------------------------------------------------------------------------------------


def _replaceable(path: Path) -> bool:
    """An empty directory or a bag directory (what ``force`` may replace)."""
    return path.is_dir() and not path.is_symlink() and (
        not any(path.iterdir()) or looks_like_bag(path)
    )


def _parse_topics(specs: list[str]) -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for spec in specs:
        name, sep, msgtype = spec.partition("=")
        name, msgtype = name.strip(), msgtype.strip()
        if not name.startswith("/"):
            raise ParameterError("topics", f"{spec!r}: topic names must be absolute (/name)")
        if sep and not msgtype:
            raise ParameterError("topics", f"{spec!r}: empty type after '='")
        if name in out:
            raise ParameterError("topics", f"{name} is listed twice")
        out[name] = msgtype or None
    return out


def main(args: list[str] | None = None) -> int:
    """Run the recorder; return the exit status (0 recorded, 1 failure, 2 invalid input)."""
    return run_node(BagRecorder, NODE_NAME, args)
