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
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "C_NED_TO_UEN",
    "young_angles_from_dcm",
    "young_dcm",
    "young_error_angles",
    "young_platform_rates",
    "young_rates",
]

Array = NDArray[np.float64]

#: Young's (up, east, north) axes from NED: ``v^UEN = C_NED_TO_UEN v^NED``. Exact.
C_NED_TO_UEN = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
C_NED_TO_UEN.setflags(write=False)


def young_dcm(theta: ArrayLike) -> Array:
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


def young_angles_from_dcm(h: ArrayLike) -> Array:
    """Euler angles θ (rad) of Young 1980 eq. (28) from H: the inverse of :func:`young_dcm`.

    ``θ2 = atan2(H31, √(H32² + H33²)) ∈ [-π/2, π/2]``, ``θ1 = atan2(-H32, H33)``,
    ``θ3 = atan2(-H21, H11)``; all with atan2 so accuracy holds for small and large angles.
    """
    h = np.asarray(h, dtype=np.float64)
    theta2 = np.arctan2(h[..., 2, 0], np.hypot(h[..., 2, 1], h[..., 2, 2]))
    theta1 = np.arctan2(-h[..., 2, 1], h[..., 2, 2])
    theta3 = np.arctan2(-h[..., 1, 0], h[..., 0, 0])
    return np.stack([theta1, theta2, theta3], axis=-1)


def young_rates(theta: ArrayLike, gamma: ArrayLike) -> Array:
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


def young_platform_rates(theta: ArrayLike, theta_dot: ArrayLike) -> Array:
    """Relative angular velocity γ^P (rad/s) from θ and θ̇: Young 1980 eq. (30).

    Inverse of :func:`young_rates`.
    """
    theta = np.asarray(theta, dtype=np.float64)
    theta_dot = np.asarray(theta_dot, dtype=np.float64)
    s1, c1 = np.sin(theta[..., 0]), np.cos(theta[..., 0])
    s2, c2 = np.sin(theta[..., 1]), np.cos(theta[..., 1])
    d1, d2, d3 = theta_dot[..., 0], theta_dot[..., 1], theta_dot[..., 2]
    return np.stack([d1 + d3 * s2, d2 * c1 - d3 * s1 * c2, d2 * s1 + d3 * c1 * c2], axis=-1)


def young_error_angles(c_b_n_computed: ArrayLike, c_b_n_true: ArrayLike) -> Array:
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
