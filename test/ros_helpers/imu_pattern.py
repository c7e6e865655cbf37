"""Deterministic ``sensor_msgs/Imu`` contents shared by the smoke-test publisher and subscriber.

Message ``i`` carries awkward float64 values (irrational-looking numbers, a subnormal, the
largest double, a negative zero, ...) so that the subscriber can check that every field
crossed DDS bit for bit.  Values are compared through ``float.hex``.
"""

from __future__ import annotations

import math

FRAME_ID = "smoke_imu"
_SPECIAL = (5e-324, -1.7976931348623157e308, -0.0, 1e-300, math.pi, -math.e, 2.0**-52, 0.1)


def expected_fields(i: int) -> dict:
    """Return the field values of message ``i`` (plain Python types)."""
    x = i + 1
    return {
        "stamp_sec": 1_700_000_000 + i,
        "stamp_nanosec": (i * 123_456_789) % 1_000_000_000,
        "frame_id": f"{FRAME_ID}_{i}",
        "orientation": (
            math.sin(x) / math.sqrt(2.0),
            math.cos(x) / math.sqrt(2.0),
            -math.sin(x) / math.sqrt(2.0),
            math.cos(x) / math.sqrt(2.0),
        ),
        "orientation_covariance": tuple(_SPECIAL[(i + k) % len(_SPECIAL)] for k in range(9)),
        "angular_velocity": (1.0 / (3.0 * x), -math.sqrt(x) * 1e-7, math.exp(-x)),
        "angular_velocity_covariance": tuple(float(k * x) / 7.0 for k in range(9)),
        "linear_acceleration": (9.80665 + x * 1e-9, -1.0 / x, math.log1p(x) * 1e3),
        "linear_acceleration_covariance": tuple(-float(k) * 1e-12 / x for k in range(9)),
    }


def make_imu(i: int):
    """Return the ``sensor_msgs.msg.Imu`` number ``i``."""
    from sensor_msgs.msg import Imu

    f = expected_fields(i)
    msg = Imu()
    msg.header.stamp.sec = f["stamp_sec"]
    msg.header.stamp.nanosec = f["stamp_nanosec"]
    msg.header.frame_id = f["frame_id"]
    o = msg.orientation
    o.x, o.y, o.z, o.w = f["orientation"]
    msg.orientation_covariance = list(f["orientation_covariance"])
    w = msg.angular_velocity
    w.x, w.y, w.z = f["angular_velocity"]
    msg.angular_velocity_covariance = list(f["angular_velocity_covariance"])
    a = msg.linear_acceleration
    a.x, a.y, a.z = f["linear_acceleration"]
    msg.linear_acceleration_covariance = list(f["linear_acceleration_covariance"])
    return msg


def fields_of(msg) -> dict:
    """Return the field values of a received ``Imu`` message, in the form of expected_fields."""
    o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return {
        "stamp_sec": msg.header.stamp.sec,
        "stamp_nanosec": msg.header.stamp.nanosec,
        "frame_id": msg.header.frame_id,
        "orientation": (o.x, o.y, o.z, o.w),
        "orientation_covariance": tuple(float(v) for v in msg.orientation_covariance),
        "angular_velocity": (w.x, w.y, w.z),
        "angular_velocity_covariance": tuple(float(v) for v in msg.angular_velocity_covariance),
        "linear_acceleration": (a.x, a.y, a.z),
        "linear_acceleration_covariance": tuple(
            float(v) for v in msg.linear_acceleration_covariance
        ),
    }


def _exact(value):
    if isinstance(value, float):
        return value.hex()
    if isinstance(value, tuple):
        return tuple(_exact(v) for v in value)
    return value


def differences(got: dict, want: dict) -> list[str]:
    """Return a description of every field of ``got`` not bit-identical to ``want``."""
    return [
        f"{key}: got {got.get(key)!r}, expected {want[key]!r}"
        for key in want
        if _exact(got.get(key)) != _exact(want[key])
    ]
