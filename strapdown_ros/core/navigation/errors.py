"""Navigation errors against truth, as docs/interface.md §4's ``/navigator/error/*`` define.

* position: navigation minus truth in the true local level, NED, m — ``C_E^N(true) (r_nav - r)``
  with both positions in ECEF (exact, not a small-angle latitude/longitude difference);
* velocity: navigation minus truth ground velocity, NED, m/s (each in its own NED frame, the
  way a navigator reports it);
* attitude: Young 1980 Euler error angles (θ1, θ2, θ3) of eq. (28) between the local-level
  frame implied by the computed attitude and the true one, ``H = C_B^N(nav) C_B^N(true)ᵀ`` in
  (up, east, north) axes (:func:`strapdown_ros.core.young.young_error_angles`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef
from strapdown_ros.core.navigation.multirate import NavSolution
from strapdown_ros.core.navigation.state import truth_navigation
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.young import young_error_angles

__all__ = [
    "NavErrors",
    "attitude_error_young",
    "navigation_errors",
    "position_error_ned",
    "velocity_error_ned",
]



def position_error_ned(r_nav_e: F64, r_true_e: F64, lat_true: F64, lon_true: F64) -> F64:
    """Position error ``C_E^N(true) (r_nav - r_true)`` (m, NED of the true position).

    Parameters
    ----------
    r_nav_e, r_true_e : arrays (K, 3)
        Navigation and true positions, ECEF (m).
    lat_true, lon_true : arrays (K,)
        Geodetic latitude and longitude of the true position (rad).
    """
    return np.einsum("nij,nj->ni", dcm_ecef_to_ned(lat_true, lon_true), r_nav_e - r_true_e)


def velocity_error_ned(v_nav_ned: F64, v_true_ned: F64) -> F64:
    """Velocity error ``v_nav - v_true`` (m/s), each ground velocity in its own NED frame."""
    return v_nav_ned - v_true_ned


def attitude_error_young(c_b_n_nav: F64, c_b_n_true: F64) -> F64:
    """Attitude error: Young 1980 eq. (28) angles (θ1, θ2, θ3) (rad).

    About the (up, east, north) axes of the true local level, of ``H = C_B^N(nav)
    C_B^N(true)ᵀ`` (:func:`~strapdown_ros.core.young.young_error_angles`).
    """
    return young_error_angles(c_b_n_nav, c_b_n_true)


@dataclass(frozen=True)
class NavErrors:
    """Errors at the navigator's output times.

    Attributes
    ----------
    t : array (K,)
        Time since the E0 epoch, s.
    index : array (K,)
        Truth sample of each output (cycle m of the truth stream).
    position_ned, velocity_ned : arrays (K, 3)
        m and m/s, NED of the true position.
    attitude_young : array (K, 3)
        Young angles (θ1, θ2, θ3), rad.
    """

    t: F64
    index: NDArray[np.int64]
    position_ned: F64
    velocity_ned: F64
    attitude_young: F64

    @property
    def horizontal(self) -> F64:
        """Root-sum-square horizontal position error (m), Waldmann Table 3's measure."""
        return np.hypot(self.position_ned[:, 0], self.position_ned[:, 1])


def navigation_errors(solution: NavSolution, truth: Stream) -> NavErrors:
    """Errors of a navigation solution against the truth stream it was computed from.

    Output times must fall on truth samples (T_nav a multiple of the truth period); the truth
    sample of each output is ``round(t / T)`` and is checked to be within 1 µs.
    """
    offset = (truth.t0_ns - int(truth.e0_epoch_ns or truth.t0_ns)) * 1e-9
    index = np.rint((solution.t - offset) / truth.period).astype(np.int64)
    if np.any(np.abs(offset + index * truth.period - solution.t) > 1e-6):
        raise ValueError("navigation output times do not fall on truth samples")
    if index.size and (index.min() < 0 or index.max() > truth.cycles):
        raise ValueError("navigation outputs extend beyond the truth stream")
    t, lat, lon, alt, v_ned, q = truth_navigation(truth, index)
    r_true = geodetic_to_ecef(lat, lon, alt)
    r_nav = geodetic_to_ecef(solution.lat, solution.lon, solution.alt)
    return NavErrors(
        t=t,
        index=index,
        position_ned=position_error_ned(r_nav, r_true, lat, lon),
        velocity_ned=velocity_error_ned(solution.v_ned, v_ned),
        attitude_young=attitude_error_young(dcm_from_quat(solution.q_b_n), dcm_from_quat(q)),
    )
