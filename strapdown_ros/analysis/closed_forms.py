"""Closed-form error propagation of a stationary free-inertial navigator (linear, first order).

The psi-angle form of the error equations (Benson 1975; Savage 2000, *Strapdown Analytics*
§12; Titterton & Weston 2004 §12.3) separates the attitude from the position errors of a
navigator at rest at latitude L (NED axes, errors of the computed frame):

* ψ̇ = -Ω × ψ - ε: the attitude error ψ of the computed attitude relative to the local level
  at the *indicated* position turns about the Earth's axis (Ω = Ω_ie (cos L, 0, -sin L)) under
  the gyro error ε = C_b^n δω_ib^b. For constant ε, with u = Ω/|Ω|:
  ``ψ(t) = R(t) ψ0 - [ε∥ t + ε⊥ sin(Ωt)/Ω - (u × ε)(1 - cos Ωt)/Ω]``,
  ``R(t) v = v∥ + v⊥ cos Ωt - (u × v) sin Ωt`` (the 24-hour terms);
* the horizontal position error z = δr_N + i δr_E (m) obeys the Schuler oscillator with the
  Coriolis (Foucault) coupling of the vertical Earth rate Ω_z = Ω sin L:
  ``z̈ - 2iΩ_z ż + ω_s² z = g (ψ_E - i ψ_N) + ∇_N + i ∇_E`` (∇ = C_b^n δf, the
  accelerometer error; the -ψ × f term with f = (0, 0, -g)). Its solution for forcing
  ``Σ (c_k + d_k t) e^{iν_k t}`` is closed form: particular terms
  ``c/D(ν) e^{iνt}`` and ``d/D(ν) (t - 2i(ν - Ω_z)/D(ν)) e^{iνt}`` with
  ``D(ν) = ω_s² + 2Ω_z ν - ν²``, plus the free modes ``e^{iΩ_z t} (A e^{iω_f t} + B e^{-iω_f t})``,
  ``ω_f = √(ω_s² + Ω_z²)`` (Schuler at 84.4 min, its plane turning at the Foucault rate);
* the attitude error relative to the *true* local level is φ = ψ + δθ, δθ the tilt of the
  indicated local level: ``δθ = (δr_E / R_E, -δr_N / R_N, -δr_E tan L / R_E)`` (R + h);
  Young's angles are φ in (up, east, north): ``θ = (-φ_D, φ_E, φ_N)``.

Special cases (zero initial errors): a north accelerometer bias b gives
``δr_N = b/ω_s² (1 - cos ω_s t)`` and ``θ2 = -b/g (1 - cos ω_s t)`` without Earth rate; an east
gyro bias ε_E gives ``δr_N = -R ε_E (t - sin(ω_s t)/ω_s)`` and ``θ2 = -ε_E sin(ω_s t)/ω_s``
for t ≪ 24 h (Titterton & Weston 2004 §12.3.4, Groves 2013 §14.2). The functions below keep the
Foucault and 24-hour terms. Assumptions: the vertical channel is decoupled (damped), one
Schuler frequency ω_s² = g / √(R_N R_E) for both channels, first order in the errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import OMEGA_IE, radii
from strapdown_ros.core.gravity import gravity_ned

__all__ = [
    "StaticErrors",
    "StaticSite",
    "horizontal_frequencies",
    "psi_angle",
    "schuler_foucault",
    "static_errors",
]

C128 = NDArray[np.complex128]


@dataclass(frozen=True)
class StaticSite:
    """Where the navigator stands: latitude (rad), altitude (m), gravity model.

    ``g`` (plumb-bob gravity magnitude, m/s²), ``r_n``, ``r_e`` (``R_N + h``, ``R_E + h``, m)
    and the Earth rate follow.
    """

    lat: float
    alt: float
    gravity_model: str = "j2"
    omega: float = OMEGA_IE

    @property
    def g(self) -> float:
        """Plumb-bob gravity magnitude (m/s²)."""
        return float(np.linalg.norm(gravity_ned(self.lat, self.alt, self.gravity_model)))

    @property
    def r_n(self) -> float:
        """``R_N + h`` (m)."""
        return float(radii(self.lat)[0]) + self.alt

    @property
    def r_e(self) -> float:
        """``R_E + h`` (m)."""
        return float(radii(self.lat)[1]) + self.alt

    @property
    def omega_s(self) -> float:
        """Schuler frequency ``√(g / √(R_N R_E))`` (rad/s)."""
        return float(np.sqrt(self.g / np.sqrt(self.r_n * self.r_e)))

    @property
    def omega_z(self) -> float:
        """Vertical Earth rate ``Ω sin L`` (rad/s)."""
        return self.omega * float(np.sin(self.lat))

    @property
    def earth_rate_ned(self) -> F64:
        """Ω_ie in NED (rad/s)."""
        return self.omega * np.array([np.cos(self.lat), 0.0, -np.sin(self.lat)])


def psi_angle(
    site: StaticSite, gyro_ned: ArrayLike = (0, 0, 0), psi0_ned: ArrayLike = (0, 0, 0)
) -> tuple[F64, F64, F64, F64]:
    """ψ(t) = a0 + a1 t + ac cos Ωt + as sin Ωt of ``ψ̇ = -Ω × ψ - ε`` (NED, rad).

    Returns the four coefficient vectors ``(a0, a1, ac, as)`` (rad, rad/s, rad, rad) for the
    constant gyro error ``gyro_ned`` ε (rad/s) and the initial ``psi0_ned``.
    """
    w = site.omega
    u = site.earth_rate_ned / w
    eps = np.asarray(gyro_ned, dtype=np.float64)
    p0 = np.asarray(psi0_ned, dtype=np.float64)
    e_par = u * (u @ eps)
    p_par = u * (u @ p0)
    # R(t)ψ0 = ψ0∥ + ψ0⊥ cos Ωt - (u × ψ0) sin Ωt, and the forced part
    # -[ε∥ t + ε⊥ sin Ωt / Ω - (u × ε)(1 - cos Ωt) / Ω]
    a0 = p_par + np.cross(u, eps) / w
    a1 = -e_par
    ac = (p0 - p_par) - np.cross(u, eps) / w
    as_ = -np.cross(u, p0) - (eps - e_par) / w
    return a0, a1, ac, as_


def horizontal_frequencies(site: StaticSite) -> tuple[float, float]:
    """The two horizontal free-mode frequencies ω1 > ω2 (rad/s).

    Roots of ``(s² + ω_N²)(s² + ω_E²) + 4 Ω_z² s² = 0`` (s = iω), ω_N² = g/R_N, ω_E² = g/R_E:
    ``ω² = (Σ ± √(Σ² - 4 ω_N² ω_E²)) / 2``, Σ = ω_N² + ω_E² + 4Ω_z². For ω_N = ω_E = ω_s they
    are ``√(ω_s² + Ω_z²) ± Ω_z``: the Schuler oscillation whose plane turns at the Foucault rate.
    """
    wn2, we2 = site.g / site.r_n, site.g / site.r_e
    sig = wn2 + we2 + 4 * site.omega_z**2
    root = np.sqrt(sig**2 - 4 * wn2 * we2)
    return float(np.sqrt((sig + root) / 2)), float(np.sqrt((sig - root) / 2))


def schuler_foucault(
    t: ArrayLike,
    site: StaticSite,
    terms: list[tuple[C128, C128, complex]],
) -> tuple[F64, F64]:
    """Horizontal position and velocity errors (NED north, east) from rest with zero errors.

    ``δr̈_N = -ω_N² δr_N - 2Ω_z δṙ_E + F_N``, ``δr̈_E = -ω_E² δr_E + 2Ω_z δṙ_N + F_E`` with
    ``F = Re Σ (c + d t) e^{νt}`` (``terms``: complex 2-vectors c [m/s²], d [m/s³], complex ν
    [1/s]). Solved exactly: for x = (δr_N, δr_E, δv_N, δv_E), ẋ = A x + b, each term has the
    particular solution ``(p + q t) e^{νt}``, ``(ν - A) q = (0, d)``, ``(ν - A) p = (0, c) - q``,
    and the free part ``V e^{Λt} V⁻¹ x_h(0)`` cancels their initial values (Λ = ±iω1, ±iω2 of
    :func:`horizontal_frequencies`). Returns (position (K, 2) m, velocity (K, 2) m/s).
    """
    t = np.asarray(t, dtype=np.float64)
    wz = site.omega_z
    a = np.zeros((4, 4))
    a[0, 2] = a[1, 3] = 1.0
    a[2, 0], a[3, 1] = -site.g / site.r_n, -site.g / site.r_e
    a[2, 3], a[3, 2] = -2 * wz, 2 * wz
    x = np.zeros((t.shape[0], 4), dtype=np.complex128)
    x0 = np.zeros(4, dtype=np.complex128)
    for c, d, nu in terms:
        m = nu * np.eye(4) - a
        q = np.linalg.solve(m, np.concatenate([[0, 0], np.asarray(d, dtype=np.complex128)]))
        p = np.linalg.solve(m, np.concatenate([[0, 0], np.asarray(c, dtype=np.complex128)]) - q)
        x += (p + np.multiply.outer(t, q)) * np.exp(nu * t)[:, None]
        x0 += p
    lam, v = np.linalg.eig(a)
    coef = np.linalg.solve(v, -x0)
    x += (np.exp(np.multiply.outer(t, lam)) * coef) @ v.T
    return x.real[:, :2], x.real[:, 2:]


@dataclass(frozen=True)
class StaticErrors:
    """Closed-form errors at times ``t`` (s): ``position_ned`` (m, D = 0), ``velocity_ned``
    (m/s, D = 0), ``psi_ned`` and ``phi_ned`` (rad), ``theta_young`` (up, east, north; rad)."""

    t: F64
    position_ned: F64
    velocity_ned: F64
    psi_ned: F64
    phi_ned: F64

    @property
    def theta_young(self) -> F64:
        """Young's angles to first order: φ in (up, east, north)."""
        p = self.phi_ned
        return np.stack([-p[:, 2], p[:, 1], p[:, 0]], axis=-1)


def static_errors(
    t: ArrayLike,
    site: StaticSite,
    accel_ned: ArrayLike = (0, 0, 0),
    gyro_ned: ArrayLike = (0, 0, 0),
    psi0_ned: ArrayLike = (0, 0, 0),
) -> StaticErrors:
    """Closed-form errors of a navigator at rest with constant sensor errors (NED axes).

    ``accel_ned`` ∇ (m/s², horizontal part used), ``gyro_ned`` ε (rad/s), ``psi0_ned`` the
    initial attitude error (rad); zero initial position and velocity errors.
    """
    t = np.asarray(t, dtype=np.float64)
    g, w = site.g, site.omega
    a0, a1, ac, as_ = psi_angle(site, gyro_ned, psi0_ned)

    def f(v: F64) -> C128:  # (g ψ_E, -g ψ_N) of a ψ coefficient
        return np.array([g * v[1], -g * v[0]], dtype=np.complex128)

    acc = np.asarray(accel_ned, dtype=np.float64)[:2]
    # C cos Ωt + S sin Ωt = Re[(C - iS) e^{iΩt}]
    terms = [(f(a0) + acc, f(a1), 0j), (f(ac) - 1j * f(as_), np.zeros(2, complex), 1j * w)]
    pos, vel = schuler_foucault(t, site, terms)
    psi = (a0 + np.multiply.outer(t, a1) + np.multiply.outer(np.cos(w * t), ac)
           + np.multiply.outer(np.sin(w * t), as_))  # fmt: skip
    dn, de = pos[:, 0], pos[:, 1]
    dtheta = np.stack([de / site.r_e, -dn / site.r_n, -de * np.tan(site.lat) / site.r_e], -1)
    zeros = np.zeros_like(t)
    return StaticErrors(
        t,
        np.stack([dn, de, zeros], -1),
        np.stack([vel[:, 0], vel[:, 1], zeros], -1),
        psi,
        psi + dtheta,
    )
