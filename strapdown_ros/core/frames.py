"""The ROS frame tree of a dataset: ``earth → map → base_link → sensors`` (ROS-free maths).

``map`` is the ENU tangent plane at a datum (REP-105 ``map`` over REP-103 ENU axes), ``earth``
is ECEF, ``base_link`` the reference IMU's body in FLU axes. Everything here returns direction
cosine matrices and translations; quaternions and messages are built in
:mod:`strapdown_ros.messages`. Definitions and equations: docs/interface.md, "Frames and TF".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ned_to_ecef, geodetic_to_ecef
from strapdown_ros.core.rotations import C_FRD_TO_FLU, C_NED_TO_ENU

__all__ = [
    "Datum",
    "MapPose",
    "body_in_map",
    "lever_arm_in_base_link",
    "row_times",
    "sensor_in_body",
]


#: FRD ↔ FLU sign flips, applied elementwise.
_FLU = np.array([1.0, -1.0, -1.0])


def row_times(d: ArrayLike, c: ArrayLike) -> F64:
    """Row vectors ``d`` (..., 3) times the matrix ``c`` (3, 3): ``out_j = Σ_k d_k c_kj``.

    Written elementwise (no BLAS): each row's result is the same bits whatever the number of
    rows, so chunked streams give identical messages.
    """
    d = np.asarray(d, dtype=np.float64)
    c = np.asarray(c, dtype=np.float64)
    return d[..., 0:1] * c[0] + d[..., 1:2] * c[1] + d[..., 2:3] * c[2]


@dataclass(frozen=True)
class Datum:
    """Origin and axes of the ``map`` frame: ENU tangent plane at a geodetic point.

    ``r0_e`` (3,) is the datum's ECEF position (m); ``c_map_e`` (3, 3) is ``C_ENU^E`` (columns:
    east, north, up in ECEF axes), the rotation of the ``earth → map`` transform.
    """

    latitude_rad: float
    longitude_rad: float
    altitude_m: float
    r0_e: F64
    c_map_e: F64

    @classmethod
    def at(cls, latitude_rad: float, longitude_rad: float, altitude_m: float) -> Datum:
        """The datum at a geodetic position (WGS-84, ellipsoidal altitude)."""
        lat, lon, alt = float(latitude_rad), float(longitude_rad), float(altitude_m)
        r0 = np.asarray(geodetic_to_ecef(lat, lon, alt), dtype=np.float64).reshape(3)
        # C_ENU^E = C_NED^E C_ENU^NED (C_ENU^NED = C_NED_TO_ENU^T = C_NED_TO_ENU, an involution)
        c = np.asarray(dcm_ned_to_ecef(lat, lon), dtype=np.float64).reshape(3, 3) @ C_NED_TO_ENU
        r0.setflags(write=False)
        c.setflags(write=False)
        return cls(lat, lon, alt, r0, c)

    def to_map(self, r_e: ArrayLike) -> F64:
        """ENU position relative to the datum of ECEF positions ``r_e`` (..., 3), m."""
        d = np.asarray(r_e, dtype=np.float64) - self.r0_e
        return row_times(d, self.c_map_e)  # (C_ENU^E)^T d, row-wise

    def to_earth(self, p_map: ArrayLike) -> F64:
        """ECEF position of ``map`` positions ``p_map`` (..., 3), m (inverse of :meth:`to_map`)."""
        return self.r0_e + row_times(p_map, self.c_map_e.T)


@dataclass(frozen=True)
class MapPose:
    """Pose of a body FLU frame in ``map``.

    ``position`` (N, 3) m ENU; ``c_body_map`` (N, 3, 3) ``C_FLU^ENU`` (the ``map → body``
    transform and the pose of a map-frame Odometry).
    """

    position: F64
    c_body_map: F64


def body_in_map(datum: Datum, r_e: ArrayLike, c_frd_e: ArrayLike) -> MapPose:
    """Pose in ``map`` of a body given in ECEF: position ``r_e`` (N, 3) m and ``C_FRD^E`` (N, 3, 3).

    ``p = C_E^ENU (r^E − r0^E)``, ``C_FLU^ENU = C_E^ENU C_FRD^E C_FRD→FLU``.
    """
    c = np.asarray(c_frd_e, dtype=np.float64)
    return MapPose(datum.to_map(r_e), datum.c_map_e.T @ c @ C_FRD_TO_FLU)


def sensor_in_body(
    lever_arm_frd: ArrayLike, displacement_frd: ArrayLike, c_sensor_body_frd: ArrayLike
) -> tuple[F64, F64]:
    """Transform ``body → sensor`` (both FLU) of a variation IMU from its offsets (all FRD).

    The sensor sits at ``p^B = l^B + C_S^B s^S`` (Savage 2020 eqs. (6)–(7): lever arm ``l`` in the
    body, displacement ``s`` in the sensor axes) with attitude ``C_S^B``. Returns the translation
    ``FLU(p^B)`` (N, 3) m and the rotation ``C_FLU_S^FLU_B = D C_S^B D`` (N, 3, 3),
    ``D = diag(1, −1, −1)``.
    """
    c = np.asarray(c_sensor_body_frd, dtype=np.float64)
    s = np.asarray(displacement_frd, dtype=np.float64)
    cs = c[..., 0] * s[..., 0:1] + c[..., 1] * s[..., 1:2] + c[..., 2] * s[..., 2:3]
    p = np.asarray(lever_arm_frd, dtype=np.float64) + cs
    return p * _FLU, c * _FLU[:, None] * _FLU  # D C D, elementwise


def lever_arm_in_base_link(lever_arm_frd: ArrayLike) -> F64:
    """Translation of ``base_link → sensor`` of a sensor at the lever arm ``l^B``.

    ``l^B``: body FRD, m, from the reference IMU (the origin of ``base_link``). Returns
    ``FLU(l^B) = D l^B`` (m), ``D = diag(1, −1, −1)``; the sensor's axes are the body's
    (rotation identity).
    """
    return np.asarray(lever_arm_frd, dtype=np.float64) * _FLU
