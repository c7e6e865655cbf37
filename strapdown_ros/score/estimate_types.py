"""The message types a navigation estimate may have, without imports: read by
:mod:`~strapdown_ros.score.estimate`, checked by the live scorer (:mod:`~strapdown_ros.score.live`)
and its launch logic (:mod:`~strapdown_ros.score.live_launch`, standard library only)."""

from __future__ import annotations

__all__ = ["ESTIMATE_TYPES"]

ESTIMATE_TYPES = (
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "sensor_msgs/msg/NavSatFix",
)
