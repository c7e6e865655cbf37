"""Compiled Earth fields at one point for the aided filter.

Geodetic coordinates, local level, gravitation gradient, ICAO pressure (and its slope), IGRF
main field.

Scalar (numba) counterparts of the vectorized functions the simulation uses, so that the filter
predicts exactly what the sensors were made from:

* :func:`ecef_to_geodetic1` — Bowring's estimate and two Newton steps, as
  :func:`strapdown_ros.core.earth.ecef_to_geodetic` (float64 here);
* :func:`ecef_to_ned1` — ``C_E^N`` (rows north, east, down in ECEF), as
  :func:`~strapdown_ros.core.earth.dcm_ecef_to_ned`;
* :func:`gravitation_gradient` — ``∂g/∂R`` of the stream's gravitation model by central
  differences of :func:`strapdown_ros.core.navigation._kernels._gravitation` (10 m steps:
  truncation and rounding both below 1e-12 relative);
* :func:`icao_pressure1` — ICAO Standard Atmosphere pressure and ``dp/dh`` at a geometric
  altitude, the layers of :mod:`strapdown_ros.core.aiding.baro`; ``dp/dH = -g₀ p / (R T(H))``
  (hydrostatic equation), ``dH/dh = r₀² / (r₀ + h)²``;
* :func:`igrf_ned1` — the spherical-harmonic synthesis of
  :func:`strapdown_ros.core.aiding.magnetometer.igrf_field_ned` for one point.
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aided._jit import jit
from strapdown_ros.core.aiding import baro as _baro
from strapdown_ros.core.aiding.magnetometer import longitude_multiples
from strapdown_ros.core.earth import (
    A_WGS84,
    B_WGS84,
    E2_WGS84,
    EP2_WGS84,
    latitude_newton_step,
)
from strapdown_ros.core.navigation._kernels import _gravitation

__all__ = [
    "ecef_to_geodetic1",
    "ecef_to_ned1",
    "gravitation_gradient",
    "icao_pressure1",
    "igrf_ned1",
]

_H_B, _BETA, _T_B, _P_B = (np.ascontiguousarray(a, dtype=np.float64) for a in _baro._BASES)
_G0, _R_AIR, _R0 = _baro.G0, _baro.R_AIR, _baro.R0_M
_latitude_newton_step = jit(latitude_newton_step)


@jit
def ecef_to_geodetic1(x, y, z):
    """Geodetic latitude, longitude (rad) and ellipsoidal altitude (m) of an ECEF point."""
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    u, w = A_WGS84 * z, B_WGS84 * p
    d = math.hypot(u, w)
    st, ct = (u / d, w / d) if d > 0 else (0.0, 1.0)
    lat = math.atan2(z + EP2_WGS84 * B_WGS84 * st**3, p - E2_WGS84 * A_WGS84 * ct**3)
    for _ in range(2):
        lat = _latitude_newton_step(lat, math.sin(lat), math.cos(lat), p, z, A_WGS84, E2_WGS84)
    s, c = math.sin(lat), math.cos(lat)
    alt = p * c + z * s - A_WGS84 * math.sqrt(1.0 - E2_WGS84 * s * s)
    return lat, lon, alt


@jit
def ecef_to_ned1(lat, lon):
    """``C_E^N`` (3, 3) at geodetic latitude and longitude (rad): rows north, east, down."""
    sp, cp, sl, cl = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    m = np.empty((3, 3))
    m[0, 0], m[0, 1], m[0, 2] = -sp * cl, -sp * sl, cp
    m[1, 0], m[1, 1], m[1, 2] = -sl, cl, 0.0
    m[2, 0], m[2, 1], m[2, 2] = -cp * cl, -cp * sl, -sp
    return m


@jit
def gravitation_gradient(r, model):
    """``G = ∂g/∂R`` (3, 3) at ``r`` (E0 or E, m): central differences with 10 m steps."""
    h = 10.0
    out = np.empty((3, 3))
    for j in range(3):
        rp = r.copy()
        rm = r.copy()
        rp[j] += h
        rm[j] -= h
        gp = _gravitation(rp[0], rp[1], rp[2], model)
        gm = _gravitation(rm[0], rm[1], rm[2], model)
        out[0, j] = (gp[0] - gm[0]) / (2.0 * h)
        out[1, j] = (gp[1] - gm[1]) / (2.0 * h)
        out[2, j] = (gp[2] - gm[2]) / (2.0 * h)
    return out


@jit
def icao_pressure1(h):
    """ICAO pressure (Pa) at geometric altitude ``h`` (m) and its slope ``dp/dh`` (Pa/m)."""
    hp = _R0 * h / (_R0 + h)
    i = 0
    for k in range(1, _H_B.shape[0]):
        if hp >= _H_B[k]:
            i = k
    beta, hb, tb, pb = _BETA[i], _H_B[i], _T_B[i], _P_B[i]
    if beta == 0.0:
        p = pb * math.exp(-_G0 * (hp - hb) / (_R_AIR * tb))
        t = tb
    else:
        p = pb * (1.0 + beta * (hp - hb) / tb) ** (-_G0 / (beta * _R_AIR))
        t = tb + beta * (hp - hb)
    dh = _R0 * _R0 / ((_R0 + h) * (_R0 + h))
    return p, -_G0 * p / (_R_AIR * t) * dh


_longitude_multiples = jit(longitude_multiples)


@jit
def igrf_ned1(x, y, z, lat, g, h, a1, a2, diag, radius):
    """Main field (nT) in NED at ECEF ``(x, y, z)`` with geodetic latitude ``lat``.

    ``g``, ``h`` Gauss coefficients (N+1, N+1); ``a1``, ``a2``, ``diag`` the Schmidt
    recursion factors of ``core.aiding.magnetometer._recursion_factors(N)``; ``radius`` the
    reference radius (m). The same expansion as ``igrf_field_ned`` (one point).
    """
    nmax = g.shape[0] - 1
    p = math.hypot(x, y)
    r = math.hypot(p, z)
    ct, st = z / r, p / r
    lon = math.atan2(y, x)
    ratio = radius / r
    cm = np.empty(nmax + 1)
    sm = np.empty(nmax + 1)
    _longitude_multiples(math.cos(lon), math.sin(lon), cm, sm)
    pnm = np.zeros((nmax + 1, nmax + 1))
    dnm = np.zeros((nmax + 1, nmax + 1))
    pnm[0, 0] = 1.0
    bx = by = bz = 0.0
    rr = ratio * ratio
    for n in range(1, nmax + 1):
        rr = rr * ratio
        for m in range(n):
            pnm[n, m] = a1[n, m] * ct * pnm[n - 1, m]
            dnm[n, m] = a1[n, m] * (ct * dnm[n - 1, m] - st * pnm[n - 1, m])
            if n >= 2:
                pnm[n, m] -= a2[n, m] * pnm[n - 2, m]
                dnm[n, m] -= a2[n, m] * dnm[n - 2, m]
        pnm[n, n] = diag[n] * st * pnm[n - 1, n - 1]
        dnm[n, n] = diag[n] * (st * dnm[n - 1, n - 1] + ct * pnm[n - 1, n - 1])
        sx = sy = sz = 0.0
        for m in range(n + 1):
            gc = g[n, m] * cm[m] + h[n, m] * sm[m]
            gs = g[n, m] * sm[m] - h[n, m] * cm[m]
            sx += gc * dnm[n, m]
            sz += gc * pnm[n, m]
            sy += m * gs * pnm[n, m]
        bx += rr * sx
        bz -= rr * (n + 1.0) * sz
        by += rr * sy
    if st > 0:
        by = by / st
    else:
        by = 0.0
    delta = lat - math.atan2(z, p)
    cd, sd = math.cos(delta), math.sin(delta)
    return bx * cd + bz * sd, by, bz * cd - bx * sd
