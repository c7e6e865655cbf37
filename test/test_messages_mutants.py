"""messages/imu.py edges found by mutation testing: bad input names the argument, T >= 1 ns,
and a given StreamTruth is used rather than recomputed."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros import messages as msg
from strapdown_ros.core.stream import Stream

N = 4
T_NS = 10_000_000


def _good():
    return {
        "stamps_ns": 1_000 + np.arange(1, N + 1) * T_NS,
        "dalpha": np.zeros((N, 3)),
        "dv": np.zeros((N, 3)),
        "period_ns": T_NS,
    }


@pytest.mark.parametrize("period_ns", [0, -5])
def test_period_must_be_positive(period_ns):
    kw = _good() | {"period_ns": period_ns}
    with pytest.raises(ValueError, match=rf"^period_ns must be > 0, got {period_ns}$"):
        msg.imu_fields_from_increments(**kw)


def test_one_nanosecond_period_is_allowed():
    """T = 1 ns: rates are increments times 1e9 (FRD (x, y, z) -> FLU (x, -y, -z))."""
    kw = _good() | {"period_ns": 1, "dalpha": np.tile([1e-9, 2e-9, 3e-9], (N, 1))}
    f = msg.imu_fields_from_increments(**kw)
    np.testing.assert_allclose(f.angular_velocity, np.tile([1.0, -2.0, -3.0], (N, 1)), rtol=1e-15)


@pytest.mark.parametrize(
    "key,value,message",
    [
        ("dalpha", np.zeros((N, 2)), r"^dalpha: expected shape \(4, 3\), got \(4, 2\)$"),
        ("dv", np.zeros((N - 1, 3)), r"^dv: expected shape \(4, 3\), got \(3, 3\)$"),
        ("c_frd_ned", np.zeros((N, 3)), r"^c_frd_ned: expected shape \(4, 3, 3\), got \(4, 3\)$"),
        ("orientation_covariance", "bogus", r"^orientation_covariance: unknown covariance spec"),
        ("angular_velocity_covariance", np.zeros(4),
         r"^angular_velocity_covariance: expected shape \(9,\)"),
        ("linear_acceleration_covariance", np.zeros((2, 2)),
         r"^linear_acceleration_covariance: expected shape \(9,\)"),
    ],
)  # fmt: skip
def test_bad_input_names_the_argument(key, value, message):
    with pytest.raises(ValueError, match=message):
        msg.imu_fields_from_increments(**(_good() | {key: value}))


class _Truth:
    """Stands in for a StreamTruth computed by another message type of the same stream."""

    def __init__(self, c):
        self.c = c
        self.calls = 0

    def c_frd_ned(self):
        self.calls += 1
        return self.c


def test_given_truth_is_used():
    cycles = 3
    stream = Stream(
        0, T_NS, np.zeros((cycles, 3)), np.zeros((cycles, 3)),
        np.tile(np.eye(3), (cycles + 1, 1, 1)), np.zeros((cycles + 1, 3)),
        np.tile([6378137.0, 0.0, 0.0], (cycles + 1, 1)),
    )  # fmt: skip
    # FRD = NED (level, north): FLU relative to ENU is +90 deg of yaw, q = (0, 0, sin 45, cos 45)
    truth = _Truth(np.tile(np.eye(3), (cycles, 1, 1)))
    f = msg.imu_fields(stream, truth=truth)
    assert truth.calls == 1
    h = np.sqrt(0.5)
    np.testing.assert_allclose(f.orientation, np.tile([0.0, 0.0, h, h], (cycles, 1)), atol=1e-15)
