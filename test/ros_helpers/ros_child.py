"""What the DDS helper scripts of this directory share: a RELIABLE QoS, the node's life,
waiting for matched endpoints and for acknowledgements, message classes by type name.

rclpy is imported inside the functions: a helper parses its arguments before it loads ROS.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any


def reliable_qos(depth: int) -> Any:
    """KEEP_LAST(``depth``), RELIABLE, VOLATILE."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def message_type(msgtype: str) -> type:
    """The rclpy message class of ``pkg/msg/Name``."""
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


TEARDOWN_S = 5.0


@contextlib.contextmanager
def ros_node(name: str) -> Iterator[Any]:
    """rclpy initialized and a node ``name``; both shut down at the end, for at most
    ``TEARDOWN_S`` s.

    The helper's result is printed before the teardown; a DDS teardown that hangs (seen in CI
    on a loaded machine after every message was acknowledged) must not fail the test, so it
    runs in a daemon thread and is abandoned after ``TEARDOWN_S``. Run the helper with
    :func:`exit_with` so that the abandoned thread cannot hold the process either.
    """
    import rclpy

    rclpy.init()
    node = rclpy.create_node(name)
    try:
        yield node
    finally:

        def teardown() -> None:
            node.destroy_node()
            rclpy.try_shutdown()

        thread = threading.Thread(target=teardown, daemon=True)
        thread.start()
        thread.join(timeout=TEARDOWN_S)


def exit_with(main: Callable[[], int]) -> None:
    """Run ``main`` and leave the process with its code at once (``os._exit``: no wait for a
    DDS thread that did not shut down)."""
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def wait_matched(
    node: Any,
    deadline: float,
    pubs: Sequence[Any] = (),
    subs: Sequence[Any] = (),
    count: int = 1,
    what: str = "subscriptions",
    step_s: float = 0.02,
) -> bool:
    """Spin until every publisher has ``count`` matched subscriptions and every subscription a
    publisher; at ``deadline`` print ``TIMEOUT waiting for <what>`` and return False."""
    import rclpy

    while any(p.get_subscription_count() < count for p in pubs) or any(
        s.get_publisher_count() < 1 for s in subs
    ):
        if time.monotonic() > deadline:
            print(f"TIMEOUT waiting for {what}", flush=True)
            return False
        rclpy.spin_once(node, timeout_sec=step_s)
    return True


def wait_acked(pubs: Sequence[Any], deadline: float) -> bool:
    """Every message of ``pubs`` acknowledged before ``deadline`` (else print ``TIMEOUT waiting
    for acknowledgements`` and return False)."""
    from rclpy.duration import Duration

    for pub in pubs:
        remaining = max(deadline - time.monotonic(), 0.1)
        if not pub.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9))):
            print("TIMEOUT waiting for acknowledgements", flush=True)
            return False
    return True
