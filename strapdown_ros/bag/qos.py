"""QoS profiles as rosbag2 stores them (``offered_qos_profiles`` of a topic's metadata).

ROS-free: a publisher's profile from the ROS graph is read through its attributes (rclpy's
``QoSProfile``: enum values and ``Duration`` s), so the bag code needs no rclpy.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

__all__ = ["DEFAULT_QOS", "offered_profiles", "offered_qos"]

_NS = 1_000_000_000
#: rmw "infinite" duration as rosbag2 stores it.
_INFINITE = QosTime(sec=9223372036, nsec=854775807)
#: Offered QoS stored per topic: what ``ros2 bag record`` (Jazzy) stores for a default rclpy/rclcpp
#: publisher (reliable, volatile; history/depth are not visible through the graph → unknown/0).
#: ``ros2 bag play`` adapts reliability and durability from it.
DEFAULT_QOS = Qos(
    history=QosHistory.UNKNOWN,
    depth=0,
    reliability=QosReliability.RELIABLE,
    durability=QosDurability.VOLATILE,
    deadline=_INFINITE,
    lifespan=_INFINITE,
    liveliness=QosLiveliness.AUTOMATIC,
    liveliness_lease_duration=_INFINITE,
    avoid_ros_namespace_conventions=False,
)


def _qos_time(d: Any) -> QosTime:
    ns = int(d.nanoseconds)
    return QosTime(sec=ns // _NS, nsec=ns % _NS)


def offered_qos(q: Any) -> Qos:
    """A publisher's QoS as seen in the ROS graph (an rclpy ``QoSProfile``), as rosbag2 stores
    it."""
    return Qos(
        history=QosHistory(int(q.history)),
        depth=int(q.depth),
        reliability=QosReliability(int(q.reliability)),
        durability=QosDurability(int(q.durability)),
        deadline=_qos_time(q.deadline),
        lifespan=_qos_time(q.lifespan),
        liveliness=QosLiveliness(int(q.liveliness)),
        liveliness_lease_duration=_qos_time(q.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(q.avoid_ros_namespace_conventions),
    )


def offered_profiles(publishers: Iterable[Any]) -> list[Qos]:
    """The distinct offered profiles of publishers (graph infos with ``qos_profile``), in
    order."""
    out: list[Qos] = []
    for info in publishers:
        q = offered_qos(info.qos_profile)
        if q not in out:
            out.append(q)
    return out
