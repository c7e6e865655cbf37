"""GNSS receiver: position and velocity of the antenna point, plus correlated receiver errors.

Truth (rigid antenna at the lever arm ``l`` from the IMU, body FRD): ``r_a = r + C_B^E l`` and
``v_a = v + C_B^E (ω_eb^B × l)`` in ECEF, with ``ω_eb^B`` the truth stream's rate relative to the
Earth. Errors per local-level NED axis: constant offset + first-order Gauss–Markov (σ, τ) +
white noise, for position (m) and velocity (m/s). Equations and presets: ``docs/aiding.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.aiding.common import (
    GaussMarkov,
    check_period,
    mat_t_vec,
    mat_vec,
    per_axis,
    rate_cross_lever,
    sensor_rng,
)
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ned_to_ecef, ecef_to_geodetic

__all__ = [
    "GNSS_NORMALS_PER_EPOCH",
    "GnssErrorModel",
    "GnssErrors",
    "GnssMeasurement",
    "antenna_state",
    "gnss_measurement",
]


#: Standard normals per epoch: position white 3, position GM 3, velocity white 3, velocity GM 3.
GNSS_NORMALS_PER_EPOCH = 12


@dataclass(frozen=True)
class GnssErrors:
    """Receiver error parameters, per NED axis (north, east, down), SI units.

    ``*_white`` white noise σ; ``*_gm_sigma`` / ``*_gm_tau_s`` Gauss–Markov σ and τ;
    ``*_offset`` constant offset. Position in m, velocity in m/s.
    """

    position_white: F64 = per_axis()
    position_gm_sigma: F64 = per_axis()
    position_gm_tau_s: F64 = per_axis(1.0)
    position_offset: F64 = per_axis()
    velocity_white: F64 = per_axis()
    velocity_gm_sigma: F64 = per_axis()
    velocity_gm_tau_s: F64 = per_axis(1.0)
    velocity_offset: F64 = per_axis()

    @property
    def position_variance(self) -> F64:
        """Variance of one fix's random error per NED axis (m²): white² + GM σ²."""
        return np.asarray(self.position_white) ** 2 + np.asarray(self.position_gm_sigma) ** 2

    @property
    def velocity_variance(self) -> F64:
        """Variance of one velocity's random error per NED axis ((m/s)²): white² + GM σ²."""
        return np.asarray(self.velocity_white) ** 2 + np.asarray(self.velocity_gm_sigma) ** 2


def antenna_state(
    r_e: ArrayLike, v_e: ArrayLike, c_b_e: ArrayLike, omega_eb_b: ArrayLike, lever_arm_b: ArrayLike
) -> tuple[F64, F64]:
    """ECEF position (m) and Earth-relative velocity (m/s) of a rigid point at a lever arm.

    Parameters
    ----------
    r_e, v_e : (n, 3)
        IMU position and velocity relative to the Earth, ECEF.
    c_b_e : (n, 3, 3)
        ``C_FRD^E``.
    omega_eb_b : (n, 3)
        Body rate relative to the Earth, FRD, rad/s.
    lever_arm_b : (3,)
        The point relative to the IMU, body FRD, m.

    Returns
    -------
    r_a, v_a : (n, 3)
        ``r + C l`` and ``v + C (ω × l)``.
    """
    r = np.asarray(r_e, dtype=np.float64)
    v = np.asarray(v_e, dtype=np.float64)
    c = np.asarray(c_b_e, dtype=np.float64)
    lever = np.broadcast_to(np.asarray(lever_arm_b, dtype=np.float64), np.shape(omega_eb_b))
    return r + mat_vec(c, lever), v + mat_vec(c, rate_cross_lever(omega_eb_b, lever))


class GnssErrorModel:
    """Seeded receiver errors at consecutive epochs (state carried, chunk-invariant).

    At construction 6 normals draw the initial Gauss–Markov states (position 3, velocity 3);
    every epoch then consumes :data:`GNSS_NORMALS_PER_EPOCH` normals whatever the parameters.

    Parameters
    ----------
    errors : GnssErrors
    period_s : float
        Epoch period (s).
    seed : int
    """

    def __init__(self, errors: GnssErrors, period_s: float, seed: int) -> None:
        self.errors = errors
        self.period_s = check_period(period_s)
        self._rng = sensor_rng(seed, "gnss")
        init = self._rng.standard_normal(6)
        self._pos_gm = GaussMarkov(
            errors.position_gm_sigma, errors.position_gm_tau_s, self.period_s, init[0:3]
        )
        self._vel_gm = GaussMarkov(
            errors.velocity_gm_sigma, errors.velocity_gm_tau_s, self.period_s, init[3:6]
        )
        self.epochs = 0

    def take(self, n: int) -> tuple[F64, F64]:
        """Position (m) and velocity (m/s) errors, NED, of the next ``n`` epochs, (n, 3) each."""
        z = self._rng.standard_normal((n, GNSS_NORMALS_PER_EPOCH))
        e = self.errors
        pos = np.asarray(e.position_offset) + (
            np.asarray(e.position_white) * z[:, 0:3] + self._pos_gm.take(z[:, 3:6])
        )
        vel = np.asarray(e.velocity_offset) + (
            np.asarray(e.velocity_white) * z[:, 6:9] + self._vel_gm.take(z[:, 9:12])
        )
        self.epochs += n
        return pos, vel

    def skip(self, n: int) -> None:
        """Advance over ``n`` epochs without output (random state and Gauss–Markov states)."""
        if n > 0:
            self.take(n)


@dataclass(frozen=True)
class GnssMeasurement:
    """Measured antenna fixes and velocities.

    Geodetic ``lat``, ``lon`` (rad), ``alt`` (m, ellipsoidal), and the Earth-relative velocity
    ``v_enu`` (n, 3) in the local ENU axes (m/s).
    """

    lat: F64
    lon: F64
    alt: F64
    v_enu: F64


def gnss_measurement(
    r_a: ArrayLike, v_a: ArrayLike, position_error_ned: ArrayLike, velocity_error_ned: ArrayLike
) -> GnssMeasurement:
    """Measured fix and velocity of an antenna at ``r_a``, ``v_a`` (ECEF) with NED errors.

    ``r̃ = r_a + C_N^E(φ_a, λ_a) δr^N``, then geodetic; ``ṽ^ENU = ENU(C_E^N v_a + δv^N)`` with the
    NED axes at the true antenna position. Zero errors give the antenna truth exactly.
    """
    r = np.asarray(r_a, dtype=np.float64)
    v = np.asarray(v_a, dtype=np.float64)
    dr = np.asarray(position_error_ned, dtype=np.float64)
    dv = np.asarray(velocity_error_ned, dtype=np.float64)
    lat, lon, alt = ecef_to_geodetic(r)
    c_n_e = dcm_ned_to_ecef(lat, lon)
    if np.any(dr != 0.0):
        lat, lon, alt = ecef_to_geodetic(r + mat_vec(c_n_e, dr))
    v_ned = mat_t_vec(c_n_e, v) + dv
    v_enu = np.stack([v_ned[:, 1], v_ned[:, 0], -v_ned[:, 2]], axis=-1)
    return GnssMeasurement(lat, lon, alt, v_enu)
