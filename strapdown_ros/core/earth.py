"""WGS-84 Earth: geodetic ↔ ECEF, radii of curvature, NED frames, E ↔ E0 state conversions.

Frames (docs/interface.md §1):

* ``E`` — ECEF of WGS-84 (z along the polar axis, x in the Greenwich meridian).
* ``E0`` — the inertial frame equal to ``E`` at the trajectory start ``t0``;
  ``C_E^E0(t) = Rz(ω_ie t)`` with ``t`` in seconds since ``t0``.
* ``N`` — local-level NED (north, east, down) at a geodetic position.
* ``B`` — body FRD.

A DCM ``C_A^B`` maps coordinates in A to B: ``v^B = C_A^B v^A``. Vectors have shape
``(..., 3)``, matrices ``(..., 3, 3)``; all functions broadcast over leading axes. Angles in
rad, lengths in m, time in s. Latitude is geodetic, altitude is above the WGS-84 ellipsoid.

References: Savage 2020 (``seeds/000``) Appendix E, eqs. (E-1)–(E-8) for the E/E0/N frame
conversions; the ellipsoid formulas are the standard ones (e.g. Savage, *Strapdown Analytics*,
2nd ed., §5.2; Groves, *Principles of GNSS, Inertial and Multisensor Integrated Navigation*,
2nd ed., §2.4).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.rotations import as_matrices, as_vectors, matrix3
from strapdown_ros.core.threads import rowwise

__all__ = [
    "A_WGS84",
    "B_WGS84",
    "E2_WGS84",
    "EP2_WGS84",
    "F_WGS84",
    "GM_WGS84",
    "J2_WGS84",
    "OMEGA_IE",
    "OMEGA_IE_VEC",
    "body_rates_relative_to_earth",
    "dcm_e0_to_ecef",
    "dcm_ecef_to_e0",
    "dcm_ecef_to_ned",
    "dcm_ned_to_ecef",
    "e0_state_to_ecef",
    "ecef_state_to_e0",
    "ecef_to_geodetic",
    "ecef_velocity_from_ned",
    "geodetic_rates",
    "geodetic_to_ecef",
    "latitude_newton_step",
    "meridian_radius",
    "ned_velocity_from_ecef",
    "radii",
    "transverse_radius",
]

#: WGS-84 semi-major axis (equatorial radius), m (docs/interface.md §1).
A_WGS84 = 6378137.0
#: WGS-84 flattening (docs/interface.md §1).
F_WGS84 = 1.0 / 298.257223563
#: WGS-84 semi-minor axis (polar radius), m: ``a (1 - f)``.
B_WGS84 = A_WGS84 * (1.0 - F_WGS84)
#: WGS-84 first eccentricity squared: ``f (2 - f)``.
E2_WGS84 = F_WGS84 * (2.0 - F_WGS84)
#: WGS-84 second eccentricity squared: ``e² / (1 - e²)``.
EP2_WGS84 = E2_WGS84 / (1.0 - E2_WGS84)
#: WGS-84 Earth gravitational constant GM, m³/s² (docs/interface.md §1).
GM_WGS84 = 3.986004418e14
#: Earth rotation rate ω_ie, rad/s (docs/interface.md §1).
OMEGA_IE = 7.292115e-5
#: Second zonal harmonic J2 of the docs/interface.md §1 ``j2`` gravitation model.
J2_WGS84 = 1.08262982131e-3
#: Earth rotation vector ``ω_ie^E = ω_ie^E0`` (rad/s), along the polar axis z.
OMEGA_IE_VEC = np.array([0.0, 0.0, OMEGA_IE])
OMEGA_IE_VEC.setflags(write=False)

_NEWTON_STEPS = 2

# Extended-precision working copies for the geodetic <-> ECEF conversions. ``np.longdouble`` is
# the x87 80-bit format on x86-64 Linux (eps 1.1e-19) and IEEE binary128 on aarch64 Linux, so
# the float64 results are correctly rounded up to ~1e-3 ulp there; where ``longdouble`` is
# plain float64 (e.g. macOS arm64, Windows) the results are still accurate to a few ulp.
_LD = np.longdouble
_A_LD = _LD(A_WGS84)
_F_LD = _LD(1) / _LD("298.257223563")
_E2_LD = _F_LD * (2 - _F_LD)
_B_LD = _A_LD * (1 - _F_LD)
_EP2_LD = _E2_LD / (1 - _E2_LD)
_HALF_PI_LD = np.arctan2(_LD(1), _LD(0))


#: A state: position (..., 3), velocity (..., 3) and attitude DCM (..., 3, 3) or None.
_PosVelAtt = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]


def _f64(x: ArrayLike) -> NDArray[np.float64]:
    return np.asarray(x, dtype=np.float64)


def _mv(c: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Broadcast matrix-vector product ``c v`` for ``c`` (..., 3, 3) and ``v`` (..., 3)."""
    return (c @ v[..., None])[..., 0]


def _mtv(c: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Broadcast transposed product ``cᵀ v`` for ``c`` (..., 3, 3) and ``v`` (..., 3)."""
    return (np.swapaxes(c, -1, -2) @ v[..., None])[..., 0]


def _omega_cross(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``ω_ie × v`` for ``v`` (..., 3) in E or E0 coordinates (exact: ω_ie is along z)."""
    return np.stack([-OMEGA_IE * v[..., 1], OMEGA_IE * v[..., 0], np.zeros_like(v[..., 2])], -1)


# --------------------------------------------------------------------------------------------
# Geodetic <-> ECEF
# --------------------------------------------------------------------------------------------


def geodetic_to_ecef(lat: ArrayLike, lon: ArrayLike, alt: ArrayLike) -> NDArray[np.float64]:
    """ECEF position of a geodetic position on the WGS-84 ellipsoid.

    ``x = (R_E + h) cos φ cos λ``, ``y = (R_E + h) cos φ sin λ``, ``z = (R_E (1 - e²) + h) sin φ``
    with the prime-vertical radius ``R_E = a / sqrt(1 - e² sin² φ)`` (Savage 2020 (E-3) in
    geodetic form; Groves 2013 eq. (2.112)). Evaluated in ``np.longdouble``, so each output
    coordinate is the correctly rounded float64 of the exact value (≤ 0.5 ulp ≈ 4.7e-10 m,
    measured against mpmath) where longdouble is extended precision.

    Parameters
    ----------
    lat, lon : array_like (...)
        Geodetic latitude φ and longitude λ, rad.
    alt : array_like (...)
        Altitude h above the WGS-84 ellipsoid, m.

    Returns
    -------
    ndarray (..., 3)
        Position ``r^E`` in ECEF (frame E), m. Inputs broadcast against each other.
    """
    lat, lon, alt = np.broadcast_arrays(_f64(lat), _f64(lon), _f64(alt))
    if lat.ndim == 1:  # long arrays on two threads, same bits (core/threads.py)
        return rowwise(_geodetic_to_ecef, lat, lon, alt)
    return _geodetic_to_ecef(lat, lon, alt)


def _geodetic_to_ecef(
    lat: NDArray[np.float64], lon: NDArray[np.float64], alt: NDArray[np.float64]
) -> NDArray[np.float64]:
    lat, lon, alt = lat.astype(_LD), lon.astype(_LD), alt.astype(_LD)
    s, c = np.sin(lat), np.cos(lat)
    n = _A_LD / np.sqrt(1 - _E2_LD * s * s)
    rc = (n + alt) * c
    r = np.stack([rc * np.cos(lon), rc * np.sin(lon), (n * (1 - _E2_LD) + alt) * s], -1)
    return r.astype(np.float64)


def latitude_newton_step(lat: Any, s: Any, c: Any, p: Any, z: Any, a: Any, e2: Any) -> Any:
    """One Newton step for the geodetic latitude φ of an ECEF point (:func:`ecef_to_geodetic`).

    The root of ``f(φ) = p sin φ - z cos φ - e² R_E(φ) sin φ cos φ`` from ``lat`` (rad; ``s``,
    ``c`` its sine and cosine), for the point's distance ``p`` from the polar axis and ``z``
    (m), an ellipsoid of semi-major axis ``a`` (m) and first eccentricity squared ``e2``. Plain
    arithmetic on scalars or arrays of any float type, so that the aided filter's compiled
    scalar conversion (``core.aided._fields``) takes the very same steps in float64.
    """
    w2 = 1.0 - e2 * s * s
    n = a / np.sqrt(w2)
    f = p * s - z * c - e2 * n * s * c
    # d/dφ [R_E sin φ cos φ] = R_E [(cos²φ - sin²φ) + e² sin²φ cos²φ / (1 - e² sin²φ)]
    df = p * c + z * s - e2 * n * ((c - s) * (c + s) + e2 * (s * c) ** 2 / w2)
    return lat - f / df


def ecef_to_geodetic(
    r: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Geodetic latitude, longitude and ellipsoidal altitude of an ECEF position (exact).

    Longitude is ``atan2(y, x)`` (Savage 2020 (E-7), four-quadrant). Latitude starts from
    Bowring's (1976) closed-form estimate and is refined by a fixed number (2) of vectorized
    Newton steps on ``f(φ) = p sin φ - z cos φ - e² R_E(φ) sin φ cos φ = 0`` (``p = √(x²+y²)``),
    which has no singularity at the poles or the equator; the altitude is then
    ``h = p cos φ + z sin φ - a √(1 - e² sin² φ)`` (well conditioned at every latitude). This
    solves the same equations as Savage 2020 (E-4)–(E-6). One Newton step already converges
    (Bowring's estimate is within 1e-9 rad up to 1000 km altitude); the second is margin. The
    work is done in ``np.longdouble``: where that is extended precision (x86-64/aarch64
    Linux) latitude and longitude are within 0.501 ulp of the exact values and the altitude
    within 1e-10 m (mpmath reference, ``test/test_earth.py``); in plain float64 a few ulp.
    Converged from -6000 km to 1e5 km altitude; only within ~43 km of the Earth's centre
    (the evolute of the meridian ellipse) are geodetic coordinates not unique.

    Parameters
    ----------
    r : array_like (..., 3)
        Position ``r^E`` in ECEF (frame E), m. Not at the Earth's centre.

    Returns
    -------
    lat : ndarray (...)
        Geodetic latitude φ in [-π/2, π/2], rad.
    lon : ndarray (...)
        Longitude λ in [-π, π], rad (0 on the polar axis, where it is undefined).
    alt : ndarray (...)
        Altitude h above the WGS-84 ellipsoid, m.
    """
    r = as_vectors(r).astype(_LD)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    # Bowring's estimate from the parametric latitude θ: tan θ = a z / (b p).
    u, w = _A_LD * z, _B_LD * p
    d = np.hypot(u, w)
    with np.errstate(invalid="ignore", divide="ignore"):
        st = np.where(d > 0, u / d, 0)
        ct = np.where(d > 0, w / d, 1)
    lat = np.arctan2(z + _EP2_LD * _B_LD * st**3, p - _E2_LD * _A_LD * ct**3)
    for _ in range(_NEWTON_STEPS):
        lat = latitude_newton_step(lat, np.sin(lat), np.cos(lat), p, z, _A_LD, _E2_LD)
    lat = np.clip(lat, -_HALF_PI_LD, _HALF_PI_LD)
    s, c = np.sin(lat), np.cos(lat)
    alt = p * c + z * s - _A_LD * np.sqrt(1 - _E2_LD * s * s)
    return lat.astype(np.float64), lon.astype(np.float64), alt.astype(np.float64)


# --------------------------------------------------------------------------------------------
# Radii of curvature
# --------------------------------------------------------------------------------------------


def meridian_radius(lat: ArrayLike) -> NDArray[np.float64]:
    """Meridian (north-south) radius of curvature ``R_N = a (1 - e²) / (1 - e² sin² φ)^{3/2}``.

    Standard ellipsoid geometry (Groves 2013 eq. (2.105); Savage, *Strapdown Analytics*, §5.2).
    ``lat`` (...): geodetic latitude φ, rad; ``R_N`` (...) in m: a(1-e²) at the equator, a²/b
    at the poles.
    """
    s = np.sin(_f64(lat))
    w2 = 1.0 - E2_WGS84 * s * s
    return A_WGS84 * (1.0 - E2_WGS84) / (w2 * np.sqrt(w2))


def transverse_radius(lat: ArrayLike) -> NDArray[np.float64]:
    """Prime-vertical (east-west) radius of curvature ``R_E = a / sqrt(1 - e² sin² φ)``.

    Standard ellipsoid geometry (Groves 2013 eq. (2.106)); ``R_E`` is also the length of the
    ellipsoid normal from the surface to the polar axis. ``lat`` (...): geodetic latitude φ,
    rad; ``R_E`` (...) in m: a at the equator, a²/b at the poles.
    """
    s = np.sin(_f64(lat))
    return A_WGS84 / np.sqrt(1.0 - E2_WGS84 * s * s)


def radii(lat: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Both radii of curvature ``(R_N, R_E)`` at geodetic latitude ``lat`` (rad), in m.

    See :func:`meridian_radius` and :func:`transverse_radius` (same shapes).
    """
    return meridian_radius(lat), transverse_radius(lat)


# --------------------------------------------------------------------------------------------
# Frame rotations
# --------------------------------------------------------------------------------------------


def dcm_ned_to_ecef(lat: ArrayLike, lon: ArrayLike) -> NDArray[np.float64]:
    """``C_N^E``: local-level NED to ECEF at a geodetic position.

    Columns are the north, east and down unit vectors in ECEF coordinates::

        north = [-sin φ cos λ, -sin φ sin λ,  cos φ]
        east  = [-sin λ,        cos λ,        0    ]
        down  = [-cos φ cos λ, -cos φ sin λ, -sin φ]

    (Savage 2020 (E-1)/(E-3) ``C_N^E`` at zero wander angle with NED axes; Groves 2013
    eq. (2.150)). Down is the ellipsoid normal pointing inwards.

    Parameters
    ----------
    lat, lon : array_like (...)
        Geodetic latitude φ and longitude λ, rad.

    Returns
    -------
    ndarray (..., 3, 3)
        ``C_N^E`` with ``v^E = C_N^E v^N``.
    """
    lat, lon = np.broadcast_arrays(_f64(lat), _f64(lon))
    sp, cp, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return matrix3([[-sp * cl, -sl, -cp * cl], [-sp * sl, cl, -cp * sl], [cp, 0.0, -sp]])


def dcm_ecef_to_ned(lat: ArrayLike, lon: ArrayLike) -> NDArray[np.float64]:
    """``C_E^N = (C_N^E)ᵀ`` (..., 3, 3): ECEF to local-level NED, ``v^N = C_E^N v^E``.

    Rows are north, east, down in ECEF; arguments as :func:`dcm_ned_to_ecef`'s.
    """
    return np.swapaxes(dcm_ned_to_ecef(lat, lon), -1, -2)


def dcm_ecef_to_e0(t: ArrayLike) -> NDArray[np.float64]:
    """``C_E^E0(t) = Rz(ω_ie t)``: ECEF at time ``t`` to the inertial E0 frame (interface.md §1).

    ``[[cos ω_ie t, -sin ω_ie t, 0], [sin ω_ie t, cos ω_ie t, 0], [0, 0, 1]]``, Savage 2020
    (E-2) with ``m T_m = t``: the Earth has turned by ``ω_ie t`` about z since ``t0``.

    Parameters
    ----------
    t : array_like (...)
        Time since ``t0``, s.

    Returns
    -------
    ndarray (..., 3, 3)
        ``C_E^E0`` with ``v^E0 = C_E^E0 v^E``.
    """
    a = OMEGA_IE * _f64(t)
    c, s = np.cos(a), np.sin(a)
    return matrix3([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def dcm_e0_to_ecef(t: ArrayLike) -> NDArray[np.float64]:
    """``C_E0^E(t) = (C_E^E0(t))ᵀ = Rz(-ω_ie t)`` (..., 3, 3), ``v^E = C_E0^E v^E0``.

    ``t`` as in :func:`dcm_ecef_to_e0`.
    """
    return np.swapaxes(dcm_ecef_to_e0(t), -1, -2)


# --------------------------------------------------------------------------------------------
# State conversions
# --------------------------------------------------------------------------------------------


def ecef_state_to_e0(
    t: ArrayLike,
    r_e: ArrayLike,
    v_e: ArrayLike,
    C_b_e: ArrayLike | None = None,
) -> _PosVelAtt:
    """Earth-referenced state to the inertial E0 state of docs/interface.md §3.

    ``R^E0 = C_E^E0 r^E``, ``V^E0 = dR^E0/dt = C_E^E0 (v^E + ω_ie × r^E)``,
    ``C_B^E0 = C_E^E0 C_B^E`` (Savage 2020 (E-1), (E-2) and the inverse of (E-7)).

    Parameters
    ----------
    t : array_like (...)
        Time since ``t0``, s.
    r_e : array_like (..., 3)
        Position ``r^E`` in ECEF, m.
    v_e : array_like (..., 3)
        Velocity relative to the Earth, ``v^E = dr^E/dt``, in ECEF coordinates, m/s.
    C_b_e : array_like (..., 3, 3) or None
        Attitude ``C_B^E`` (body FRD to ECEF), or None.

    Returns
    -------
    R_e0 : ndarray (..., 3)
        Position ``R^E0``, m.
    V_e0 : ndarray (..., 3)
        Inertial velocity ``V^E0 = dR^E0/dt`` in E0 coordinates, m/s.
    C_b_e0 : ndarray (..., 3, 3) or None
        Attitude ``C_B^E0`` (None if ``C_b_e`` is None).
    """
    c = dcm_ecef_to_e0(t)
    r_e, v_e = as_vectors(r_e), as_vectors(v_e)
    r0 = _mv(c, r_e)
    v0 = _mv(c, v_e + _omega_cross(r_e))
    cb = None if C_b_e is None else c @ as_matrices(C_b_e)
    return r0, v0, cb


def e0_state_to_ecef(
    t: ArrayLike,
    R_e0: ArrayLike,
    V_e0: ArrayLike,
    C_b_e0: ArrayLike | None = None,
) -> _PosVelAtt:
    """Inertial E0 state of docs/interface.md §3 to the Earth-referenced state.

    The inverse of :func:`ecef_state_to_e0` (exact up to rounding), with its shapes and units.

    ``r^E = C_E0^E R^E0``, ``v^E = C_E0^E V^E0 - ω_ie × r^E``, ``C_B^E = C_E0^E C_B^E0``
    (Savage 2020 (E-7) velocity and (E-8) chain rule, with E in place of N); ``C_b_e`` is None
    if ``C_b_e0`` is.
    """
    c = dcm_ecef_to_e0(t)
    r_e = _mtv(c, as_vectors(R_e0))
    v_e = _mtv(c, as_vectors(V_e0)) - _omega_cross(r_e)
    cb = None if C_b_e0 is None else np.swapaxes(c, -1, -2) @ as_matrices(C_b_e0)
    return r_e, v_e, cb


def body_rates_relative_to_earth(
    omega_ib_b: ArrayLike,
    C_b_e: ArrayLike,
) -> NDArray[np.float64]:
    """Angular rate of the body relative to the Earth, ``ω_eb^B = ω_ib^B - C_E^B ω_ie^E``.

    Used for the docs/interface.md §4 odometry ``twist.angular`` (converted to FLU at the message
    layer).

    Parameters
    ----------
    omega_ib_b : array_like (..., 3)
        Inertial angular rate of the body ``ω_ib^B`` in body (FRD) axes, rad/s.
    C_b_e : array_like (..., 3, 3)
        Attitude ``C_B^E`` (body to ECEF).

    Returns
    -------
    ndarray (..., 3)
        ``ω_eb^B`` in body axes, rad/s.
    """
    c = as_matrices(C_b_e)
    # C_E^B ω_ie^E = (C_B^E)ᵀ [0, 0, ω_ie] = ω_ie × (row 2 of C_B^E).
    return as_vectors(omega_ib_b) - OMEGA_IE * c[..., 2, :]


def ned_velocity_from_ecef(lat: ArrayLike, lon: ArrayLike, v_e: ArrayLike) -> NDArray[np.float64]:
    """Earth-relative velocity resolved in NED: ``v^N = C_E^N v^E``.

    Parameters
    ----------
    lat, lon : array_like (...)
        Geodetic latitude and longitude, rad.
    v_e : array_like (..., 3)
        Velocity relative to the Earth in ECEF coordinates, m/s.

    Returns
    -------
    ndarray (..., 3)
        ``[v_N, v_E, v_D]``, m/s.
    """
    return _mtv(dcm_ned_to_ecef(lat, lon), as_vectors(v_e))


def ecef_velocity_from_ned(lat: ArrayLike, lon: ArrayLike, v_ned: ArrayLike) -> NDArray[np.float64]:
    """Earth-relative velocity resolved in ECEF, ``v^E = C_N^E v^N`` (..., 3), m/s.

    The inverse of :func:`ned_velocity_from_ecef` (``v_ned`` = ``[v_N, v_E, v_D]``, m/s).
    """
    return _mv(dcm_ned_to_ecef(lat, lon), as_vectors(v_ned))


def geodetic_rates(
    lat: ArrayLike, alt: ArrayLike, v_ned: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Time derivatives of geodetic latitude, longitude and altitude.

    ``φ' = v_N / (R_N + h)``, ``λ' = v_E / ((R_E + h) cos φ)``, ``h' = -v_D``
    (Groves 2013 eq. (2.111)); ``λ'`` is infinite at the poles.

    Parameters
    ----------
    lat : array_like (...)
        Geodetic latitude φ, rad.
    alt : array_like (...)
        Altitude h above the ellipsoid, m.
    v_ned : array_like (..., 3)
        Earth-relative velocity in NED, m/s.

    Returns
    -------
    lat_dot, lon_dot : ndarray (...)
        rad/s.
    alt_dot : ndarray (...)
        m/s.
    """
    lat, alt = _f64(lat), _f64(alt)
    v = as_vectors(v_ned)
    rn, re = radii(lat)
    with np.errstate(divide="ignore"):
        lon_dot = v[..., 1] / ((re + alt) * np.cos(lat))
    return v[..., 0] / (rn + alt), lon_dot, -v[..., 2]
