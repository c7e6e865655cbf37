"""QoS profiles of the nodes' publishers and subscriptions."""

from __future__ import annotations

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from strapdown_ros.nodes.parameters import ParameterError, declare_int, declare_string

__all__ = ["RELIABILITY", "describe_qos", "qos_from_parameters", "qos_profile"]

RELIABILITY = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}


def qos_profile(
    depth: int, *, reliable: bool = True, transient_local: bool = False, keep_all: bool = False
) -> QoSProfile:
    """KEEP_LAST(``depth``) (KEEP_ALL with ``keep_all``), RELIABLE or BEST_EFFORT, VOLATILE or
    TRANSIENT_LOCAL."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=(
            DurabilityPolicy.TRANSIENT_LOCAL if transient_local else DurabilityPolicy.VOLATILE
        ),
    )


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
    return qos_profile(depth, reliable=reliability == "reliable")


def describe_qos(q: QoSProfile) -> str:
    """``RELIABLE, VOLATILE, KEEP_LAST(10)``-style summary of a profile (for the logs)."""
    history = "KEEP_ALL" if q.history == HistoryPolicy.KEEP_ALL else f"KEEP_LAST({q.depth})"
    return f"{q.reliability.name}, {q.durability.name}, {history}"
