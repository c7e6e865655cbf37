"""rclpy message classes of ROS type names (``pkg/msg/Name``)."""

from __future__ import annotations

import importlib
import re

__all__ = ["message_class"]

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
