"""navsatfix_fields_from_geodetic: bad-input messages name their argument, columns keep the
sensor_msgs/NavSatFix dtypes, a given covariance and frame are passed on (expected values from
the message definitions and the inputs themselves)."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.navsatfix import navsatfix_fields, navsatfix_fields_from_geodetic

T = np.array([1_000, 2_000], dtype=np.int64)
GOOD = {"lat": [0.1, 0.2], "lon": [0.3, 0.4], "alt": [5.0, 6.0]}


@pytest.mark.parametrize(
    "name",
    ["lat", "lon", "alt", "status", "service", "position_covariance", "position_covariance_type"],
)
def test_bad_shape_message_names_the_argument(name: str) -> None:
    """The argument's own name starts the message (as_column's / covariance_rows' format)."""
    kw: dict = dict(GOOD)
    kw[name] = np.zeros((3, 7)) if name == "position_covariance" else [1, 2, 3]
    with pytest.raises(ValueError, match=rf"^{name}: "):
        navsatfix_fields_from_geodetic(T, **kw)


def test_columns_dtypes_and_passed_on_fields() -> None:
    cov = np.diag([1.0, 2.0, 3.0])
    f = navsatfix_fields_from_geodetic(
        T, [1, 2], [1, 0], [7, 8], "gnss_antenna", position_covariance=cov,
        position_covariance_type=2, status=-1, service=4,
    )  # fmt: skip
    assert f.frame_id == "gnss_antenna"
    assert f.status.dtype == np.int8 and f.service.dtype == np.uint16
    assert f.position_covariance_type.dtype == np.uint8
    assert f.latitude.dtype == f.longitude.dtype == f.altitude.dtype == np.float64
    np.testing.assert_array_equal(f.position_covariance_type, [2, 2])
    np.testing.assert_array_equal(f.latitude, np.degrees([1.0, 2.0]))
    np.testing.assert_array_equal(np.asarray(f.position_covariance).reshape(2, 9),
                                  np.tile(cov.reshape(9), (2, 1)))


def test_stream_fields_pass_frame_and_covariance_type_on() -> None:
    """navsatfix_fields of a Stream passes frame_id and position_covariance_type on (expected
    values: the arguments themselves; the stream is two cycles at rest on the equator)."""
    r = np.tile([6378137.0, 0.0, 0.0], (3, 1))
    s = Stream(0, 10_000_000, np.zeros((2, 3)), np.zeros((2, 3)),
               np.tile(np.eye(3), (3, 1, 1)), np.zeros((3, 3)), r)  # fmt: skip
    f = navsatfix_fields(s, "gnss_antenna", position_covariance=np.eye(3),
                         position_covariance_type=1)  # fmt: skip
    assert f.frame_id == "gnss_antenna"
    np.testing.assert_array_equal(f.position_covariance_type, [1, 1, 1])
