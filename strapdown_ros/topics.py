"""The message type of each ``recording.topics`` key (docs/interface.md §4), the default
topic list and the topic column of the command summaries; what a scenario produces is its
plan's (:mod:`strapdown_ros.plan`). No rclpy here.
"""

from __future__ import annotations

from collections.abc import Mapping

from strapdown_ros.config import DEFAULT_TOPICS

__all__ = ["MSGTYPES", "spec_topics", "topic_lines"]

IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
CLOCK = "rosgraph_msgs/msg/Clock"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"

#: Message type of every ``recording.topics`` key (docs/interface.md §4).
MSGTYPES: dict[str, str] = {
    "clock": CLOCK,
    "reference_odom": ODOMETRY,
    "reference_fix": NAVSATFIX,
    "reference_imu": IMU,
    "variation_odom": ODOMETRY,
    "variation_fix": NAVSATFIX,
    "variation_imu": IMU,
    "variation_reference_odom": ODOMETRY,
    "variation_reference_imu": IMU,
    "variation_imu_measured": IMU,
    "navigator_odom": ODOMETRY,
    "navigator_fix": NAVSATFIX,
    "navigator_error_position": VECTOR3_STAMPED,
    "navigator_error_velocity": VECTOR3_STAMPED,
    "navigator_error_attitude": VECTOR3_STAMPED,
}

def spec_topics() -> dict[str, str]:
    """Every default topic of docs/interface.md §4 -> its message type (``/clock`` first)."""
    return {DEFAULT_TOPICS[key]: msgtype for key, msgtype in MSGTYPES.items()}


def topic_lines(cells: Mapping[str, str]) -> list[str]:
    """One summary line per topic, ``  <topic>  <cell>``, the topic names in one column."""
    width = max((len(t) for t in cells), default=0)
    return [f"  {topic:<{width}}  {cell}" for topic, cell in cells.items()]
