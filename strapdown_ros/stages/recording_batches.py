"""A stream's serialized Imu, Odometry and NavSatFix batches on the recording's topics and
frames (``recording.topics`` ``<name>_imu`` ...): the reference's and the variation's."""

from __future__ import annotations

from strapdown_ros.bag.batches import Batch, stream_batches
from strapdown_ros.config import Scenario
from strapdown_ros.core.stream import Stream


def named_stream_batches(
    scenario: Scenario, stream: Stream, name: str, body_frame: str, fix: bool = True
) -> list[Batch]:
    """Serialized batches of ``stream`` on the recording topics ``<name>_imu``, ``<name>_odom``
    (and ``<name>_fix``), in the recording frame ``body_frame`` and the Earth frame."""
    rec = scenario.recording
    return stream_batches(
        stream,
        imu_topic=rec.topics[f"{name}_imu"],
        odom_topic=rec.topics[f"{name}_odom"],
        fix_topic=rec.topics[f"{name}_fix"] if fix else None,
        body_frame=rec.frames[body_frame],
        earth_frame=rec.frames["earth"],
    )
