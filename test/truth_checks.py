"""Checks shared by the trajectory tests: a truth's velocity against its position."""

from __future__ import annotations

import numpy as np

from strapdown_ros.core.earth import dcm_ned_to_ecef, geodetic_to_ecef


def velocity_and_position_derivative(traj, t: np.ndarray, h: float) -> tuple[np.ndarray, ...]:
    """``(v^E, dr^E/dt)`` (N, 3) of a trajectory's truth at ``t`` (s): the ECEF velocity
    ``C_N^E v^N`` it reports and the 4th-order central difference (step ``h`` s) of its ECEF
    position, ``(8 (r(t+h) - r(t-h)) - (r(t+2h) - r(t-2h))) / 12h`` (error O(h⁴))."""

    def r_ecef(tt: np.ndarray) -> np.ndarray:
        lt = traj.local_truth(tt)
        return geodetic_to_ecef(lt.lat, lt.lon, lt.alt)

    fd = (8 * (r_ecef(t + h) - r_ecef(t - h)) - (r_ecef(t + 2 * h) - r_ecef(t - 2 * h))) / (12 * h)
    lt = traj.local_truth(t)
    v_e = np.einsum("nij,nj->ni", dcm_ned_to_ecef(lt.lat, lt.lon), lt.v_ned)
    return v_e, fd
