"""Young 1980 eqs. (51a)–(51c) integrated along a run: the nonlinear orientation error oracle.

Young's frames mapped onto a strapdown navigator (docs/theory/young_nonlinear.md):

* Σ_P, the ideal platform: the true local level (up, east, north) at the true position;
* Σ_C, the computer frame: the local level at the navigator's indicated position;
* Σ_M, the actual platform: the frame the computed attitude takes for local level,
  ``C_B^M = C_NED_TO_UEN Ĉ_B^N`` (Ĉ the navigator's attitude). Its inertial rate in its own
  axes is the computer frame's rate (eq. (47)'s brackets, components taken over unrotated, the
  point of eqs. (43)–(45)) plus the drift ``ε^M = -C_B^M δω^b`` of the gyro errors
  ``δω^b = ω̃_ib^b - ω_ib^b`` (measured minus true, body axes).

Since ``C_B^M = H C_B^P`` with ``C_B^P = C_NED_TO_UEN C_B^N(true)``, the drift is
``ε^M = -H d^P`` with ``d^P = C_B^P δω^b`` the gyro error resolved in the true local level, and
``H^T ε^M = -d^P`` enters γ^P (eq. (50)) without H. The inputs are arrays: the true and the
indicated latitude, longitude and their rates on a time grid (interpolated with cubic Hermite
splines, so the rates are the derivatives of the positions between samples) and the
cumulative gyro error angle ``D^P(t) = ∫ d^P dt`` (a cubic spline whose derivative is d^P).

Three integrators of the same model, the ``method`` of :func:`integrate_orientation` (scipy
``solve_ivp``, DOP853):

* ``young``: the Euler angles θ by eq. (51) (singular at θ2 = ±90°);
* ``young_dcm``: H itself by ``Ḣ = Δ^M H - H Ψ^P`` (eqs. (29), (48)), θ by eq. (28) at the
  output times — the same physics without eqs. (30), (31), (50), (51);
* ``phi_angle``: the small-angle (linear) limit, the phi-angle model
  ``θ̇ = -ψ^P × θ + (δ_0^M - ψ^P) - d^P`` (Titterton & Weston 2004 §12.2; Savage 2000 §12).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicHermiteSpline, CubicSpline, PPoly

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import OMEGA_IE
from strapdown_ros.core.young import (
    C_NED_TO_UEN,
    frame_rates,
    young_angle_rates,
    young_angles_from_dcm,
    young_dcm,
    young_operator,
)

__all__ = [
    "METHODS",
    "FrameTrack",
    "OrientationInputs",
    "OrientationSolution",
    "drift_in_platform",
    "integrate_orientation",
    "phi_angle_rates",
    "wrap_angle",
]


#: Default tolerances of the integrators (DOP853): θ to about 1e-11 rad over hours.
RTOL = 1e-11
ATOL = 1e-13


def wrap_angle(a: ArrayLike) -> F64:
    """Angles (rad) wrapped into [-π, π)."""
    a = np.asarray(a, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _strictly_increasing(t: F64, name: str) -> None:
    if t.ndim != 1 or t.shape[0] < 2:
        raise ValueError(f"{name}: need a 1-D time grid of at least 2 samples, got {t.shape}")
    if not np.all(np.diff(t) > 0):
        raise ValueError(f"{name}: times must be strictly increasing")


@dataclass(frozen=True)
class FrameTrack:
    """The path of a local-level frame: geodetic latitude, longitude and their rates.

    Attributes
    ----------
    t : array (K,)
        Time (s), strictly increasing.
    lat, lon : arrays (K,)
        Geodetic latitude φ and longitude λ (rad); lon continuous (unwrapped) or wrapped, the
        spline is built on the unwrapped values.
    lat_rate, lon_rate : arrays (K,)
        φ̇, λ̇ (rad/s), e.g. ``v_N / (R_N + h)``, ``v_E / ((R_E + h) cos φ)``.
    """

    t: F64
    lat: F64
    lon: F64
    lat_rate: F64
    lon_rate: F64

    def __post_init__(self) -> None:
        for name in ("t", "lat", "lon", "lat_rate", "lon_rate"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.ndim != 1 or (name != "t" and a.shape != np.shape(self.t)):
                raise ValueError(f"FrameTrack.{name}: expected shape {np.shape(self.t)}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"FrameTrack.{name}: non-finite values")
            object.__setattr__(self, name, a)
        _strictly_increasing(self.t, "FrameTrack.t")

    def splines(self, interpolation: str = "spline") -> tuple[PPoly, PPoly, PPoly]:
        """(φ(t), φ̇(t), λ̇(t)) as piecewise cubics.

        ``"spline"``: a C² cubic spline through the positions only (the rates are its
        derivatives; right for any navigator, whose position increments the frame's rate
        integrates to, e.g. the paper mode's Euler steps); ``"hermite"``: cubic Hermite on the
        positions and the given rates (C¹; for a navigator whose rates are the derivatives of
        its positions).
        """
        lon = np.unwrap(self.lon)
        if interpolation == "spline":
            lat_s: PPoly = CubicSpline(self.t, self.lat)
            lon_s: PPoly = CubicSpline(self.t, lon)
        elif interpolation == "hermite":
            lat_s = CubicHermiteSpline(self.t, self.lat, self.lat_rate)
            lon_s = CubicHermiteSpline(self.t, lon, self.lon_rate)
        else:
            raise ValueError(f"interpolation must be 'spline' or 'hermite', got {interpolation!r}")
        return lat_s, lat_s.derivative(), lon_s.derivative()


@dataclass(frozen=True)
class OrientationInputs:
    """What eq. (51) needs along a run.

    Attributes
    ----------
    true : FrameTrack
        The true position: the ideal platform Σ_P (ψ^P, eq. (39)).
    indicated : FrameTrack
        The navigator's indicated position: the computer frame Σ_C (δ^M, eq. (47)).
    drift_t : array (J,) or None
        Times (s) of ``drift_angle_p``.
    drift_angle_p : array (J, 3) or None
        Cumulative gyro error angle ``D^P(t) = ∫ C_B^P δω^b dt`` (rad) in the true local level
        (up, east, north); None: perfect gyros.
    omega : float
        Earth rate Ω_e (rad/s).
    interpolation : str
        How the tracks are interpolated (:meth:`FrameTrack.splines`), default ``"spline"``.
    """

    true: FrameTrack
    indicated: FrameTrack
    drift_t: F64 | None = None
    drift_angle_p: F64 | None = None
    omega: float = OMEGA_IE
    interpolation: str = "spline"

    def __post_init__(self) -> None:
        if (self.drift_t is None) != (self.drift_angle_p is None):
            raise ValueError("OrientationInputs: give both drift_t and drift_angle_p, or neither")
        if self.drift_t is not None:
            t = np.asarray(self.drift_t, dtype=np.float64)
            d = np.asarray(self.drift_angle_p, dtype=np.float64)
            _strictly_increasing(t, "OrientationInputs.drift_t")
            if d.shape != t.shape + (3,) or not np.all(np.isfinite(d)):
                raise ValueError(
                    f"OrientationInputs.drift_angle_p: expected finite values of shape "
                    f"{t.shape + (3,)}, got {d.shape}"
                )
            object.__setattr__(self, "drift_t", t)
            object.__setattr__(self, "drift_angle_p", d)

    @property
    def span(self) -> tuple[float, float]:
        """The time span covered by every input (s)."""
        lo = max(self.true.t[0], self.indicated.t[0])
        hi = min(self.true.t[-1], self.indicated.t[-1])
        if self.drift_t is not None:
            lo, hi = max(lo, self.drift_t[0]), min(hi, self.drift_t[-1])
        return float(lo), float(hi)

    def rates(self) -> Callable[[float], tuple[F64, F64, F64]]:
        """The rates at time t: ``f(t) -> (δ_0^M, ψ^P, d^P)``.

        The commanded rates (eq. (47) without ε), the ideal frame's rates (eq. (39)) and the
        gyro error in Σ_P axes, rad/s.
        """
        tl, tdl, tdn = self.true.splines(self.interpolation)
        il, idl, idn = self.indicated.splines(self.interpolation)
        omega = self.omega
        if self.drift_t is None:
            drift = None
        else:
            drift = CubicSpline(self.drift_t, self.drift_angle_p, axis=0).derivative()
        zero = np.zeros(3)

        def f(t: float) -> tuple[F64, F64, F64]:
            delta0 = frame_rates(il(t), idl(t), idn(t), omega)
            psi = frame_rates(tl(t), tdl(t), tdn(t), omega)
            return delta0, psi, (zero if drift is None else drift(t))

        return f


def drift_in_platform(c_b_n_true: ArrayLike, drift_b: ArrayLike) -> F64:
    """Gyro errors (body FRD) in the true (up, east, north) local level.

    ``d^P = C_NED_TO_UEN C_B^N(true) δω^b``; the drift of eq. (44) in Σ_M axes is
    ``ε^M = -H d^P``.
    """
    c = np.asarray(c_b_n_true, dtype=np.float64)
    d = np.asarray(drift_b, dtype=np.float64)
    return np.einsum("ij,...jk,...k->...i", C_NED_TO_UEN, c, d)


@dataclass(frozen=True)
class OrientationSolution:
    """Integrated orientation error.

    Attributes
    ----------
    t : array (K,)
        Output times (s).
    theta : array (K, 3)
        Young angles (θ1 up, θ2 east, θ3 north), rad; θ1, θ3 continuous (not wrapped).
    nfev : int
        Right-hand-side evaluations.
    """

    t: F64
    theta: F64
    nfev: int


def _solve(
    rhs: Callable[[float, F64], F64],
    y0: F64,
    t_eval: F64,
    rtol: float,
    atol: float,
    max_step: float,
) -> tuple[F64, int]:
    sol = solve_ivp(
        rhs,
        (float(t_eval[0]), float(t_eval[-1])),
        y0,
        method="DOP853",
        t_eval=t_eval,
        rtol=rtol,
        atol=atol,
        max_step=max_step,
    )
    if not sol.success:
        raise RuntimeError(f"orientation error integration failed: {sol.message}")
    return sol.y.T, int(sol.nfev)


def _times(inputs: OrientationInputs, t_eval: ArrayLike | None) -> F64:
    lo, hi = inputs.span
    t = inputs.indicated.t if t_eval is None else np.asarray(t_eval, dtype=np.float64)
    t = t[(t >= lo) & (t <= hi)] if t_eval is None else t
    _strictly_increasing(t, "t_eval")
    if t[0] < lo - 1e-9 or t[-1] > hi + 1e-9:
        raise ValueError(f"t_eval [{t[0]}, {t[-1]}] s is outside the inputs' span [{lo}, {hi}] s")
    return t


def phi_angle_rates(
    theta: ArrayLike, delta0_m: ArrayLike, psi_p: ArrayLike, drift_p: ArrayLike
) -> F64:
    """Small-angle limit of eq. (51): ``θ̇ = -ψ^P × θ + (δ_0^M - ψ^P) - d^P`` (rad/s).

    The phi-angle error equation ``φ̇ = -ω_in × φ + δω_in - C_b^n δω_ib^b`` in (up, east, north)
    axes: ψ^P = ω_in (true position), δ_0^M - ψ^P = δω_in (indicated minus true frame rate),
    d^P = C_b^n δω_ib^b. Eq. (51) minus this is of second order in θ and δω_in.
    """
    theta = np.asarray(theta, dtype=np.float64)
    psi = np.asarray(psi_p, dtype=np.float64)
    return -np.cross(psi, theta) + (np.asarray(delta0_m) - psi) - np.asarray(drift_p)


#: The integrators of :func:`integrate_orientation` (module docstring).
METHODS = ("young", "young_dcm", "phi_angle")


def _young_rhs(f: Callable[[float], tuple[F64, F64, F64]]) -> Callable[[float, F64], F64]:
    """θ̇ by eq. (51) with ``δ^M = δ_0^M - H(θ) d^P``."""

    def rhs(tt: float, th: F64) -> F64:
        delta0, psi, d_p = f(tt)
        return young_angle_rates(th, delta0 - young_dcm(th) @ d_p, psi)

    return rhs


def _young_dcm_rhs(f: Callable[[float], tuple[F64, F64, F64]]) -> Callable[[float, F64], F64]:
    """``Ḣ = Δ^M H - H Ψ^P`` (H flattened) with ``Δ^M = young_operator(δ_0^M - H d^P)``."""

    def rhs(tt: float, y: F64) -> F64:
        h = y.reshape(3, 3)
        delta0, psi, d_p = f(tt)
        return (young_operator(delta0 - h @ d_p) @ h - h @ young_operator(psi)).ravel()

    return rhs


def _phi_angle_rhs(f: Callable[[float], tuple[F64, F64, F64]]) -> Callable[[float, F64], F64]:
    """θ̇ of the phi-angle model :func:`phi_angle_rates`."""

    def rhs(tt: float, th: F64) -> F64:
        return phi_angle_rates(th, *f(tt))

    return rhs


def integrate_orientation(
    inputs: OrientationInputs,
    theta0: ArrayLike,
    t_eval: ArrayLike | None = None,
    *,
    method: str = "young",
    rtol: float = RTOL,
    atol: float = ATOL,
    max_step: float = np.inf,
) -> OrientationSolution:
    """θ(t) from θ(t_eval[0]) = ``theta0`` (rad) by one of :data:`METHODS`.

    * ``"young"``: Young 1980 eqs. (51a)–(51c), ``δ^M = δ_0^M + ε^M`` with ``ε^M = -H(θ) d^P``
      (module docstring); singular at θ2 = ±90°.
    * ``"young_dcm"``: H integrated directly, ``Ḣ = Δ^M H - H Ψ^P`` (eqs. (29), (48)), with the
      Young operators (eq. (8)) ``Δ^M = young_operator(δ_0^M - H d^P)``, ``Ψ^P =
      young_operator(ψ^P)``; θ by eq. (28) inverted at the output times. No Euler-angle
      kinematics (eqs. (30), (31), (50), (51)) and no singularity: a check of those equations
      and an oracle for θ2 near ±90°. θ1 and θ3 are unwrapped along the output.
    * ``"phi_angle"``: the linear (phi-angle) model :func:`phi_angle_rates`.

    ``t_eval``: output times (default: the indicated track's times within the inputs' span);
    the first is the start.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r} is not one of {', '.join(METHODS)}")
    t = _times(inputs, t_eval)
    f = inputs.rates()
    th0 = np.asarray(theta0, dtype=np.float64)
    if method != "young_dcm":
        rhs = _young_rhs(f) if method == "young" else _phi_angle_rhs(f)
        y, nfev = _solve(rhs, th0, t, rtol, atol, max_step)
        return OrientationSolution(t, y, nfev)
    y, nfev = _solve(_young_dcm_rhs(f), young_dcm(th0).ravel(), t, rtol, atol, max_step)
    theta = young_angles_from_dcm(y.reshape(-1, 3, 3))
    for i in (0, 2):  # continuous, starting at θ0's branch
        theta[:, i] = np.unwrap(theta[:, i])
        theta[:, i] += 2.0 * np.pi * np.round((th0[i] - theta[0, i]) / (2.0 * np.pi))
    return OrientationSolution(t, theta, nfev)
