"""``bag_player``: publishes a bag's serialized messages with their original timing.

Every message of the selected topics is published raw (the bag's CDR payload, nothing is
deserialized) at wall time ``start + (t - t_begin) / rate_factor`` (monotonic clock), where
``t`` is its log time, ``t_begin`` = the bag's first log time + ``start_offset_s`` and ``start``
= when the first message goes out; with ``duration_s`` only the window ``[t_begin, t_begin +
duration_s]`` is played. The player sleeps until shortly before each deadline while servicing
rclpy, then sleeps precisely; a separate process reads the bag ahead
(:class:`~strapdown_ros.bag.playback.ReaderProcess`) so that parsing a chunk never delays a
publication. It publishes ``/clock`` (``rosgraph_msgs/Clock``, the log time, before the first
message of each new log time, or with ``clock_rate_hz`` before the first message of each
``1/clock_rate_hz`` of bag time: :class:`~strapdown_ros.bag.playback.ClockTicks`) unless the bag
itself has the clock topic, which is then played as recorded. With ``loop`` it starts over after
the last message (one mean message interval later) until stopped. Topics can be selected
(``topics``) and renamed (``remap``; ROS' own ``-r from:=to`` works too); publishers take the
reliability and durability the bag recorded.

At the end (or on SIGINT/SIGTERM) it logs the messages per topic and the pacing error — publish
time minus scheduled time — as p50, p99 and max; while it plays, it warns (at most once a
second) when publications are later than ``pacing_warn_ms``. A bag it cannot read (missing
directory or metadata, truncated or interrupted data file, unknown topic) is refused before
anything is published, with the reason; an empty bag is reported and nothing is published.
Parameters: docs/recording.md.

Exit status: 0 played (also when stopped by a signal, or nothing to play), 1 failure while
playing (e.g. the data turned out corrupt midway), 2 invalid parameter or unreadable bag.
"""

from __future__ import annotations

import array
import contextlib
import gc
import os
import time
from collections.abc import Callable, Iterator

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from strapdown_ros.bag.playback import (
    CLOCK_MSGTYPE,
    PASS_END,
    BagSource,
    ClockTicks,
    PacingWatch,
    PlayTopic,
    ReaderProcess,
    clock_payload,
    pacing_stats,
)
from strapdown_ros.bag.reader import BagReadError
from strapdown_ros.nodes.handshake import wait_for_subscriptions
from strapdown_ros.nodes.lifecycle import EXIT_FAILURE, EXIT_OK, drain_publishers, run_node
from strapdown_ros.nodes.message_types import message_class
from strapdown_ros.nodes.pacing import Pacer
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_bool,
    declare_int,
    declare_number,
    declare_string,
    declare_string_array,
)
from strapdown_ros.nodes.qos import qos_profile
from strapdown_ros.nodes.signals import SignalStop

NODE_NAME = "bag_player"
#: Longest time without servicing rclpy while publishing.
SPIN_EVERY_S = 0.05
GRACE_S = 0.3


class _StopRequestedError(Exception):
    """SIGINT/SIGTERM arrived while the player was waiting."""


class BagPlayer(SignalStop, Node):
    """Publishes a bag's messages paced against the wall clock (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        bag = declare_string(self, "bag", "", "bag directory to play (required)")
        self.rate_factor = declare_number(
            self, "rate_factor", 1.0, "speed over real time; <= 0: as fast as possible"
        )
        self.start_offset_s = declare_number(
            self, "start_offset_s", 0.0, "skip this many seconds from the bag's start"
        )
        self.duration_s = declare_number(
            self, "duration_s", 0.0, "play this many seconds of the bag from the start; 0: all"
        )
        self.loop = declare_bool(self, "loop", False, "start over at the end, until stopped")
        topics = declare_string_array(self, "topics", "topics to play (default: all)")
        remaps = declare_string_array(self, "remap", "renames FROM:=TO")
        self.publish_clock = declare_bool(self, "publish_clock", True, "publish /clock")
        self.clock_topic = declare_string(self, "clock_topic", "/clock", "topic of the clock")
        self.clock_rate_hz = declare_number(
            self, "clock_rate_hz", 0.0, "/clock ticks per second of bag time; 0: every log time"
        )
        self.pacing_warn_ms = declare_number(
            self, "pacing_warn_ms", 50.0, "warn while playing when publications are later "
            "than this; 0: never",
        )  # fmt: skip
        depth = declare_int(self, "qos_depth", 1000, "publisher history depth", minimum=1)
        self.wait_for_subscribers = declare_int(
            self, "wait_for_subscribers", 0, "subscriptions to wait for on every topic", 0
        )
        self.wait_timeout_s = declare_number(self, "wait_timeout_s", 10.0, "seconds to wait")
        self.drain_timeout_s = declare_number(
            self, "drain_timeout_s", 10.0, "at the end, longest wait for acknowledgements"
        )
        self.read_ahead = declare_int(
            self, "read_ahead", 20_000, "messages buffered ahead of the publisher", minimum=1
        )
        self.realtime_priority = declare_int(
            self, "realtime_priority", 0, "SCHED_FIFO priority of the publishing thread; 0: off", 0
        )
        if self.realtime_priority > 99:
            raise ParameterError(
                "realtime_priority", f"must be 0 (off) or 1..99, got {self.realtime_priority}"
            )
        if not bag:
            raise ParameterError("bag", "is required (the bag directory to play)")
        for name in ("start_offset_s", "duration_s", "clock_rate_hz", "pacing_warn_ms"):
            if getattr(self, name) < 0:
                raise ParameterError(name, f"must be >= 0, got {getattr(self, name):g}")
        remap = _parse_remaps(remaps)
        self.selected = bool(topics)
        try:
            self.source = BagSource(bag, topics, remap)
        except BagReadError as exc:
            raise ParameterError("bag", str(exc)) from exc

        self.begin_ns = self.source.start_ns + round(self.start_offset_s * 1e9)
        #: end of the window (exclusive; None: the bag's end): [begin, begin + duration]
        self.stop_ns = None if self.duration_s == 0 else self.begin_ns + round(
            self.duration_s * 1e9) + 1  # fmt: skip
        if self.source.message_count and self.begin_ns > self.source.end_ns:
            span = (self.source.end_ns - self.source.start_ns) * 1e-9
            self.source.close()
            raise ParameterError(
                "start_offset_s", f"{self.start_offset_s:g} s is beyond the bag's {span:g} s"
            )
        self.publishers_by_index: list[object | None] = []
        self.played: list[PlayTopic] = []
        for t in self.source.topics:
            try:
                cls = message_class(t.msgtype)
            except ValueError as exc:
                self.get_logger().warning(f"{t.topic}: not played: {exc}")
                self.publishers_by_index.append(None)
                continue
            qos = qos_profile(depth, reliable=t.reliable, transient_local=t.transient_local)
            try:
                pub = self.create_publisher(cls, t.out_topic, qos)
            except Exception as exc:  # invalid (remapped) topic name
                raise ParameterError("remap", f"{t.topic} -> {t.out_topic}: {exc}") from exc
            self.publishers_by_index.append(pub)
            self.played.append(t)
        out_topics = [p.topic_name for p in self.publishers_by_index if p is not None]
        self.clock_pub = None
        if self.publish_clock:
            if self.clock_topic in out_topics:
                self.get_logger().info(
                    f"the bag has {self.clock_topic}: it is played as recorded"
                )
            else:
                self.clock_pub = self.create_publisher(
                    message_class(CLOCK_MSGTYPE),
                    self.clock_topic,
                    QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE),
                )
        self.counts = {t.out_topic: 0 for t in self.played}
        self.clock_count = 0
        self.errors = array.array("d")
        self.loops = 0
        self._stop_reason: str | None = None
        src = self.source
        self.get_logger().info(
            f"bag {src.path}: {src.message_count} messages on {len(self.played)} topic(s), "
            f"{(src.end_ns - src.start_ns) * 1e-9:.3f} s; rate_factor {self.rate_factor:g}, "
            f"start_offset_s {self.start_offset_s:g}, duration_s {self.duration_s:g}, "
            f"loop {self.loop}; topics "
            + ", ".join(
                t.topic if t.topic == t.out_topic else f"{t.topic} -> {t.out_topic}"
                for t in self.played
            )
        )

    # -----------------------------------------------------------------------------------------

    def run(self, executor) -> int:
        """Play the bag; return the exit status."""
        self.take_stop_signals()
        try:
            if not self.played or self.source.message_count == 0:
                self.get_logger().warning(
                    f"bag {self.source.path} has no messages"
                    + (" on the selected topics" if self.selected else "")
                    + ": nothing to play"
                )
                return EXIT_OK
            reader = ReaderProcess(
                self.source, self.begin_ns, self.stop_ns, loop=self.loop,
                high_water=self.read_ahead,
            )  # fmt: skip
            try:
                status = self._run_with(executor, reader)
            finally:
                reader.close()
            return status
        finally:
            self.source.close()

    def _run_with(self, executor, reader: ReaderProcess) -> int:
        last_spin = [time.monotonic()]

        def spin(timeout_s: float) -> None:
            if self._stop_reason is not None:  # a signal while waiting (subscribers, deadline)
                raise _StopRequestedError()
            reader.refill()  # a moment to spare: take a batch from the reader process
            executor.spin_once(timeout_sec=timeout_s)
            last_spin[0] = time.monotonic()

        start: float | None = None
        try:
            if not self._wait_for_subscribers(spin):
                return EXIT_FAILURE
            reader.wait_ready()
            for _ in range(3):  # the executor's first passes are slow (wait set set-up)
                spin(0.0)
            # Everything allocated so far is long-lived: keep the garbage collector's full
            # passes (tens of ms with rclpy loaded) off it, so they cannot stall a publication.
            gc.collect()
            gc.freeze()
            start = time.monotonic()
            with self._realtime():
                status = self._play(reader, spin, last_spin)
        except BagReadError as exc:
            self.get_logger().error(f"{exc}; stopped")
            status = EXIT_FAILURE
        except _StopRequestedError:
            status = EXIT_OK
        if start is not None:
            self._log_summary(time.monotonic() - start)
        if status == EXIT_OK:
            try:
                self._drain(spin)
            except _StopRequestedError:
                pass
        return status

    def _play(
        self, reader: ReaderProcess, spin: Callable[[float], None], last_spin: list[float]
    ) -> int:
        pubs = self.publishers_by_index
        topics = self.source.topics
        counts = self.counts
        errors = self.errors
        clock_pub = self.clock_pub
        paced = self.rate_factor > 0
        pacer: Pacer | None = None
        ticks = ClockTicks(
            round(1e9 / self.clock_rate_hz) if self.clock_rate_hz else 0, self.begin_ns
        )
        watch = PacingWatch(self.pacing_warn_ms * 1e-3 if paced else 0.0)
        warn = self.get_logger().warning
        offset_ns = 0  # added to the log times of the current pass (loop)
        gap_ns = 0
        last_t: int | None = None
        distinct = 0  # distinct log times in the first pass
        while self._stop_reason is None:
            item = reader.get()
            if item is None:
                break
            if item == PASS_END:  # loop: the next pass follows one mean interval later
                if not self.loop:
                    continue
                self.loops += 1
                if last_t is None:
                    break
                if not gap_ns:
                    span = last_t - self.begin_ns
                    gap_ns = span // (distinct - 1) if distinct > 1 else 1_000_000_000
                offset_ns += last_t - self.begin_ns + gap_ns
                last_t = None
                ticks.restart(self.begin_ns)
                continue
            k, t, data = item  # type: ignore[misc]
            pub = pubs[k]
            if pub is None:
                continue
            stamp = t + offset_ns
            if pacer is None:
                pacer = Pacer(self.rate_factor, stamp)
            pacer.wait(stamp, spin)
            if self._stop_reason is not None:
                break
            if paced:
                now = time.monotonic()
                errors.append(now - pacer.due(stamp))
                text = watch.observe(errors[-1], now)
                if text is not None:
                    warn(text)
            if t != last_t:
                if not self.loops:
                    distinct += 1
                if clock_pub is not None and ticks.due(t):
                    clock_pub.publish(clock_payload(t))
                    self.clock_count += 1
            pub.publish(data)
            counts[topics[k].out_topic] += 1
            last_t = t
            reader.refill()
            if time.monotonic() - last_spin[0] > SPIN_EVERY_S:
                spin(0.0)
        return EXIT_OK

    @contextlib.contextmanager
    def _realtime(self) -> Iterator[None]:
        """Run the block with the publishing thread on SCHED_FIFO (``realtime_priority``)."""
        prio = self.realtime_priority
        if prio <= 0 or self.rate_factor <= 0 or not hasattr(os, "sched_setscheduler"):
            yield
            return
        try:
            before = os.sched_getscheduler(0), os.sched_getparam(0)
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
        except OSError as exc:
            self.get_logger().warning(
                f"realtime_priority {prio}: cannot use SCHED_FIFO ({exc.strerror}); pacing on the "
                "normal scheduler (needs CAP_SYS_NICE or an rtprio limit, see docs/recording.md)"
            )
            yield
            return
        self.get_logger().info(f"publishing thread on SCHED_FIFO priority {prio}")
        try:
            yield
        finally:
            os.sched_setscheduler(0, before[0], before[1])

    def _wait_for_subscribers(self, spin: Callable[[float], None]) -> bool:
        wanted = self.wait_for_subscribers
        if wanted <= 0:
            return True
        pubs = [p for p in self.publishers_by_index if p is not None]
        return wait_for_subscriptions(self, pubs, wanted, self.wait_timeout_s, spin)

    def _drain(self, spin: Callable[[float], None]) -> None:
        """Give RELIABLE subscribers the time to acknowledge everything, then a grace period."""
        pubs = [p for p in self.publishers_by_index if p is not None]
        if self.clock_pub is not None:
            pubs.append(self.clock_pub)
        drain_publishers(
            self, pubs, spin, self.drain_timeout_s, GRACE_S, lambda: self._stop_reason is None
        )

    def _log_summary(self, elapsed: float) -> None:
        total = sum(self.counts.values())
        stats = pacing_stats(self.errors)
        why = f" (stopped: {self._stop_reason})" if self._stop_reason else ""
        lines = [
            f"played {total} messages in {elapsed:.3f} s"
            + (f", {self.loops} loop(s)" if self.loop else "")
            + why,
            stats.format() if self.rate_factor > 0 else "rate_factor <= 0: not paced",
        ]
        if self.clock_pub is not None:
            lines.append(f"  {self.clock_topic}: {self.clock_count} (clock)")
        lines += [f"  {t}: {n}" for t, n in self.counts.items()]
        self.get_logger().info("\n".join(lines))


def _parse_remaps(specs: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for spec in specs:
        src, sep, dst = spec.partition(":=")
        if not sep:
            src, sep, dst = spec.partition("=")
        src, dst = src.strip(), dst.strip()
        if not sep or not src or not dst:
            raise ParameterError("remap", f"{spec!r}: expected FROM:=TO")
        if src in out:
            raise ParameterError("remap", f"{src} is remapped twice")
        out[src] = dst
    return out


def main(args: list[str] | None = None) -> int:
    """Run the player; return the exit status (0 played, 1 failure, 2 invalid input)."""
    return run_node(BagPlayer, NODE_NAME, args)
