"""The start-up handshake: wait until every output topic has its subscriptions.

An orchestrator (``strapdown-sim run``) knows how many subscriptions each topic will have (the
recorder and the downstream nodes) and passes them as ``subscribers_per_topic``; a node waits
for them before it subscribes to its input or publishes, so nothing is sent before everyone
who should receive it listens.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node

from strapdown_ros.nodes.parameters import ParameterError, declare_string_array

__all__ = ["declare_subscriber_counts", "describe_wanted", "wait_for_subscriptions"]


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


def describe_wanted(wanted: dict[str, int]) -> str:
    """``2 subscription(s) on /a; 1 on /b, /c`` of topic → count (topics wanting 0 left out)."""
    by_count: dict[int, list[str]] = {}
    for topic, n in wanted.items():
        if n > 0:
            by_count.setdefault(n, []).append(topic)
    if not by_count:
        return "no subscription"
    groups = sorted(by_count.items(), reverse=True)
    return "; ".join(
        f"{n}{' subscription(s)' if i == 0 else ''} on {', '.join(topics)}"
        for i, (n, topics) in enumerate(groups)
    )


def wait_for_subscriptions(
    node: Node,
    pubs: Sequence[Any],
    wanted: int,
    timeout_s: float,
    spin: Callable[[float], None],
    per_topic: dict[str, int] | None = None,
) -> bool:
    """Spin until every publisher in ``pubs`` has ``wanted`` matched subscriptions.

    ``per_topic`` overrides ``wanted`` for the publishers of the named topics. Logs what it
    waits for; returns False (after logging which topics are short) when ``timeout_s`` passes
    first.
    """
    per_topic = per_topic or {}

    def want(p: Any) -> int:
        return per_topic.get(p.topic_name, wanted)

    node.get_logger().info(
        f"waiting for {describe_wanted({p.topic_name: want(p) for p in pubs})} "
        f"(timeout {timeout_s:g} s)"
    )
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
