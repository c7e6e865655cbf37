"""The Odometry, NavSatFix and Imu fields of one stream at once (the truth computed once)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import ImuFields, NavSatFixFields, OdometryFields
from strapdown_ros.messages.frames import DEFAULT_BODY_FRAME, EARTH_FRAME
from strapdown_ros.messages.imu import imu_fields
from strapdown_ros.messages.navsatfix import navsatfix_fields
from strapdown_ros.messages.odometry import odometry_fields
from strapdown_ros.messages.truth import StreamTruth

__all__ = ["StreamFields", "stream_fields"]


class StreamFields(NamedTuple):
    """Odometry, NavSatFix and Imu fields of one stream (None where not requested)."""

    odometry: OdometryFields | None
    navsatfix: NavSatFixFields | None
    imu: ImuFields | None


def stream_fields(
    stream: Stream,
    body_frame: str = DEFAULT_BODY_FRAME,
    earth_frame: str = EARTH_FRAME,
    *,
    odometry: bool = True,
    navsatfix: bool = True,
    imu: bool = True,
    imu_kwargs: Mapping[str, object] | None = None,
) -> StreamFields:
    """The :func:`odometry_fields`, :func:`navsatfix_fields` and :func:`imu_fields` of a stream.

    Equal, bit for bit, to the three calls with default covariances (``imu_kwargs`` are passed
    to :func:`imu_fields`), but the E0 → E conversion and the geodetic conversion are computed
    once for all three (one :class:`~strapdown_ros.messages.truth.StreamTruth`).
    """
    truth = StreamTruth(stream)
    kw: dict[str, Any] = dict(imu_kwargs or {})
    return StreamFields(
        odometry_fields(stream, body_frame, earth_frame, truth=truth) if odometry else None,
        navsatfix_fields(stream, body_frame, truth=truth) if navsatfix else None,
        imu_fields(stream, body_frame, truth=truth, **kw) if imu else None,
    )
