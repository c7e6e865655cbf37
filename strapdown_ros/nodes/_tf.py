"""TF and map-frame outputs of the nodes (docs/interface.md, "Frames and TF").

Each node that publishes Odometry or Imu also publishes what :class:`~strapdown_ros.stages.
frames.TFStage` derives from it: ``trajectory_node`` ``/tf_static`` (transient local) and
``map → base_link``, ``variation_node`` ``base_link → variation_imu``, ``navigator_node``
``map → <navigator frame>``, and each its map-frame Odometry (and Δv/Δq topics when
``recording.increments`` is true). Live TF needs the ``tf2_msgs`` Python bindings, which ROS 2's
PyPI wheels lack (``make setup`` builds them, ``tools/build_tf2_msgs.py``); without them the node
says once why TF is off and publishes the rest.
"""

from __future__ import annotations

from collections.abc import Iterable

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from strapdown_ros.bag import cdr
from strapdown_ros.nodes.message_types import message_class
from strapdown_ros.plan.model import Plan
from strapdown_ros.stages.tf import node_derived_topics

__all__ = ["TF_OFF_REASON", "derived_outputs", "static_qos", "tf_unavailable"]

#: Why live TF is off when tf2_msgs does not import (logged once per node).
TF_OFF_REASON = (
    "live TF is off: tf2_msgs/msg/TFMessage is not importable here ({error}). The ROS 2 "
    "PyPI wheels do not ship tf2_msgs; `make setup` builds it with tools/build_tf2_msgs.py "
    "when cmake and a C compiler are present (log: .venv/tf2_build/build.log). /tf and "
    "/tf_static are not published; every other topic is."
)


def tf_unavailable() -> str | None:
    """None when ``tf2_msgs/msg/TFMessage`` imports, else the reason."""
    try:
        message_class(cdr.TF_MESSAGE)
    except ValueError as exc:
        return str(exc)
    return None


def derived_outputs(
    node: Node, plan: Plan, outputs: Iterable[str], *, static: bool = False
) -> dict[str, str]:
    """The derived topics (name → type) a node publishes beside its ``outputs``
    (:func:`~strapdown_ros.stages.tf.node_derived_topics`). Without tf2_msgs the TF topics
    are left out and the node logs why, once."""
    topics = node_derived_topics(plan, outputs, static=static)
    if any(m == cdr.TF_MESSAGE for m in topics.values()):
        error = tf_unavailable()
        if error is not None:
            node.get_logger().warning(TF_OFF_REASON.format(error=error))
            topics = {t: m for t, m in topics.items() if m != cdr.TF_MESSAGE}
    return topics


def static_qos(qos: QoSProfile) -> QoSProfile:
    """``qos`` made transient local with depth 1: a latched ``/tf_static`` publisher."""
    return QoSProfile(
        history=qos.history,
        depth=1,
        reliability=qos.reliability,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
