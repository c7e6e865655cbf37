"""Waldmann's coning scenario (seeds/004, §6 "Results"): the ``coning`` trajectory kind.

The vehicle's centre of mass (CM) rests at a geodetic position or moves with the §6 velocity
profile relative to the ground::

    V_N = 200 sin(2π t/1200),  V_E = 150 sin(2π t/1200),  V_D = 5 sin(2π t/300)  [m/s],
    t ∈ [0, 300] s,

while the body performs the coning motion relative to the local-level (NED) frame given in §6
(the unnumbered equation after the velocity profile)::

    ω_b^bl = [-Ω_p sin θ cos(Ω_p t), -Ω_p sin θ sin(Ω_p t), Ω_p (cos θ - 1)]ᵀ,
    θ = π/2 rad, Ω_p = π/6 rad/s,

θ the cone half-angle and Ω_p the precession rate of the body axis z_b about the local vertical.
The attitude history with exactly this rate, starting from ``C_B^N(0) = C_0``, is

    C_B^N(t) = C_0 · Rz(Ω_p t) · Ry(θ) · Rz(-Ω_p t)

(derivation in :class:`ConingTrajectory`). The IMU lever arm of §6 (1 m ahead of the CM) is not
modelled here: the trajectory is the CM, and the variation step adds the lever arm.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import dcm_from_euler, rot_y, rot_z
from strapdown_ros.core.trajectory.base import LocalTruth
from strapdown_ros.core.trajectory.latlon_path import LatLonPath

__all__ = [
    "AMPLITUDE_DEFAULT",
    "CM_MOTIONS",
    "DURATION_DEFAULT",
    "PERIOD_DEFAULT",
    "PRECESSION_RATE_DEFAULT",
    "THETA_DEFAULT",
    "ConingTrajectory",
    "lowest_altitude",
]


#: §6 defaults: cone half-angle, precession rate, CM velocity amplitudes and periods, duration.
THETA_DEFAULT = math.pi / 2.0
PRECESSION_RATE_DEFAULT = math.pi / 6.0
AMPLITUDE_DEFAULT = (200.0, 150.0, 5.0)
PERIOD_DEFAULT = (1200.0, 1200.0, 300.0)
DURATION_DEFAULT = 300.0

CM_MOTIONS = ("rest", "sinusoids")


def lowest_altitude(
    alt0: float, amplitude_down: float, period_down: float, duration: float
) -> float:
    """Lowest CM altitude (m) of the sinusoids over ``[0, duration]``.

    ``h = h0 - A_D P_D/(2π) (1 - cos(2π t/P_D))`` is lowest at ``t = P_D/2`` or at the end;
    ``h0`` itself when ``A_D <= 0`` (the CM rises first).
    """
    if amplitude_down <= 0.0:
        return float(alt0)
    one_minus_cos = (
        2.0
        if duration >= 0.5 * period_down
        else 1.0 - math.cos(2.0 * math.pi * duration / period_down)
    )
    return float(alt0 - amplitude_down * period_down / (2.0 * math.pi) * one_minus_cos)


class ConingTrajectory:
    """CM at rest or on the §6 sinusoidal velocity profile; body coning relative to NED.

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude of the CM at t = 0 (rad).
    alt : float
        Ellipsoidal altitude of the CM at t = 0 (m).
    theta : float
        Cone half-angle θ (rad); §6 uses π/2.
    precession_rate : float
        Precession rate Ω_p (rad/s); §6 uses π/6.
    duration : float
        Length (s), > 0; §6 uses 300.
    cm_motion : {"rest", "sinusoids"}
        CM fixed to the ground, or ``v_i(t) = A_i sin(2π t / P_i)`` (NED, m/s).
    amplitude_ned : array (3,)
        ``A_N, A_E, A_D`` (m/s), default (200, 150, 5).
    period_ned : array (3,)
        ``P_N, P_E, P_D`` (s), > 0, default (1200, 1200, 300).
    rph : array (3,)
        Initial roll, pitch, heading (rad) giving ``C_0 = C_B^N(0)``; zero in §6.

    Notes
    -----
    Attitude. With ``a = Ω_p t`` and ``C(t) = C_0 Rz(a) Ry(θ) Rz(-a)``, using
    ``d/dt Rz(a) = Ω_p Rz(a) (e_z×)`` and ``Rᵀ (e_z×) R = ((Rᵀ e_z)×)``::

        (ω_b^bl ×) = Cᵀ Ċ = Ω_p Rz(a) [((Ry(θ)ᵀ e_z)×) - (e_z×)] Rz(-a)
        ω_b^bl = Ω_p Rz(a) ([-sin θ, 0, cos θ] - [0, 0, 1])
               = Ω_p [-sin θ cos a, -sin θ sin a, cos θ - 1],

    exactly Waldmann's §6 expression for any constant ``C_0``. The body z axis in the frame of
    ``C_0`` is ``Rz(a) Ry(θ) e_z = [sin θ cos a, sin θ sin a, cos θ]``: a cone of half-angle θ
    about the (C_0) vertical, precessing at Ω_p; with zero roll and pitch in ``C_0`` the cone axis
    is the local vertical as in the paper. ``|ω_b^bl| = 2 Ω_p sin(θ/2)`` (√2 Ω_p for θ = π/2).

    Position. At rest: constant. Sinusoids: ``h(t) = h_0 - A_D P_D/(2π) (1 - cos(2π t/P_D))``
    in closed form; latitude and longitude integrate the geodetic rates with
    :class:`~strapdown_ros.core.trajectory.latlon_path.LatLonPath`. The velocity is zero at t = 0
    in both cases.
    """

    def __init__(
        self,
        lat: float,
        lon: float,
        alt: float,
        theta: float = THETA_DEFAULT,
        precession_rate: float = PRECESSION_RATE_DEFAULT,
        duration: float = DURATION_DEFAULT,
        cm_motion: str = "rest",
        amplitude_ned: ArrayLike = AMPLITUDE_DEFAULT,
        period_ned: ArrayLike = PERIOD_DEFAULT,
        rph: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        if cm_motion not in CM_MOTIONS:
            raise ValueError(
                f"cm_motion: must be one of {', '.join(CM_MOTIONS)}, got {cm_motion!r}"
            )
        if not duration > 0.0:
            raise ValueError(f"duration_s: must be > 0, got {duration}")
        self.lat0, self.lon0, self.alt0 = float(lat), float(lon), float(alt)
        self.theta = float(theta)
        self.precession_rate = float(precession_rate)
        self.cm_motion = cm_motion
        self.amplitude_ned = np.asarray(amplitude_ned, dtype=np.float64).reshape(3)
        self.period_ned = np.asarray(period_ned, dtype=np.float64).reshape(3)
        if np.any(self.period_ned <= 0.0):
            raise ValueError(f"velocity_period_ned_s: must be > 0, got {self.period_ned.tolist()}")
        self._duration = float(duration)
        self.c0 = dcm_from_euler(*np.asarray(rph, dtype=np.float64).reshape(3))
        self._ry = rot_y(self.theta)
        self._path = None
        if cm_motion == "sinusoids":
            self._path = LatLonPath([0.0, self._duration], self.lat0, self.lon0, self._vn_ve_h)

    @property
    def duration(self) -> float:
        """Length of the trajectory (s)."""
        return self._duration

    def velocity_ned(self, t: ArrayLike) -> F64:
        """CM velocity relative to the Earth, NED (m/s), shape (N, 3): §6 profile or zero."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        if self.cm_motion == "rest":
            return np.zeros((t.size, 3))
        w = 2.0 * np.pi / self.period_ned
        return self.amplitude_ned * np.sin(t[:, None] * w)

    def altitude(self, t: ArrayLike) -> F64:
        """CM ellipsoidal altitude (m): ``h_0 - A_D P_D/(2π) (1 - cos(2π t/P_D))`` or ``h_0``."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        if self.cm_motion == "rest":
            return np.full(t.size, self.alt0)
        w = 2.0 * np.pi / self.period_ned[2]
        # 1 - cos x = 2 sin²(x/2): no cancellation at small t.
        return self.alt0 - self.amplitude_ned[2] / w * 2.0 * np.sin(0.5 * w * t) ** 2

    def _vn_ve_h(self, t: F64) -> tuple[F64, F64, F64]:
        v = self.velocity_ned(t)
        return v[:, 0], v[:, 1], self.altitude(t)

    def attitude(self, t: ArrayLike) -> F64:
        """``C_B^N(t) = C_0 Rz(Ω_p t) Ry(θ) Rz(-Ω_p t)`` (FRD to NED), shape (N, 3, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        a = self.precession_rate * t
        return self.c0 @ rot_z(a) @ self._ry @ rot_z(-a)

    def omega_bl_b(self, t: ArrayLike) -> F64:
        """Waldmann §6 body rate relative to the local level, body axes (rad/s), (N, 3).

        ``ω_b^bl = Ω_p [-sin θ cos(Ω_p t), -sin θ sin(Ω_p t), cos θ - 1]``.
        """
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        a = self.precession_rate * t
        s, c = math.sin(self.theta), math.cos(self.theta)
        w = self.precession_rate
        return np.stack(
            [-w * s * np.cos(a), -w * s * np.sin(a), np.full(t.size, w * (c - 1.0))], -1
        )

    def local_truth(self, t: ArrayLike) -> LocalTruth:
        """CM truth at times ``t`` (s since t0, within ``[0, duration]``), vectorized.

        Returns
        -------
        LocalTruth
            Geodetic CM position (rad, rad, m), NED velocity relative to the Earth (m/s), and
            the coning attitude ``C_B^N`` (FRD to NED).
        """
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        tol = 1e-9 * max(1.0, self._duration)
        if t.size and (t.min() < -tol or t.max() > self._duration + tol):
            raise ValueError(
                f"times must lie in [0, {self._duration}] s, got [{t.min()}, {t.max()}]"
            )
        if self._path is None:
            lat, lon = np.full(t.size, self.lat0), np.full(t.size, self.lon0)
        else:
            lat, lon = self._path(t)
        return LocalTruth(
            t=t,
            lat=lat,
            lon=lon,
            alt=self.altitude(t),
            v_ned=self.velocity_ned(t),
            c_b_n=self.attitude(t),
        )
