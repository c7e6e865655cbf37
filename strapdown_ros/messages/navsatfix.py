"""``sensor_msgs/NavSatFix`` fields of geodetic positions (docs/interface.md §4).

Geodetic latitude/longitude (deg) and ellipsoidal altitude (m) of ``r^E(t_m)``; ``STATUS_FIX``
/ ``SERVICE_GPS``; ideal streams: zero covariance, ``COVARIANCE_TYPE_UNKNOWN``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import NavSatFixFields, as_column, as_stamps, covariance_rows
from strapdown_ros.messages.frames import DEFAULT_BODY_FRAME
from strapdown_ros.messages.truth import StreamTruth

__all__ = [
    "COVARIANCE_TYPE_APPROXIMATED",
    "COVARIANCE_TYPE_DIAGONAL_KNOWN",
    "COVARIANCE_TYPE_KNOWN",
    "COVARIANCE_TYPE_UNKNOWN",
    "SERVICE_GPS",
    "SERVICE_UNKNOWN",
    "STATUS_FIX",
    "STATUS_NO_FIX",
    "navsatfix_fields",
    "navsatfix_fields_from_geodetic",
]

# sensor_msgs/NavSatStatus and NavSatFix constants (values of the message definitions).
STATUS_FIX = 0
SERVICE_GPS = 1
#: An inertial-only position (the navigator's): not a GNSS fix (docs/interface.md §4).
STATUS_NO_FIX = -1
SERVICE_UNKNOWN = 0
COVARIANCE_TYPE_UNKNOWN = 0
COVARIANCE_TYPE_APPROXIMATED = 1
COVARIANCE_TYPE_DIAGONAL_KNOWN = 2
COVARIANCE_TYPE_KNOWN = 3


def navsatfix_fields_from_geodetic(
    stamps_ns: ArrayLike,
    lat: ArrayLike,
    lon: ArrayLike,
    alt: ArrayLike,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    position_covariance: ArrayLike | None = None,
    position_covariance_type: int | None = None,
    status: ArrayLike = STATUS_FIX,
    service: ArrayLike = SERVICE_GPS,
) -> NavSatFixFields:
    """NavSatFix fields of geodetic positions (``lat``, ``lon`` in rad, ``alt`` ellipsoidal, m).

    ``position_covariance`` None → zeros and ``COVARIANCE_TYPE_UNKNOWN``; otherwise (9,), (3, 3),
    (N, 9) or (N, 3, 3) m² in ENU with type ``position_covariance_type`` (default KNOWN).
    """
    t = as_stamps(stamps_ns)
    n = t.shape[0]
    cov = covariance_rows(position_covariance, n, 3, "position_covariance")
    ctype = position_covariance_type
    if ctype is None:
        ctype = COVARIANCE_TYPE_UNKNOWN if position_covariance is None else COVARIANCE_TYPE_KNOWN
    return NavSatFixFields(
        stamps_ns=t,
        frame_id=frame_id,
        status=as_column(status, n, np.int8, "status"),
        service=as_column(service, n, np.uint16, "service"),
        latitude=np.degrees(as_column(lat, n, np.float64, "lat")),
        longitude=np.degrees(as_column(lon, n, np.float64, "lon")),
        altitude=as_column(alt, n, np.float64, "alt"),
        position_covariance=cov,
        position_covariance_type=as_column(ctype, n, np.uint8, "position_covariance_type"),
    )


def navsatfix_fields(
    stream: Stream,
    frame_id: str = DEFAULT_BODY_FRAME,
    *,
    position_covariance: ArrayLike | None = None,
    position_covariance_type: int | None = None,
    truth: StreamTruth | None = None,
) -> NavSatFixFields:
    """NavSatFix (truth) fields of a stream, m = 0..M: geodetic position of ``r^E(t_m)``.

    ``truth`` as in :func:`~strapdown_ros.messages.imu.imu_fields`.
    """
    lat, lon, alt = (truth if truth is not None else StreamTruth(stream)).geodetic
    return navsatfix_fields_from_geodetic(
        stream.stamps_ns,
        lat,
        lon,
        alt,
        frame_id,
        position_covariance=position_covariance,
        position_covariance_type=position_covariance_type,
    )
