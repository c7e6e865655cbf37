"""Magnetometer: a geomagnetic main-field model rotated into the body, plus sensor errors.

``m̃^B = S (C_N^B B^N) + b_hi + n``: the model field ``B^N`` (NED) at the sensor's position
rotated by the true attitude, a soft-iron matrix S, a hard-iron offset ``b_hi`` and white
noise, body FRD. :func:`igrf_field_ned` is a vectorized spherical-harmonic synthesis of a
Gauss-coefficient model (IGRF; the coefficients are plain arrays supplied by the caller, see
``docs/aiding.md``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.aiding.common import (
    check_period,
    mat_t_vec,
    mat_vec,
    per_axis,
    sensor_rng,
)
from strapdown_ros.core.array_types import F64

__all__ = [
    "IGRF_REFERENCE_RADIUS_M",
    "MAG_NORMALS_PER_EPOCH",
    "MagnetometerErrorModel",
    "MagnetometerErrors",
    "field_body",
    "igrf_field_ned",
]


#: Reference radius a of the IGRF / WMM spherical-harmonic expansions (6371.2 km).
IGRF_REFERENCE_RADIUS_M = 6371200.0

#: Standard normals per epoch: white 3.
MAG_NORMALS_PER_EPOCH = 3


@functools.lru_cache(maxsize=4)
def _recursion_factors(nmax: int) -> tuple[F64, F64, F64]:
    """Factors of the Schmidt semi-normalized recursions up to degree ``nmax``.

    ``P_n^m = a1 cos θ P_{n−1}^m − a2 P_{n−2}^m`` (m < n) with
    ``a1 = (2n − 1)/√(n² − m²)``, ``a2 = √((n − 1)² − m²)/√(n² − m²)``; ``P_n^n = d_n sin θ
    P_{n−1}^{n−1}`` with ``d_1 = 1``, ``d_n = √((2n − 1)/(2n))``.
    """
    a1 = np.zeros((nmax + 1, nmax + 1))
    a2 = np.zeros((nmax + 1, nmax + 1))
    diag = np.ones(nmax + 1)
    for n in range(1, nmax + 1):
        if n > 1:
            diag[n] = np.sqrt((2.0 * n - 1.0) / (2.0 * n))
        for m in range(n):
            a1[n, m] = (2.0 * n - 1.0) / np.sqrt(n * n - m * m)
            if n - 2 >= m:
                a2[n, m] = np.sqrt((n - 1.0) ** 2 - m * m) / np.sqrt(n * n - m * m)
    return a1, a2, diag


def longitude_multiples(cos_lon: object, sin_lon: object, cm: F64, sm: F64) -> None:
    """``cos mλ``, ``sin mλ`` into ``cm``, ``sm`` (m = 0..N on their first axis), in place.

    The angle-addition recursion from ``cos λ``, ``sin λ``: for arrays of points here, for one
    point in the compiled filter (:mod:`strapdown_ros.core.aided._fields`, the same arithmetic).
    """
    cm[0], sm[0] = 1.0, 0.0
    if cm.shape[0] > 1:
        cm[1], sm[1] = cos_lon, sin_lon
    for m in range(2, cm.shape[0]):
        cm[m] = cm[m - 1] * cm[1] - sm[m - 1] * sm[1]
        sm[m] = sm[m - 1] * cm[1] + cm[m - 1] * sm[1]


def igrf_field_ned(
    r_e: ArrayLike, lat: ArrayLike, g: ArrayLike, h: ArrayLike,
    radius_m: float = IGRF_REFERENCE_RADIUS_M,
) -> F64:  # fmt: skip
    """Main-field vector (nT) in the geodetic NED frame at ECEF positions.

    ``V = a Σ_n (a/r)^{n+1} Σ_m (g_n^m cos mλ + h_n^m sin mλ) P_n^m(cos θ)`` with Schmidt
    semi-normalized associated Legendre functions, ``B = −∇V`` in geocentric spherical
    components (θ geocentric colatitude, λ longitude, r radius of ``r_e``), then rotated from
    the geocentric to the geodetic local level by ``δ = φ − φ_gc``.

    Parameters
    ----------
    r_e : (n, 3)
        ECEF positions, m.
    lat : (n,)
        Their geodetic latitudes φ, rad (for the rotation to geodetic north/down).
    g, h : (N+1, N+1)
        Gauss coefficients ``g[n, m]``, ``h[n, m]`` (nT) at the epoch of interest; ``[0, 0]``
        and ``h[n, 0]`` ignored.
    radius_m : float
        Reference radius a of the expansion.

    Returns
    -------
    (n, 3)
        ``B^N = (X north, Y east, Z down)``, nT.
    """
    r_e = np.asarray(r_e, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    nmax = g.shape[0] - 1
    a1, a2, diag = _recursion_factors(nmax)
    x, y, z = r_e[:, 0], r_e[:, 1], r_e[:, 2]
    p = np.hypot(x, y)
    r = np.hypot(p, z)
    ct, st = z / r, p / r  # geocentric colatitude θ: cos θ, sin θ
    lon = np.arctan2(y, x)
    ratio = radius_m / r
    npts = r.shape[0]
    cm = np.empty((nmax + 1, npts))
    sm = np.empty((nmax + 1, npts))
    longitude_multiples(np.cos(lon), np.sin(lon), cm, sm)
    # P_n^m and dP_n^m/dθ for m = 0..n, one degree at a time (vectorized over m and points).
    pnm = np.zeros((nmax + 1, nmax + 1, npts))
    dnm = np.zeros((nmax + 1, nmax + 1, npts))
    pnm[0, 0] = 1.0
    bx = np.zeros(npts)  # X_gc = -B_θ
    by = np.zeros(npts)  # Y = B_λ (times sin θ until the end)
    bz = np.zeros(npts)  # Z_gc = -B_r
    rr = ratio * ratio
    orders = np.arange(nmax + 1, dtype=np.float64)[:, None]
    for n in range(1, nmax + 1):
        rr = rr * ratio  # (a/r)^{n+2}
        k = slice(0, n)  # m < n
        pnm[n, k] = a1[n, k, None] * ct * pnm[n - 1, k]
        dnm[n, k] = a1[n, k, None] * (ct * dnm[n - 1, k] - st * pnm[n - 1, k])
        if n >= 2:
            pnm[n, k] -= a2[n, k, None] * pnm[n - 2, k]
            dnm[n, k] -= a2[n, k, None] * dnm[n - 2, k]
        pnm[n, n] = diag[n] * st * pnm[n - 1, n - 1]
        dnm[n, n] = diag[n] * (st * dnm[n - 1, n - 1] + ct * pnm[n - 1, n - 1])
        m = slice(0, n + 1)
        gc = g[n, m, None] * cm[m] + h[n, m, None] * sm[m]
        gs = g[n, m, None] * sm[m] - h[n, m, None] * cm[m]
        # Sums over m as running sums (add.accumulate is sequential, so each point's sum has
        # the same order whatever npts; .sum() may sum pairwise when npts = 1).
        bx = bx + rr * np.cumsum(gc * dnm[n, m], axis=0)[-1]
        bz = bz - rr * (n + 1.0) * np.cumsum(gc * pnm[n, m], axis=0)[-1]
        by = by + rr * np.cumsum(orders[m] * gs * pnm[n, m], axis=0)[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        by = np.where(st > 0, by / np.where(st > 0, st, 1.0), 0.0)
    # Geocentric -> geodetic local level: rotate (X, Z) by δ = φ - φ_gc about east.
    lat = np.asarray(lat, dtype=np.float64)
    delta = lat - np.arctan2(z, p)
    cd, sd = np.cos(delta), np.sin(delta)
    north = bx * cd + bz * sd
    down = bz * cd - bx * sd
    return np.stack([north, by, down], axis=-1)


def field_body(c_b_n: ArrayLike, field_ned: ArrayLike) -> F64:
    """``C_N^B B^N = (C_B^N)ᵀ B^N`` (n, 3): the field in body axes, element-wise sums."""
    return mat_t_vec(np.asarray(c_b_n, dtype=np.float64), np.asarray(field_ned, dtype=np.float64))


@dataclass(frozen=True)
class MagnetometerErrors:
    """Magnetometer errors, body FRD, tesla.

    ``hard_iron`` fixed offset (3,); ``hard_iron_sigma`` σ of an offset drawn per run (3,);
    ``soft_iron`` the 3×3 matrix S (identity: none); ``white`` noise σ per axis (3,).
    """

    hard_iron: F64 = per_axis()
    hard_iron_sigma: F64 = per_axis()
    soft_iron: F64 = field(default_factory=partial(np.eye, 3))
    white: F64 = per_axis()

    @property
    def variance(self) -> F64:
        """Variance of one message's random error per FRD axis (T²): white²."""
        return np.asarray(self.white) ** 2


class MagnetometerErrorModel:
    """Seeded magnetometer errors at consecutive epochs (chunk-invariant).

    3 normals at construction (hard iron), :data:`MAG_NORMALS_PER_EPOCH` per epoch.
    """

    def __init__(self, errors: MagnetometerErrors, period_s: float, seed: int) -> None:
        self.errors = errors
        self.period_s = check_period(period_s)
        self._rng = sensor_rng(seed, "magnetometer")
        init = self._rng.standard_normal(3)
        self.hard_iron = np.asarray(errors.hard_iron) + np.asarray(errors.hard_iron_sigma) * init
        self._soft = np.asarray(errors.soft_iron, dtype=np.float64)
        self._identity = bool(np.array_equal(self._soft, np.eye(3)))
        self.epochs = 0

    def apply(self, field_b: ArrayLike) -> F64:
        """Measured field (n, 3) of the true body field (n, 3) at the next n epochs (T, FRD)."""
        b = np.asarray(field_b, dtype=np.float64)
        n = b.shape[0]
        z = self._rng.standard_normal((n, MAG_NORMALS_PER_EPOCH))
        soft = b if self._identity else mat_vec(np.broadcast_to(self._soft, (n, 3, 3)), b)
        self.epochs += n
        return soft + (self.hard_iron + np.asarray(self.errors.white) * z)

    def skip(self, n: int) -> None:
        """Advance over ``n`` epochs without output (random state)."""
        if n > 0:
            self._rng.standard_normal((n, MAG_NORMALS_PER_EPOCH))
            self.epochs += n
