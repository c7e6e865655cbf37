"""Navigation errors against a truth stream, as SPEC §4's ``/navigator/error/*`` topics define.

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

from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef
from strapdown_ros.core.navigation.multirate import NavSolution
from strapdown_ros.core.navigation.state import truth_navigation
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.young import young_error_angles

__all__ = ["NavErrors", "navigation_errors"]

Array = NDArray[np.float64]


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

    t: Array
    index: NDArray[np.int64]
    position_ned: Array
    velocity_ned: Array
    attitude_young: Array

    @property
    def horizontal(self) -> Array:
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
    dr = np.einsum("nij,nj->ni", dcm_ecef_to_ned(lat, lon), r_nav - r_true)
    return NavErrors(
        t=t,
        index=index,
        position_ned=dr,
        velocity_ned=solution.v_ned - v_ned,
        attitude_young=young_error_angles(dcm_from_quat(solution.q_b_n), dcm_from_quat(q)),
    )
