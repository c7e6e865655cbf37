"""Young 1980 (NSWC) Euler-angle orientation error: eqs. (28), (30), (31).

Young defines the platform frames with axes (up, east, north) — x along the ellipsoid normal,
y east, z north — and relates the ideal platform frame Σ_P to the actual frame Σ_M by
``𝒯_P2M = R_{+z''}(θ3) R_{+y'}(θ2) R_{+x}(θ1)`` with matrix H of eq. (28)
(``v^M = H v^P``):

    H = [[ Cθ2 Cθ3,  Sθ1 Sθ2 Cθ3 + Cθ1 Sθ3, -Cθ1 Sθ2 Cθ3 + Sθ1 Sθ3],
         [-Cθ2 Sθ3, -Sθ1 Sθ2 Sθ3 + Cθ1 Cθ3,  Cθ1 Sθ2 Sθ3 + Sθ1 Cθ3],
         [ Sθ2,     -Sθ1 Cθ2,                 Cθ1 Cθ2              ]]

For a navigator, docs/interface.md §4 takes Σ_P as the true local-level frame and Σ_M as the
local-level
frame implied by the computed attitude: ``H = C_B^N(computed) C_B^N(true)ᵀ`` resolved in the
(up, east, north) axes. For small errors ``H ≈ I - (θ×)``, so θ equals, to second order, the
rotation vector of the error rotation that carries the true local-level axes to the computed
ones.

The kinematics of the derivation are here too (docs/theory/young_nonlinear.md):

* Young's angular-velocity operators, eq. (8): ``W^T Ẇ = young_operator(α)`` for the rotation
  of Σ_b with respect to Σ_a (v^b = W v^a), i.e. ``-(α×)``;
* the frame matrices E, F, G of eqs. (25)–(27);
* the angular velocity of a local-level (up, east, north) frame at latitude φ moving at
  ``φ̇, λ̇``, eq. (39) (and the bracketed commanded rates of eq. (47) at the indicated position);
* γ^P of eqs. (48)/(50) and the nonlinear orientation error equations (51a)–(51c).

The integrator of eq. (51) along a navigator's run is
:mod:`strapdown_ros.core.young_nonlinear`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import OMEGA_IE

__all__ = [
    "C_NED_TO_UEN",
    "commanded_rates",
    "earth_rotation_dcm",
    "earth_to_platform_dcm",
    "frame_rates",
    "relative_rates",
    "young_angle_rates",
    "young_angles_from_dcm",
    "young_dcm",
    "young_error_angles",
    "young_operator",
    "young_operator_vector",
    "young_platform_rates",
    "young_rates",
]


#: Young's (up, east, north) axes from NED: ``v^UEN = C_NED_TO_UEN v^NED``. Exact.
C_NED_TO_UEN = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
C_NED_TO_UEN.setflags(write=False)


def young_dcm(theta: ArrayLike) -> F64:
    """Matrix H of Young 1980 eq. (28) from Euler angles θ = (θ1, θ2, θ3) (rad).

    Parameters
    ----------
    theta : array (..., 3)
        Rotations about x (up), then y' (east), then z'' (north), rad.

    Returns
    -------
    array (..., 3, 3)
        ``H = C_P^M``: coordinates in the rotated frame M from coordinates in P.
    """
    theta = np.asarray(theta, dtype=np.float64)
    s1, s2, s3 = (np.sin(theta[..., i]) for i in range(3))
    c1, c2, c3 = (np.cos(theta[..., i]) for i in range(3))
    h = np.empty(theta.shape[:-1] + (3, 3))
    h[..., 0, 0] = c2 * c3
    h[..., 0, 1] = s1 * s2 * c3 + c1 * s3
    h[..., 0, 2] = -c1 * s2 * c3 + s1 * s3
    h[..., 1, 0] = -c2 * s3
    h[..., 1, 1] = -s1 * s2 * s3 + c1 * c3
    h[..., 1, 2] = c1 * s2 * s3 + s1 * c3
    h[..., 2, 0] = s2
    h[..., 2, 1] = -s1 * c2
    h[..., 2, 2] = c1 * c2
    return h


def young_angles_from_dcm(h: ArrayLike) -> F64:
    """Euler angles θ (rad) of Young 1980 eq. (28) from H: the inverse of :func:`young_dcm`.

    ``θ2 = atan2(H31, √(H32² + H33²)) ∈ [-π/2, π/2]``, ``θ1 = atan2(-H32, H33)``,
    ``θ3 = atan2(-H21, H11)``; all with atan2 so accuracy holds for small and large angles.
    """
    h = np.asarray(h, dtype=np.float64)
    theta2 = np.arctan2(h[..., 2, 0], np.hypot(h[..., 2, 1], h[..., 2, 2]))
    theta1 = np.arctan2(-h[..., 2, 1], h[..., 2, 2])
    theta3 = np.arctan2(-h[..., 1, 0], h[..., 0, 0])
    return np.stack([theta1, theta2, theta3], axis=-1)


def young_rates(theta: ArrayLike, gamma: ArrayLike) -> F64:
    """Euler-angle rates θ̇ (rad/s) from the relative angular velocity γ^P: Young 1980 eq. (31).

    Parameters
    ----------
    theta : array (..., 3)
        Current angles (rad); singular at θ2 = ±π/2 (sec θ2).
    gamma : array (..., 3)
        ``γ^P`` (rad/s): angular velocity of Σ_M relative to Σ_P, eq. (29) ``Γ^P = Hᵀ Ḣ``.
    """
    theta = np.asarray(theta, dtype=np.float64)
    gamma = np.asarray(gamma, dtype=np.float64)
    s1, c1 = np.sin(theta[..., 0]), np.cos(theta[..., 0])
    t2, sec2 = np.tan(theta[..., 1]), 1.0 / np.cos(theta[..., 1])
    g1, g2, g3 = gamma[..., 0], gamma[..., 1], gamma[..., 2]
    return np.stack(
        [
            g1 + g2 * t2 * s1 - g3 * t2 * c1,
            g2 * c1 + g3 * s1,
            g3 * c1 * sec2 - g2 * s1 * sec2,
        ],
        axis=-1,
    )


def young_platform_rates(theta: ArrayLike, theta_dot: ArrayLike) -> F64:
    """Relative angular velocity γ^P (rad/s) from θ and θ̇: Young 1980 eq. (30).

    Inverse of :func:`young_rates`.
    """
    theta = np.asarray(theta, dtype=np.float64)
    theta_dot = np.asarray(theta_dot, dtype=np.float64)
    s1, c1 = np.sin(theta[..., 0]), np.cos(theta[..., 0])
    s2, c2 = np.sin(theta[..., 1]), np.cos(theta[..., 1])
    d1, d2, d3 = theta_dot[..., 0], theta_dot[..., 1], theta_dot[..., 2]
    return np.stack([d1 + d3 * s2, d2 * c1 - d3 * s1 * c2, d2 * s1 + d3 * c1 * c2], axis=-1)


def young_error_angles(c_b_n_computed: ArrayLike, c_b_n_true: ArrayLike) -> F64:
    """Young 1980 error angles (θ1, θ2, θ3) (rad) between a computed and a true attitude.

    Parameters
    ----------
    c_b_n_computed : array (..., 3, 3)
        ``C_B^N`` (body FRD to local-level NED) computed by the navigator.
    c_b_n_true : array (..., 3, 3)
        ``C_B^N`` of the truth.

    Returns
    -------
    array (..., 3)
        θ of eq. (28) for ``H = C_NED_TO_UEN C_B^N(computed) C_B^N(true)ᵀ C_NED_TO_UENᵀ``,
        i.e. about the (up, east, north) axes of the true local level (docs/interface.md §4
        ``/navigator/error/attitude``).
    """
    comp = np.asarray(c_b_n_computed, dtype=np.float64)
    true = np.asarray(c_b_n_true, dtype=np.float64)
    h = C_NED_TO_UEN @ comp @ np.swapaxes(true, -1, -2) @ C_NED_TO_UEN.T
    return young_angles_from_dcm(h)


# ---------------------------------------------------------------------------------------------
# The derivation: operators, frame matrices, eqs. (39), (47), (50), (51)


def young_operator(v: ArrayLike) -> F64:
    """Young 1980 eq. (8)/(17) operator of an angular velocity vector: ``-(v×)``.

    ``[[0, v3, -v2], [-v3, 0, v1], [v2, -v1, 0]]``; for ``v^b = W v^a`` the operator of the
    rotation of Σ_b with respect to Σ_a in Σ_a axes is ``W^T Ẇ = young_operator(α^a)``.
    """
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = v[..., 2], -v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = -v[..., 2], v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = v[..., 1], -v[..., 0]
    return out


def young_operator_vector(a: ArrayLike) -> F64:
    """The vector (α1, α2, α3) of a Young operator, eq. (9): ``(A23, A31, A12)``.

    Skew-symmetrized first, so a slightly non-skew numerical ``W^T Ẇ`` gives its nearest
    operator's vector.
    """
    a = np.asarray(a, dtype=np.float64)
    s = 0.5 * (a - np.swapaxes(a, -1, -2))
    return np.stack([s[..., 1, 2], s[..., 2, 0], s[..., 0, 1]], axis=-1)


def earth_rotation_dcm(t: ArrayLike, omega: float = OMEGA_IE) -> F64:
    """Matrix E of Young 1980 eq. (25): ``v^e = E v^I``, ``R_{+Z}(Ω_e t)`` (t in s)."""
    a = np.asarray(t, dtype=np.float64) * omega
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, s
    out[..., 1, 0], out[..., 1, 1] = -s, c
    out[..., 2, 2] = 1.0
    return out


def earth_to_platform_dcm(lat: ArrayLike, lon: ArrayLike) -> F64:
    """Matrix F (eq. (26), true position) or G (eq. (27), indicated position) of Young 1980.

    ``v^P = F v^e`` with ``R_{-y'}(φ) R_{+Z}(λ)``: rows are the up (ellipsoid normal), east and
    north unit vectors in ECEF at geodetic latitude φ and longitude λ (rad). Equals
    ``C_NED_TO_UEN @ dcm_ecef_to_ned(φ, λ)``.
    """
    lat = np.asarray(lat, dtype=np.float64)
    lon = np.asarray(lon, dtype=np.float64)
    cp, sp, cl, sl = np.cos(lat), np.sin(lat), np.cos(lon), np.sin(lon)
    out = np.zeros(np.broadcast(lat, lon).shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = cp * cl, cp * sl, sp
    out[..., 1, 0], out[..., 1, 1] = -sl, cl
    out[..., 2, 0], out[..., 2, 1], out[..., 2, 2] = -sp * cl, -sp * sl, cp
    return out


def frame_rates(
    lat: ArrayLike, lat_rate: ArrayLike, lon_rate: ArrayLike, omega: float = OMEGA_IE
) -> F64:
    """Inertial angular velocity of an (up, east, north) local-level frame in its own axes.

    Young 1980 eq. (39): ``ψ^P = ((λ̇ + Ω_e) sin φ, -φ̇, (λ̇ + Ω_e) cos φ)`` (rad/s) for the
    ideal platform frame at the true position; at the indicated position (φ^s, φ̇^s, λ̇^s) it is
    the computer frame's rate, the bracketed terms of eq. (47) without the drift.
    """
    lat = np.asarray(lat, dtype=np.float64)
    w = np.asarray(lon_rate, dtype=np.float64) + omega
    north = -np.asarray(lat_rate, dtype=np.float64)
    return np.stack(np.broadcast_arrays(w * np.sin(lat), north, w * np.cos(lat)), axis=-1)


def commanded_rates(
    lat_s: ArrayLike,
    lat_rate_s: ArrayLike,
    lon_rate_s: ArrayLike,
    drift_m: ArrayLike = (0.0, 0.0, 0.0),
    omega: float = OMEGA_IE,
) -> F64:
    """δ^M of Young 1980 eq. (47): the computer frame's rate applied about Σ_M, plus drift.

    ``δ^M = ((λ̇^s + Ω_e) sin φ^s + ε1, -φ̇^s + ε2, (λ̇^s + Ω_e) cos φ^s + ε3)`` (rad/s), the
    inertial angular velocity of the actual frame Σ_M in its own axes (eq. (45)); ε (rad/s) are
    the drift rates of eq. (44) in Σ_M axes. (The printed eq. (47) has ``sin φ̇^s``: a slip.)
    """
    return frame_rates(lat_s, lat_rate_s, lon_rate_s, omega) + np.asarray(drift_m, dtype=np.float64)


def relative_rates(theta: ArrayLike, delta_m: ArrayLike, psi_p: ArrayLike) -> F64:
    """γ^P of Young 1980 eqs. (48)/(50): ``Γ^P = H^T Δ^M H - Ψ^P``, i.e. ``γ = H^T δ^M - ψ^P``.

    The angular velocity of Σ_M relative to Σ_P in Σ_P axes (rad/s), from θ (rad), δ^M
    (eq. (47)) and ψ^P (eq. (39)).
    """
    h = young_dcm(theta)
    delta_m = np.asarray(delta_m, dtype=np.float64)
    return np.einsum("...ji,...j->...i", h, delta_m) - np.asarray(psi_p, dtype=np.float64)


def young_angle_rates(theta: ArrayLike, delta_m: ArrayLike, psi_p: ArrayLike) -> F64:
    """θ̇ (rad/s) of Young 1980 eqs. (51a)–(51c), the nonlinear orientation error equations.

    Parameters
    ----------
    theta : array (..., 3)
        Euler angles of eq. (28) (rad); singular at θ2 = ±π/2.
    delta_m : array (..., 3)
        δ^M of eq. (47): commanded rates (at the indicated position) plus drift, Σ_M axes, rad/s.
    psi_p : array (..., 3)
        ψ^P of eq. (39): rate of the ideal frame (true position) in its own axes, rad/s.

    Notes
    -----
    Written term by term as eqs. (51a)–(51c) with δ_i for the brackets of eq. (47) and
    ψ^P = ((λ̇ + Ω) sin φ, -φ̇, (λ̇ + Ω) cos φ):

    * θ̇1 = δ1 sec θ2 cos θ3 - δ2 sec θ2 sin θ3 - ψ2 tan θ2 sin θ1 + ψ3 tan θ2 cos θ1 - ψ1
    * θ̇2 = δ1 sin θ3 + δ2 cos θ3 - ψ2 cos θ1 - ψ3 sin θ1
    * θ̇3 = -δ1 tan θ2 cos θ3 + δ2 tan θ2 sin θ3 + δ3 - ψ3 cos θ1 sec θ2 + ψ2 sin θ1 sec θ2

    equal to eq. (31) applied to eq. (50) (:func:`young_rates` of :func:`relative_rates`).
    """
    theta = np.asarray(theta, dtype=np.float64)
    d = np.asarray(delta_m, dtype=np.float64)
    p = np.asarray(psi_p, dtype=np.float64)
    s1, c1 = np.sin(theta[..., 0]), np.cos(theta[..., 0])
    s3, c3 = np.sin(theta[..., 2]), np.cos(theta[..., 2])
    t2, sec2 = np.tan(theta[..., 1]), 1.0 / np.cos(theta[..., 1])
    d1, d2, d3 = d[..., 0], d[..., 1], d[..., 2]
    p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2]
    return np.stack(
        [
            d1 * sec2 * c3 - d2 * sec2 * s3 - p2 * t2 * s1 + p3 * t2 * c1 - p1,  # (51a)
            d1 * s3 + d2 * c3 - p2 * c1 - p3 * s1,  # (51b)
            -d1 * t2 * c3 + d2 * t2 * s3 + d3 - p3 * c1 * sec2 + p2 * s1 * sec2,  # (51c)
        ],
        axis=-1,
    )
