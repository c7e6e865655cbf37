"""Small helpers shared by the ROS nodes: typed parameters, QoS, message classes, pacing.

Parameter problems raise :class:`ParameterError`; a node's ``main`` turns it (and
:class:`~strapdown_ros.config.ScenarioError`) into exit status 2, as ``strapdown-sim`` does.
"""

from __future__ import annotations

import importlib
import re
import signal
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = [
    "EXIT_FAILURE",
    "EXIT_INVALID",
    "EXIT_OK",
    "InputBatch",
    "Pacer",
    "ParameterError",
    "RunControl",
    "SignalStop",
    "declare_batch_period",
    "declare_bool",
    "declare_int",
    "declare_number",
    "declare_run_control",
    "declare_scenario",
    "declare_string",
    "declare_string_array",
    "declare_subscriber_counts",
    "drain_publishers",
    "make_executor",
    "message_class",
    "qos_from_parameters",
]

#: Exit statuses of the nodes (those of ``strapdown-sim``).
EXIT_OK, EXIT_FAILURE, EXIT_INVALID = 0, 1, 2

RELIABILITY = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}


class ParameterError(ValueError):
    """A node parameter is missing or invalid; ``name`` is the parameter."""

    def __init__(self, name: str, problem: str) -> None:
        self.name = name
        self.problem = problem
        super().__init__(f"parameter '{name}': {problem}")


def _declare(node: Node, name: str, default: Any, description: str, dynamic: bool = False) -> Any:
    descriptor = ParameterDescriptor(description=description, dynamic_typing=dynamic)
    try:
        return node.declare_parameter(name, default, descriptor).value
    except Exception as exc:  # rclpy's InvalidParameterTypeException and the like
        raise ParameterError(name, str(exc)) from exc


def declare_string(node: Node, name: str, default: str, description: str = "") -> str:
    """Declare a string parameter and return its value."""
    value = _declare(node, name, default, description, dynamic=True)
    if not isinstance(value, str):
        raise ParameterError(name, f"must be a string, got {value!r}")
    return value


def declare_bool(node: Node, name: str, default: bool, description: str = "") -> bool:
    """Declare a boolean parameter and return its value."""
    value = _declare(node, name, default, description, dynamic=True)
    if not isinstance(value, bool):
        raise ParameterError(name, f"must be true or false, got {value!r}")
    return value


def declare_number(node: Node, name: str, default: float, description: str = "") -> float:
    """Declare a floating-point parameter (``3`` is accepted as well as ``3.0``)."""
    value = _declare(node, name, float(default), description, dynamic=True)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(name, f"must be a number, got {value!r}")
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ParameterError(name, f"must be finite, got {value}")
    return value


def declare_int(
    node: Node, name: str, default: int, description: str = "", minimum: int | None = None
) -> int:
    """Declare an integer parameter and return its value."""
    value = _declare(node, name, int(default), description, dynamic=True)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ParameterError(name, f"must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise ParameterError(name, f"must be >= {minimum}, got {value}")
    return value


def declare_scenario(node: Node, required: bool = True, what: str = "") -> Any:
    """Declare ``scenario`` (a YAML path), ``overrides`` and ``duration_s``; load the scenario.

    Returns the :class:`~strapdown_ros.config.Scenario` (None when ``required`` is False and
    no path is given). ``what`` says what the node takes from it, for the description. Raises
    :class:`ParameterError` for a missing path or a negative duration and
    :class:`~strapdown_ros.config.ScenarioError` for an invalid file.
    """
    from strapdown_ros.config import load_scenario

    path = declare_string(
        node, "scenario", "", f"scenario YAML file{f' ({what})' if what else ''}"
        + (" (required)" if required else "")
    )
    overrides = declare_string_array(node, "overrides", "scenario overrides dotted.key=value")
    duration_s = declare_number(node, "duration_s", 0.0, "duration (s); 0 = the scenario's")
    if not path:
        if required:
            raise ParameterError("scenario", "is required (the path of a scenario YAML file)")
        return None
    if duration_s < 0:
        raise ParameterError("duration_s", f"must be >= 0, got {duration_s}")
    return load_scenario(path, overrides, duration_s if duration_s > 0 else None)


def declare_string_array(node: Node, name: str, description: str = "") -> list[str]:
    """Declare a string-array parameter (default empty) and return its value.

    A single string is accepted as a one-element list (``-p overrides:=rate_hz=100``).
    """
    value = _declare(node, name, [""], description, dynamic=True)
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise ParameterError(name, f"must be a list of strings, got {value!r}")
    return [v for v in value if v]


def qos_from_parameters(node: Node) -> QoSProfile:
    """Declare ``qos_reliability`` ('reliable' | 'best_effort') and ``qos_depth``; return the QoS.

    History KEEP_LAST(depth), durability VOLATILE.
    """
    reliability = declare_string(
        node, "qos_reliability", "reliable", "publisher reliability: reliable | best_effort"
    )
    if reliability not in RELIABILITY:
        raise ParameterError(
            "qos_reliability", f"must be one of: {', '.join(RELIABILITY)}; got {reliability!r}"
        )
    depth = declare_int(node, "qos_depth", 1000, "publisher history depth (KEEP_LAST)", minimum=1)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=RELIABILITY[reliability],
        durability=DurabilityPolicy.VOLATILE,
    )


_MSGTYPE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/msg/([A-Za-z][A-Za-z0-9_]*)$")


def message_class(msgtype: str) -> type:
    """The rclpy message class of ``'pkg/msg/Name'``, e.g. ``sensor_msgs.msg.Imu``."""
    match = _MSGTYPE.match(msgtype)
    if match is None:
        raise ValueError(f"not a message type name of the form pkg/msg/Name: {msgtype!r}")
    package, name = match.groups()
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {msgtype} is not available: {exc}") from exc


#: Default ``batch_period_s``: the longest a received message waits before it is processed.
BATCH_PERIOD_S = 0.01


def declare_batch_period(node: Node, default: float = BATCH_PERIOD_S) -> float:
    """Declare ``batch_period_s`` (latency against CPU) and return it."""
    value = declare_number(
        node,
        "batch_period_s",
        default,
        "longest wait (s) of a received message before it is processed while input keeps "
        "coming: messages are decoded, computed and serialized in batches (latency vs CPU)",
    )
    if not 0 < value <= 1:
        raise ParameterError("batch_period_s", f"must be > 0 and <= 1, got {value}")
    return value


class InputBatch:
    """Raw input messages buffered by subscription callbacks, processed in batches.

    A callback only calls :meth:`add`; the node's loop calls :meth:`spin` and processes
    :meth:`take` when :meth:`due`: when nothing arrived for ``quiet_s`` (the burst of one cycle
    is in, or the stream paused or ended: low latency at low rates) or the oldest message has
    waited ``period_s`` (messages keep coming: a kHz stream, or a backlog). Decoding, computing
    and serializing k messages with one set of numpy calls costs little more than one message,
    so a node keeps up with kHz streams on a fraction of a core (docs/benchmarks.md), and a
    node that falls behind takes larger batches by itself.
    """

    #: Default ``quiet_s`` (s): a 200 Hz stream's cycles are processed as they come.
    QUIET_S = 0.002

    def __init__(self, period_s: float, quiet_s: float = QUIET_S) -> None:
        self.period_s = period_s
        self.quiet_s = min(quiet_s, period_s)
        self.items: list[Any] = []
        self.received = 0
        self.last_input = time.monotonic()
        self._oldest = 0.0
        self._quiet = False

    def add(self, item: Any) -> None:
        """Buffer one message (called by subscription callbacks)."""
        now = time.monotonic()
        if not self.items:
            self._oldest = now
        self.items.append(item)
        self.received += 1
        self.last_input = now

    def spin(self, spin: Callable[[float], None]) -> None:
        """Spin the executor for at most ``quiet_s``; note whether anything arrived."""
        before = self.received
        spin(self.quiet_s)
        self._quiet = self.received == before

    def due(self) -> bool:
        """Messages wait and the input was quiet for ``quiet_s`` or the oldest waited
        ``period_s``."""
        if not self.items:
            return False
        return self._quiet or time.monotonic() - self._oldest >= self.period_s

    def take(self) -> list[Any]:
        """The buffered messages, oldest first; the buffer is emptied."""
        items, self.items = self.items, []
        return items


class Pacer:
    """Maps stamps to wall-clock deadlines: stamp ``t`` is due at ``start + (t - t0) / rate``.

    ``rate_factor <= 0`` means as fast as possible (everything is due at once). Waiting is done
    by a caller-supplied ``spin(timeout_s)`` (which keeps rclpy responsive) until the deadline is
    close, then by :func:`time.sleep` for the last stretch.
    """

    #: Below this many seconds before a deadline, stop spinning and sleep precisely.
    FINE_S = 0.002

    def __init__(self, rate_factor: float, t0_ns: int, start: float | None = None) -> None:
        self.rate_factor = rate_factor
        self.t0_ns = t0_ns
        self.start = time.monotonic() if start is None else start
        self.max_lateness_s = 0.0

    def due(self, stamp_ns: int) -> float:
        """Monotonic time at which ``stamp_ns`` is due."""
        if self.rate_factor <= 0:
            return self.start
        return self.start + (stamp_ns - self.t0_ns) * 1e-9 / self.rate_factor

    def wait(self, stamp_ns: int, spin) -> None:
        """Return when ``stamp_ns`` is due; record the lateness (paced mode only)."""
        if self.rate_factor <= 0:
            return
        deadline = self.due(stamp_ns)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= self.FINE_S:
                break
            spin(min(remaining - self.FINE_S, 0.1))
        while remaining > 0:
            time.sleep(remaining)
            remaining = deadline - time.monotonic()
        self.max_lateness_s = max(self.max_lateness_s, -remaining)


class SignalStop:
    """Mixin of nodes that finish their work on SIGINT/SIGTERM (the recorder, the player).

    After :meth:`take_stop_signals` a signal only sets ``_stop_reason`` (rclpy's handlers would
    shut the context down at once), so the node still drains its queues and closes its bag; a
    second signal sets ``drain_timeout_s`` to 0 (stop draining).
    """

    _stop_reason: str | None
    drain_timeout_s: float

    def take_stop_signals(self) -> None:
        """Replace rclpy's SIGINT/SIGTERM handlers by :meth:`_on_signal`."""
        from rclpy.signals import uninstall_signal_handlers

        uninstall_signal_handlers()
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)

    def _on_signal(self, signum: int, frame: object) -> None:
        if self._stop_reason is None:
            self._stop_reason = signal.Signals(signum).name
        else:  # a second signal: stop draining
            self.drain_timeout_s = 0.0


#: Executors a node can run on (parameter ``executor``).
EXECUTORS = ("events", "single_threaded")


def make_executor(node: Node, kind: str) -> Executor:
    """A new executor of ``kind`` ('events' | 'single_threaded') holding ``node``.

    ``events`` is rclpy's ``EventsExecutor`` (C++ event queue, no wait-set rebuild per
    callback). Switching the five pipeline nodes to it lowered their CPU by 0.15–0.3 ms per
    received message (1 kHz, 2 cores; docs/benchmarks.md), which is what lets the pipeline run
    1 kHz in real time. Nodes only ever call ``spin_once`` on it (its ``spin()`` has been seen
    to hang at shutdown). Where rclpy has no EventsExecutor (older releases), the
    SingleThreadedExecutor is used.
    """
    if kind not in EXECUTORS:
        raise ParameterError("executor", f"must be one of: {', '.join(EXECUTORS)}; got {kind!r}")
    executor: Executor | None = None
    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:  # pragma: no cover - rclpy before Jazzy
            node.get_logger().warning("rclpy has no EventsExecutor; using SingleThreadedExecutor")
        else:
            executor = EventsExecutor(context=node.context)
    if executor is None:
        executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    return executor


def _interrupted_summary(node: Any, logger: Any) -> None:
    """Log the end-of-run summary of a node stopped by a signal (if it has one to give)."""
    summary = getattr(node, "interrupted_summary", None)
    if summary is None:
        return
    try:
        text = summary()
    except Exception:  # noqa: S110 - the summary is a courtesy; never fail the shutdown
        return
    if text:
        logger.info(text)


def run_node(node_factory: Callable[[], Any], name: str, args: list[str] | None = None) -> int:
    """Entry point shared by the nodes: init, build, ``node.run(executor)``, clean shutdown.

    The executor is chosen by the node parameter ``executor`` (:func:`make_executor`; default
    ``events``). Exit status: 0 done or stopped by SIGINT/SIGTERM, 1 failure while running, 2
    invalid parameter or scenario (the message names it).
    """
    from strapdown_ros.config import ScenarioError

    try:
        rclpy.init(args=args)
    except Exception as exc:  # rcl's RCLError: e.g. an unparsable --ros-args rule
        import sys

        print(f"{name}: invalid command-line arguments: {exc}", file=sys.stderr)
        return EXIT_INVALID
    logger = rclpy.logging.get_logger(name)
    node = None
    executor: Executor | None = None
    try:
        node = node_factory()
        kind = declare_string(
            node, "executor", "events", "rclpy executor: events | single_threaded"
        )
        executor = make_executor(node, kind)
        return node.run(executor)
    except ParameterError as exc:
        logger.error(f"invalid parameter: {exc}")
        return EXIT_INVALID
    except ScenarioError as exc:
        logger.error(f"invalid scenario: {exc}")
        return EXIT_INVALID
    except (KeyboardInterrupt, ExternalShutdownException):
        _interrupted_summary(node, logger)
        return EXIT_OK
    except Exception as exc:
        if not rclpy.ok():  # a signal shut the context down under a publish or a wait
            _interrupted_summary(node, logger)
            return EXIT_OK
        logger.error(f"failed: {exc}\n{traceback.format_exc()}")
        return EXIT_FAILURE
    finally:
        # A second SIGINT/SIGTERM during the clean-up must not end in a traceback.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if executor is not None and node is not None:
            executor.remove_node(node)
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


@dataclass(frozen=True)
class RunControl:
    """When a downstream node starts (subscriptions to wait for) and when it stops."""

    exit_when_done: bool
    idle_timeout_s: float
    wait_for_subscribers: int
    wait_timeout_s: float
    subscribers_per_topic: dict[str, int]


def declare_run_control(node: Node, done: str) -> RunControl:
    """Declare ``exit_when_done``, ``idle_timeout_s``, ``wait_for_subscribers``,
    ``wait_timeout_s`` and ``subscribers_per_topic`` (the nodes that process an input stream).

    ``done`` says what "done" is for the node (e.g. "the last output"), for the description.
    """
    exit_when_done = declare_bool(
        node, "exit_when_done", True, f"exit after {done} or idle_timeout_s"
    )
    idle_timeout_s = declare_number(
        node, "idle_timeout_s", 5.0, "with exit_when_done: exit after this long without input"
    )
    if idle_timeout_s <= 0:
        raise ParameterError("idle_timeout_s", f"must be > 0, got {idle_timeout_s}")
    wait_for_subscribers = declare_int(
        node, "wait_for_subscribers", 0, "output subscriptions to wait for before subscribing", 0
    )
    wait_timeout_s = declare_number(node, "wait_timeout_s", 10.0, "seconds to wait")
    return RunControl(
        exit_when_done,
        idle_timeout_s,
        wait_for_subscribers,
        wait_timeout_s,
        declare_subscriber_counts(node),
    )


def drain_publishers(
    node: Node, pubs: list[Any], spin: Callable[[float], None], timeout_s: float, grace_s: float
) -> None:
    """Let RELIABLE subscribers acknowledge everything (at most ``timeout_s``, a warning names
    the topics that did not), then spin ``grace_s`` more."""
    deadline = time.monotonic() + timeout_s
    for pub in pubs:
        while rclpy.ok(context=node.context):
            if pub.wait_for_all_acked(Duration(nanoseconds=50_000_000)):
                break
            if time.monotonic() > deadline:
                node.get_logger().warning(
                    f"{pub.topic_name}: messages not acknowledged within {timeout_s:g} s"
                )
                break
    end = time.monotonic() + grace_s
    while time.monotonic() < end and rclpy.ok(context=node.context):
        spin(max(end - time.monotonic(), 0.0))


def declare_subscriber_counts(node: Node) -> dict[str, int]:
    """Declare ``subscribers_per_topic`` (``TOPIC=COUNT`` strings) and return it as a dict.

    Used by orchestrators (``strapdown-sim run``) that know how many subscriptions each output
    topic will have (e.g. a recorder and a downstream node on ``/variation/imu``).
    """
    out: dict[str, int] = {}
    for item in declare_string_array(
        node, "subscribers_per_topic", "TOPIC=COUNT: subscriptions to wait for on that topic"
    ):
        topic, sep, count = item.rpartition("=")
        if not sep or not topic.startswith("/") or not count.isdigit():
            raise ParameterError(
                "subscribers_per_topic", f"items must be /topic=COUNT, got {item!r}"
            )
        out[topic] = int(count)
    return out


def wait_for_subscriptions(
    node: Node,
    pubs: list[Any],
    wanted: int,
    timeout_s: float,
    spin: Callable[[float], None],
    per_topic: dict[str, int] | None = None,
) -> bool:
    """Spin until every publisher in ``pubs`` has ``wanted`` matched subscriptions.

    ``per_topic`` overrides ``wanted`` for the publishers of the named topics. Returns False
    (after logging which topics are short) when ``timeout_s`` passes first.
    """
    per_topic = per_topic or {}

    def want(p: Any) -> int:
        return per_topic.get(p.topic_name, wanted)

    deadline = time.monotonic() + timeout_s
    while True:
        missing = [p for p in pubs if p.get_subscription_count() < want(p)]
        if not missing:
            waited = time.monotonic() - deadline + timeout_s
            node.get_logger().info(f"subscriptions matched after {waited:.3f} s")
            return True
        if time.monotonic() > deadline:
            node.get_logger().error(
                f"timeout after {timeout_s:g} s waiting for subscriptions on "
                + ", ".join(
                    f"{p.topic_name} (has {p.get_subscription_count()}, wants {want(p)})"
                    for p in missing
                )
            )
            return False
        spin(0.02)
