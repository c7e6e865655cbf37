"""Gravitation and gravity models (docs/interface.md §1) and the Savage 2020 Appendix C expansion.

Gravitation ``g`` is the mass attraction only; plumb-bob gravity adds the centrifugal term of the
Earth's rotation, ``g_P = g - ω_ie × (ω_ie × r)`` (docs/interface.md §1), and is what a level
accelerometer at
rest on the Earth measures (with the opposite sign). All models are axisymmetric about the polar
axis z, so the same functions apply to coordinates in E (ECEF) or in E0 (docs/interface.md §1,
Savage 2020
Appendix E note). Vectors have shape ``(..., 3)``; functions broadcast over leading axes. Units:
m, m/s², rad.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.earth import (
    A_WGS84,
    GM_WGS84,
    J2_WGS84,
    OMEGA_IE,
    dcm_ecef_to_ned,
    geodetic_to_ecef,
)

__all__ = [
    "GRAVITY_MODELS",
    "gravitation",
    "gravitation_first_order",
    "gravitation_gradient_j2",
    "gravitation_j2",
    "gravitation_spherical",
    "gravity_ned",
    "gravity_plumb_bob",
]

#: Names accepted by :func:`gravitation` (docs/interface.md §1 ``j2`` is the default of every
#stream).
GRAVITY_MODELS: tuple[str, ...] = ("j2", "spherical")


def _vec(v: ArrayLike) -> NDArray[np.float64]:
    v = np.asarray(v, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise ValueError(f"expected an array of 3-vectors (..., 3), got shape {v.shape}")
    return v


def _s(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return x[..., None, None]


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.einsum("...i,...i->...", a, b)


def gravitation_j2(r: ArrayLike) -> NDArray[np.float64]:
    """J2 gravitation, the docs/interface.md §1 ``j2`` model, exactly as written there.

    ``g = -GM/r³ [x (1 + k(1 - 5z²/r²)), y (1 + k(1 - 5z²/r²)), z (1 + k(3 - 5z²/r²))]`` with
    ``k = 1.5 J2 (a/r)²``; this is the gradient of the potential
    ``U = GM/r [1 - J2 (a/r)² (3 sin²φ_c - 1)/2]`` (φ_c geocentric latitude), i.e. the
    classical oblate-Earth model Savage 2020 Appendix B (B-6) refers to, truncated at J2.

    Parameters
    ----------
    r : array_like (..., 3)
        Position in E or E0 coordinates (the model is axisymmetric about z), m. Not zero.

    Returns
    -------
    ndarray (..., 3)
        Gravitation (mass attraction, no centrifugal term) in the same frame, m/s².
    """
    r = _vec(r)
    r2 = _dot(r, r)
    rn = np.sqrt(r2)
    k = 1.5 * J2_WGS84 * A_WGS84**2 / r2
    zz = 5.0 * r[..., 2] ** 2 / r2
    m = -GM_WGS84 / (r2 * rn)
    fxy = m * (1.0 + k * (1.0 - zz))
    fz = m * (1.0 + k * (3.0 - zz))
    return np.stack([fxy * r[..., 0], fxy * r[..., 1], fz * r[..., 2]], -1)


def gravitation_spherical(r: ArrayLike) -> NDArray[np.float64]:
    """Point-mass (spherical Earth) gravitation ``g = -GM r / |r|³``.

    Savage 2020 Appendix C eq. (C-1) with ``μ = GM_WGS84``.

    Parameters
    ----------
    r : array_like (..., 3)
        Position in E or E0 coordinates, m. Not zero.

    Returns
    -------
    ndarray (..., 3)
        Gravitation in the same frame, m/s².
    """
    r = _vec(r)
    r2 = _dot(r, r)
    return (-GM_WGS84 / (r2 * np.sqrt(r2)))[..., None] * r


def gravitation(r: ArrayLike, model: str = "j2") -> NDArray[np.float64]:
    """Gravitation of the named model (docs/interface.md §1 ``gravity_model``).

    Parameters
    ----------
    r : array_like (..., 3)
        Position in E or E0 coordinates, m.
    model : str
        One of :data:`GRAVITY_MODELS`: ``"j2"`` (:func:`gravitation_j2`, the default) or
        ``"spherical"`` (:func:`gravitation_spherical`).

    Returns
    -------
    ndarray (..., 3)
        Gravitation in the same frame, m/s².

    Raises
    ------
    ValueError
        If ``model`` is not one of :data:`GRAVITY_MODELS`.
    """
    if model == "j2":
        return gravitation_j2(r)
    if model == "spherical":
        return gravitation_spherical(r)
    raise ValueError(
        f"unknown gravity model {model!r}; valid models are: {', '.join(GRAVITY_MODELS)}"
    )


def gravity_plumb_bob(r_e: ArrayLike, model: str = "j2") -> NDArray[np.float64]:
    """Plumb-bob gravity ``g_P = g(r) - ω_ie × (ω_ie × r)`` in ECEF (docs/interface.md §1).

    ``-ω_ie × (ω_ie × r) = ω_ie² [x, y, 0]`` (centrifugal acceleration of the rotating frame).

    Parameters
    ----------
    r_e : array_like (..., 3)
        Position ``r^E`` in ECEF, m.
    model : str
        Gravitation model, see :func:`gravitation`.

    Returns
    -------
    ndarray (..., 3)
        Plumb-bob gravity in ECEF, m/s².
    """
    r_e = _vec(r_e)
    g = gravitation(r_e, model)
    w2 = OMEGA_IE * OMEGA_IE
    return g + np.stack([w2 * r_e[..., 0], w2 * r_e[..., 1], np.zeros_like(r_e[..., 2])], -1)


def gravity_ned(lat: ArrayLike, alt: ArrayLike, model: str = "j2") -> NDArray[np.float64]:
    """Plumb-bob gravity resolved in local-level NED at a geodetic position.

    ``g_P^N = C_E^N (g(r^E) - ω_ie × (ω_ie × r^E))`` at ``r^E = geodetic_to_ecef(lat, 0, alt)``.
    The models are axisymmetric, so the NED components do not depend on longitude (it is not an
    argument); the east component is exactly zero and the north component is the (small) angle
    between the model's plumb line and the ellipsoid normal times ``|g_P|``.

    Parameters
    ----------
    lat : array_like (...)
        Geodetic latitude, rad.
    alt : array_like (...)
        Altitude above the WGS-84 ellipsoid, m.
    model : str
        Gravitation model, see :func:`gravitation`.

    Returns
    -------
    ndarray (..., 3)
        ``[g_N, g_E, g_D]``, m/s² (``g_D`` ≈ +9.78 at the equator, +9.83 at the poles).
    """
    lat, alt = np.broadcast_arrays(np.asarray(lat, np.float64), np.asarray(alt, np.float64))
    r_e = geodetic_to_ecef(lat, 0.0, alt)
    g_e = gravity_plumb_bob(r_e, model)
    return (dcm_ecef_to_ned(lat, np.zeros_like(lat)) @ g_e[..., None])[..., 0]


def gravitation_first_order(
    g_ref: ArrayLike,
    R_ref: ArrayLike,
    S: ArrayLike,
) -> NDArray[np.float64]:
    """Variation-trajectory gravitation as a first-order expansion, Savage 2020 eq. (C-12).

    ``g_var = g_ref + (u · g_ref)/|R_ref| (S - 3 (u · S) u)``, ``u = R_ref / |R_ref|``.

    The expansion is that of the spherical model (C-1); with ``g_ref`` from the ``j2`` model it
    carries a first-order error of relative size ~J2 in the gradient (about 5e-9 m/s² per metre
    of ``S`` near the Earth's surface). The exact first-order expansion of ``j2`` is
    ``g_ref + gravitation_gradient_j2(R_ref) @ S``.

    Parameters
    ----------
    g_ref : array_like (..., 3)
        Gravitation at the reference position, E0 coordinates, m/s².
    R_ref : array_like (..., 3)
        Reference position ``R_ref^E0``, m.
    S : array_like (..., 3)
        Position offset ``S^E0 = R_var^E0 - R_ref^E0`` (Savage 2020 eq. (6)), m.

    Returns
    -------
    ndarray (..., 3)
        ``g_var^E0``, m/s².
    """
    g_ref, R_ref, S = _vec(g_ref), _vec(R_ref), _vec(S)
    rn = np.sqrt(_dot(R_ref, R_ref))
    u = R_ref / rn[..., None]
    return g_ref + (_dot(u, g_ref) / rn)[..., None] * (S - 3.0 * _dot(u, S)[..., None] * u)


def gravitation_gradient_j2(r: ArrayLike) -> NDArray[np.float64]:
    """Gravitation gradient (Jacobian) ``G = ∂g/∂r`` of the ``j2`` model, analytic.

    With ``U = GM/r + A/r³ - B z²/r⁵``, ``A = GM J2 a²/2``, ``B = 3 GM J2 a²/2`` (the potential of
    :func:`gravitation_j2`), ``G`` is the Hessian of ``U``::

        G = GM (3 r rᵀ/r⁵ - I/r³) + A (15 r rᵀ/r⁷ - 3 I/r⁵)
            - B (2 e_z e_zᵀ/r⁵ - 10 z (e_z rᵀ + r e_zᵀ)/r⁷ - 5 z² I/r⁷ + 35 z² r rᵀ/r⁹)

    Symmetric and trace-free (Laplace). Useful for implicit solves and for the exact
    first-order expansion ``g(R + S) ≈ g(R) + G S``.

    Parameters
    ----------
    r : array_like (..., 3)
        Position in E or E0 coordinates, m.

    Returns
    -------
    ndarray (..., 3, 3)
        ``∂g/∂r`` in the same frame, 1/s².
    """
    r = _vec(r)
    r2 = _dot(r, r)
    rn = np.sqrt(r2)
    z = r[..., 2]
    a_c = 0.5 * GM_WGS84 * J2_WGS84 * A_WGS84**2
    b_c = 3.0 * a_c
    inv2 = 1.0 / r2
    inv3 = inv2 / rn
    inv5 = inv3 * inv2
    inv7 = inv5 * inv2
    eye = np.eye(3)
    rr = r[..., :, None] * r[..., None, :]
    ez = np.array([0.0, 0.0, 1.0])
    ezr = ez[:, None] * r[..., None, :]
    ezr = ezr + np.swapaxes(ezr, -1, -2)
    ezez = np.outer(ez, ez)
    return (
        GM_WGS84 * (3.0 * _s(inv5) * rr - _s(inv3) * eye)
        + a_c * (15.0 * _s(inv7) * rr - 3.0 * _s(inv5) * eye)
        - b_c
        * (
            2.0 * _s(inv5) * ezez
            - 10.0 * _s(z * inv7) * ezr
            - 5.0 * _s(z * z * inv7) * eye
            + 35.0 * _s(z * z * inv7 * inv2) * rr
        )
    )
