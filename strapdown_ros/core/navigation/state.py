"""Navigation state in navigation terms and its initialization from a stream's truth.

The navigator works in geodetic coordinates and the local-level NED frame (Waldmann, seeds/004,
§2: latitude λ, longitude Λ, altitude h, ground velocity ``U_l = [V_N, V_E, V_D]``, attitude
``D_l^b`` as the quaternion ``q_b^l`` of eq. (33)). Streams carry their truth in the inertial E0
frame (docs/interface.md §1, §3); :func:`state_from_stream` and :func:`truth_navigation` convert
E0 → ECEF → geodetic/NED with :mod:`strapdown_ros.core.earth`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    dcm_ecef_to_ned,
    e0_state_to_ecef,
    ecef_to_geodetic,
    ned_velocity_from_ecef,
)
from strapdown_ros.core.rotations import quat_from_dcm
from strapdown_ros.core.stream import Stream

__all__ = ["NavState", "state_from_stream", "truth_navigation"]


@dataclass(frozen=True)
class NavState:
    """Navigation state at one instant (Waldmann eq. (9) and (14) variables).

    Attributes
    ----------
    t : float
        Time since the stream's E0 epoch (docs/interface.md §1), s.
    lat, lon : float
        Geodetic latitude λ and longitude Λ, rad.
    alt : float
        Altitude h above the WGS-84 ellipsoid, m.
    v_ned : array (3,)
        Ground velocity ``U_l = [V_N, V_E, V_D]`` relative to the Earth, m/s.
    q_b_n : array (4,)
        Attitude quaternion ``q_b^l`` (Hamilton, scalar first) of body FRD relative to NED:
        ``dcm_from_quat(q_b_n) = C_B^N`` (Waldmann's ``D_l^b``, eq. (15)).
    """

    t: float
    lat: float
    lon: float
    alt: float
    v_ned: F64
    q_b_n: F64


def _times(stream: Stream, index: NDArray[np.int64]) -> F64:
    """Time since the E0 epoch of truth samples ``index`` (docs/interface.md §1-§2)."""
    offset_ns = stream.t0_ns - int(stream.e0_epoch_ns or stream.t0_ns)
    return (offset_ns + index.astype(np.float64) * stream.period_ns) * 1e-9


def truth_navigation(
    stream: Stream, index: NDArray[np.int64] | None = None
) -> tuple[F64, F64, F64, F64, F64, F64]:
    """Truth of a stream in navigation terms at truth samples ``index``.

    E0 → ECEF by ``r^E = C_E0^E R^E0``, ``v^E = C_E0^E V^E0 - ω_ie × r^E``,
    ``C_B^E = C_E0^E C_B^E0`` (docs/interface.md §1, Savage 2020 (E-7)); then geodetic coordinates,
    ``v^N = C_E^N v^E`` and ``C_B^N = C_E^N C_B^E``.

    Parameters
    ----------
    stream : Stream
        A stream whose truth is in E0 (docs/interface.md §3).
    index : array of int, optional
        Truth sample indices m (default: all, 0..M).

    Returns
    -------
    t, lat, lon, alt : arrays (K,)
        Time since the E0 epoch (s), rad, rad, m.
    v_ned : array (K, 3)
        Ground velocity in NED, m/s.
    q_b_n : array (K, 4)
        Quaternion of ``C_B^N`` (body FRD to NED).
    """
    if index is None:
        index = np.arange(stream.cycles + 1)
    index = np.asarray(index, dtype=np.int64)
    t = _times(stream, index)
    r_e, v_e, c_b_e = e0_state_to_ecef(
        t, stream.r_e0[index], stream.v_e0[index], stream.c_b_e0[index]
    )
    lat, lon, alt = ecef_to_geodetic(r_e)
    v_ned = ned_velocity_from_ecef(lat, lon, v_e)
    assert c_b_e is not None
    q = quat_from_dcm(dcm_ecef_to_ned(lat, lon) @ c_b_e)
    return t, lat, lon, alt, v_ned, q


def state_from_stream(stream: Stream, m: int = 0) -> NavState:
    """Error-free initial navigation state from truth sample ``m`` of a stream.

    The first truth message is the initial state at t0 (docs/interface.md §2); the conversion is
    that of
    :func:`truth_navigation`. This is Waldmann's ``λ(0), Λ(0), h(0)`` (9), ``U_l(0)`` (27) and
    ``q_b^l(0)`` (33) "given" by an ideal alignment.

    Parameters
    ----------
    stream : Stream
        A stream whose truth is in E0.
    m : int
        Truth sample index (default 0, the start).

    Returns
    -------
    NavState
    """
    t, lat, lon, alt, v, q = truth_navigation(stream, np.array([m]))
    return NavState(float(t[0]), float(lat[0]), float(lon[0]), float(alt[0]), v[0], q[0])
