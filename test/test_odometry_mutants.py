"""messages/odometry.py edges found by mutation testing (docs/development.md, "Mutation testing"):
bad input names the argument, the covariances and frame ids are passed through, a given
StreamTruth is used, and a stream without cycles is at rest on the Earth."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros import messages as msg
from strapdown_ros.core.stream import Stream

N = 4
R_EQ = 6378137.0


def _good():
    return {
        "stamps_ns": 1_000 + np.arange(N) * 10_000_000,
        "r_e": np.tile([R_EQ, 0.0, 0.0], (N, 1)),
        "v_e": np.zeros((N, 3)),
        "c_b_e": np.tile(np.eye(3), (N, 1, 1)),
        "omega_eb_b": np.zeros((N, 3)),
    }


@pytest.mark.parametrize(
    "key,value,message",
    [
        ("r_e", np.zeros((N, 2)), r"^r_e: expected shape \(4, 3\), got \(4, 2\)$"),
        ("v_e", np.zeros((N - 1, 3)), r"^v_e: expected shape \(4, 3\), got \(3, 3\)$"),
        ("omega_eb_b", np.zeros(3), r"^omega_eb_b: expected shape \(4, 3\), got \(3,\)$"),
        ("c_b_e", np.zeros((N, 3)), r"^c_b_e: expected shape \(4, 3, 3\), got \(4, 3\)$"),
        ("pose_covariance", np.zeros(4), r"^pose_covariance: expected shape \(36,\)"),
        ("twist_covariance", np.zeros((2, 2)), r"^twist_covariance: expected shape \(36,\)"),
    ],
)  # fmt: skip
def test_bad_input_names_the_argument(key, value, message):
    with pytest.raises(ValueError, match=message):
        msg.odometry_fields_from_ecef(**(_good() | {key: value}))


def test_covariances_are_passed_through():
    cov = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    f = msg.odometry_fields_from_ecef(**_good(), pose_covariance=2 * cov, twist_covariance=cov)
    assert np.array_equal(f.twist_covariance, np.tile(cov.reshape(36), (N, 1)))
    assert np.array_equal(f.pose_covariance, np.tile(2 * cov.reshape(36), (N, 1)))


def _stream(cycles: int) -> Stream:
    return Stream(
        0, 10_000_000, np.zeros((cycles, 3)), np.zeros((cycles, 3)),
        np.tile(np.eye(3), (cycles + 1, 1, 1)), np.zeros((cycles + 1, 3)),
        np.tile([R_EQ, 0.0, 0.0], (cycles + 1, 1)),
    )  # fmt: skip


def test_frame_ids_of_a_stream():
    f = msg.odometry_fields(_stream(2), "imu_body", "ecef_custom")
    assert (f.child_frame_id, f.frame_id) == ("imu_body", "ecef_custom")


def test_stream_without_cycles_is_at_rest_on_the_earth():
    """One epoch, no increment: the body rate relative to the Earth is zero (docstring)."""
    f = msg.odometry_fields(_stream(0))
    assert f.twist_angular.shape == (1, 3)
    np.testing.assert_allclose(f.twist_angular, np.zeros((1, 3)), rtol=0, atol=1e-20)
    np.testing.assert_allclose(f.position, [[R_EQ, 0.0, 0.0]], rtol=1e-15)


class _Truth:
    """Stands in for a StreamTruth computed by another message type of the same stream."""

    def __init__(self, ecef):
        self._ecef = ecef
        self.calls = 0

    @property
    def ecef(self):
        self.calls += 1
        return self._ecef


def test_given_truth_is_used():
    cycles = 2
    r = np.tile([0.0, R_EQ, 0.0], (cycles + 1, 1))  # not the stream's position: 90° east
    v = np.tile([1.0, 2.0, 3.0], (cycles + 1, 1))
    c = np.tile(np.eye(3), (cycles + 1, 1, 1))
    truth = _Truth((r, v, c))
    f = msg.odometry_fields(_stream(cycles), truth=truth)
    assert truth.calls == 1
    assert np.array_equal(f.position, r)
    # C_FRD^E = I: twist.linear = FLU(v) = (1, -2, -3)
    np.testing.assert_allclose(f.twist_linear, np.tile([1.0, -2.0, -3.0], (cycles + 1, 1)),
                               rtol=1e-15)  # fmt: skip
