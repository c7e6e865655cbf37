"""The Earth-referenced truth of a stream, shared by its Imu, Odometry and NavSatFix fields."""

from __future__ import annotations

from functools import cached_property

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.earth import dcm_ned_to_ecef, e0_state_to_ecef, ecef_to_geodetic
from strapdown_ros.core.stream import Stream
from strapdown_ros.messages.fields import F64

__all__ = ["StreamTruth"]


class StreamTruth:
    """Earth-referenced truth of a stream at t_m, m = 0..M, each part computed once, on demand.

    One object serves the Imu, Odometry and NavSatFix fields of a stream
    (:func:`~strapdown_ros.messages.stream.stream_fields`): the E0 → E conversion and the
    extended-precision geodetic conversion dominate their cost.
    """

    def __init__(self, stream: Stream) -> None:
        self.stream = stream

    @cached_property
    def ecef(self) -> tuple[F64, F64, F64]:
        """``r^E, v^E, C_B^E`` (FRD), E0 → E at ``t = t_m - t0``."""
        s = self.stream
        r_e, v_e, c_b_e = e0_state_to_ecef(s.t, s.r_e0, s.v_e0, s.c_b_e0)
        assert c_b_e is not None
        return r_e, v_e, c_b_e

    @cached_property
    def geodetic(self) -> tuple[F64, F64, F64]:
        """Geodetic latitude, longitude (rad) and altitude (m) of ``r^E`` (exact)."""
        return ecef_to_geodetic(self.ecef[0])

    def c_frd_ned(self) -> F64:
        """``C_FRD^NED`` at t_m, m = 1..M (the Imu messages)."""
        lat, lon, _ = self.geodetic
        return matmul33(dcm_ned_to_ecef(lat[1:], lon[1:]), self.ecef[2][1:], transpose_a=True)
