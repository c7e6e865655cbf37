"""A node's life: ``main`` (init, build, run, clean shutdown), its executor, when it stops, and
the drain of its publishers at the end.

Exit statuses are those of ``strapdown-sim``: 0 done (or stopped by SIGINT/SIGTERM/SIGHUP), 1
failure while running, 2 invalid parameter or scenario.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from strapdown_ros.nodes.handshake import declare_subscriber_counts
from strapdown_ros.nodes.parameters import (
    ParameterError,
    declare_bool,
    declare_int,
    declare_number,
    declare_string,
)
from strapdown_ros.nodes.signals import STOP_SIGNALS, hangup_as_terminate
from strapdown_ros.nodes.usage import front

__all__ = [
    "EXECUTORS",
    "EXIT_FAILURE",
    "EXIT_INVALID",
    "EXIT_OK",
    "RunControl",
    "declare_run_control",
    "drain_publishers",
    "make_executor",
    "run_node",
]

#: Exit statuses of the nodes (those of ``strapdown-sim``).
EXIT_OK, EXIT_FAILURE, EXIT_INVALID = 0, 1, 2

#: Seconds the teardown after ``run`` (executor, node, rclpy) may take before the process
#: leaves without it, with the status it had.
TEARDOWN_TIMEOUT_S = 15.0

#: Executors a node can run on (parameter ``executor``).
EXECUTORS = ("events", "single_threaded")


def make_executor(node: Node, kind: str) -> Executor:
    """A new executor of ``kind`` ('events' | 'single_threaded') holding ``node``.

    ``events`` is rclpy's ``EventsExecutor`` (C++ event queue, no wait-set rebuild per
    callback), what lets the pipeline run 1 kHz in real time (docs/benchmarks.md). Nodes only
    ever call ``spin_once`` on it (its ``spin()`` has been seen to hang at shutdown). Where
    rclpy has no EventsExecutor (older releases), the SingleThreadedExecutor is used.
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


def _teardown(node: Any, executor: Executor | None) -> None:
    """Remove the node from its executor, destroy it, shut rclpy down."""
    if executor is not None and node is not None:
        executor.remove_node(node)
        executor.shutdown()
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()


def _shut_down(node: Any, executor: Executor | None, timeout_s: float) -> bool:
    """:func:`_teardown` in a daemon thread, for at most ``timeout_s`` (signals ignored).

    Returns False when it did not finish in time: a DDS teardown has been seen to hang on a
    loaded machine after every message was delivered; the caller then leaves the process.
    """
    # A second SIGINT/SIGTERM/SIGHUP during the clean-up must not end in a traceback.
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    thread = threading.Thread(target=_teardown, args=(node, executor), daemon=True)
    thread.start()
    thread.join(timeout_s)
    return not thread.is_alive()


def _leave(name: str, status: int, timeout_s: float) -> None:
    """End the process now with ``status`` (``os._exit``), saying that the teardown hung."""
    print(
        f"{name}: shutdown did not finish within {timeout_s:g} s; exiting with status {status}",
        file=sys.stderr,
    )
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def run_node(node_factory: Callable[[], Any], name: str, args: list[str] | None = None) -> int:
    """Entry point shared by the nodes: ``--help``, bad arguments and the library versions
    (:func:`~strapdown_ros.nodes.usage.front`, before rclpy starts), then init, build,
    ``node.run(executor)``, clean shutdown.

    The executor is chosen by the node parameter ``executor`` (:func:`make_executor`; default
    ``events``). Exit status: 0 done or stopped by SIGINT/SIGTERM/SIGHUP, 1 failure while
    running, 2 invalid parameter or scenario (the message names it). A teardown that does not
    finish within :data:`TEARDOWN_TIMEOUT_S` ends the process with that status.
    """
    from strapdown_ros.config import ScenarioError

    front(name, args)
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rcl's RCLError: e.g. an unparsable --ros-args rule
        print(f"{name}: invalid command-line arguments: {exc}", file=sys.stderr)
        return EXIT_INVALID
    hangup_as_terminate()  # rclpy handles SIGINT and SIGTERM; SIGHUP the same way
    logger = rclpy.logging.get_logger(name)
    node = None
    executor: Executor | None = None
    status = EXIT_FAILURE
    try:
        node = node_factory()
        kind = declare_string(
            node, "executor", "events", "rclpy executor: events | single_threaded"
        )
        executor = make_executor(node, kind)
        status = node.run(executor)
    except ParameterError as exc:
        logger.error(f"invalid parameter: {exc}")
        status = EXIT_INVALID
    except ScenarioError as exc:
        logger.error(f"invalid scenario: {exc}")
        status = EXIT_INVALID
    except (KeyboardInterrupt, ExternalShutdownException):
        _interrupted_summary(node, logger)
        status = EXIT_OK
    except Exception as exc:
        if not rclpy.ok():  # a signal shut the context down under a publish or a wait
            _interrupted_summary(node, logger)
            status = EXIT_OK
        else:
            logger.error(f"failed: {exc}\n{traceback.format_exc()}")
            status = EXIT_FAILURE
    except BaseException:  # SystemExit and the like: clean up, then let it through
        _shut_down(node, executor, TEARDOWN_TIMEOUT_S)
        raise
    if not _shut_down(node, executor, TEARDOWN_TIMEOUT_S):
        _leave(name, status, TEARDOWN_TIMEOUT_S)
    return status


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
    node: Node,
    pubs: Sequence[Any],
    spin: Callable[[float], None],
    timeout_s: float,
    grace_s: float,
    running: Callable[[], bool] | None = None,
) -> float | None:
    """Let RELIABLE subscribers acknowledge everything, then spin ``grace_s`` more.

    At most ``timeout_s`` in all; a warning names each topic not acknowledged in time. Waits in
    50 ms steps while ``running()`` (default: the node's context is ok), so a signal ends the
    drain. Returns the seconds until every publisher's messages were acknowledged (None: they
    were not).
    """
    if running is None:

        def running() -> bool:
            return rclpy.ok(context=node.context)

    start = time.monotonic()
    deadline = start + timeout_s
    acked = True
    for pub in pubs:
        while True:
            if not running():
                acked = False
                break
            if pub.wait_for_all_acked(Duration(nanoseconds=50_000_000)):
                break
            if time.monotonic() > deadline:
                node.get_logger().warning(
                    f"{pub.topic_name}: messages not acknowledged within {timeout_s:g} s"
                )
                acked = False
                break
    waited = time.monotonic() - start
    end = time.monotonic() + grace_s
    while time.monotonic() < end and running():
        spin(max(end - time.monotonic(), 0.0))
    return waited if acked else None
