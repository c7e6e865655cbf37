"""Velocity and attitude matching: the master's state carried to the slave (E0 frame).

Notation (docs/transfer_alignment.md §2): master (reference IMU) attitude ``C_r = C_Br^E0``,
inertial velocity ``V_r``; slave (variation IMU) ``C_s = C_Bs^E0``, ``V_s``; mounting
``M = C_Bs^Br``, lever arm ``l`` (Br FRD, m). A fixed mount gives ``C_s = C_r M`` (Savage 2020
eq. (5)) and ``R_s = R_r + C_r l`` (eqs. (6)–(7) with s = 0), so

    V_s = V_r + d(C_r l)/dt = V_r + C_r (ω_ib^Br × l)                         (velocity)

which the simulation meets at even cycles in the form of eq. (10),
``V_s,m = V_r,m + (C_r,m+1 − C_r,m−1) l / 2T``. The filter's error states (estimate minus
truth): ``δV``, ``φ`` (``Ĉ_s = exp([φ×]) C_s``), the mounting misalignment ``μ``
(``M̂ = exp([μ×]) M``, Br axes) and the lever-arm error ``δl``.

* **Velocity matching** (Kain & Cloutier 1989; Groves 2013 §15.1.1):
  ``z = V_r``, ``h(x̂) = V̂_s − D l̂`` with ``D = (C_r,m+1 − C_r,m−1)/2T`` (``central_difference``)
  or ``D = C_r [ω_ib×]`` (``rate``, ``ω_ib`` the master's body rate); ``H_δV = I``,
  ``H_δl = −D``.
* **Attitude matching**: ``z = C_r``, ``h(x̂) = Ĉ_s M̂ᵀ``, innovation the rotation vector
  ``ν = rotvec(C_r M̂ Ĉ_sᵀ) ≈ −(φ − C_r μ)``; ``H_φ = I``, ``H_μ = −C_r``.
"""

from __future__ import annotations

import numpy as np

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import rotvec_from_dcm, skew

__all__ = [
    "attitude_matching",
    "carried_position",
    "start_velocity",
    "transport_matrix",
    "velocity_matching",
]


def transport_matrix(kind: str, c_prev: F64, c_mid: F64, c_next: F64, w_ib: F64,
                     period_s: float) -> F64:  # fmt: skip
    """``D`` (3, 3) with ``V_s = V_r + D l``: central difference of eq. (10) or ``C_r [ω×]``.

    ``c_prev``, ``c_mid``, ``c_next``: master attitude at cycles m−1, m, m+1; ``w_ib`` the
    master's inertial body rate (rad/s, Br FRD); ``period_s`` the IMU period T.
    """
    if kind == "central_difference":
        return (np.asarray(c_next) - np.asarray(c_prev)) / (2.0 * period_s)
    if kind == "rate":
        return np.asarray(c_mid) @ skew(np.asarray(w_ib))
    raise ValueError(f"unknown velocity transport {kind!r}")


def start_velocity(c0: F64, c1: F64, c2: F64, v0: F64, lever: F64, period_s: float) -> F64:
    """Slave velocity at cycle 0: ``V_r + (−3 S_0 + 4 S_1 − S_2)/2T``, ``S = C_r l``.

    The second-order one-sided difference the variation uses at its first cycle.
    """
    s0, s1, s2 = (np.asarray(c) @ lever for c in (c0, c1, c2))
    return np.asarray(v0) + (-3.0 * s0 + 4.0 * s1 - s2) / (2.0 * period_s)


def carried_position(r_ref: F64, c_ref: F64, lever: F64) -> F64:
    """``R_s = R_r + C_r l`` (eqs. (6)–(7), no displacement)."""
    return np.asarray(r_ref) + np.asarray(c_ref) @ np.asarray(lever)


def velocity_matching(v_hat: F64, v_master: F64, d: F64, lever_hat: F64, n: int, i_v: int,
                      i_l: int) -> tuple[F64, F64]:  # fmt: skip
    """Innovation ``ν = V_r − (V̂_s − D l̂)`` (3,) and H (3, n).

    ``i_v``: index of δV; ``i_l``: index of δl (−1: no lever-arm states).
    """
    nu = np.asarray(v_master) - (np.asarray(v_hat) - d @ np.asarray(lever_hat))
    h = np.zeros((3, n))
    h[:, i_v : i_v + 3] = np.eye(3)
    if i_l >= 0:
        h[:, i_l : i_l + 3] = -d
    return nu, h


def attitude_matching(c_hat: F64, c_master: F64, mount_hat: F64, n: int, i_phi: int,
                      i_mu: int) -> tuple[F64, F64]:  # fmt: skip
    """Innovation ``ν = rotvec(C_r M̂ Ĉ_sᵀ)`` (3,) and H (3, n) (``H_φ = I``, ``H_μ = −C_r``)."""
    c_master = np.asarray(c_master)
    nu = rotvec_from_dcm(c_master @ np.asarray(mount_hat) @ np.asarray(c_hat).T)
    h = np.zeros((3, n))
    h[:, i_phi : i_phi + 3] = np.eye(3)
    h[:, i_mu : i_mu + 3] = -c_master
    return np.asarray(nu, dtype=np.float64), h
