"""The exact strapdown update of Savage 2020 eqs. (2)-(4) in the inertial E0 frame.

Over one cycle m (``t_{m-1} → t_m``, length T) with constant body angular rate and specific
force, and gravity varying linearly in time (Savage 2020 Appendix A, eqs. (A-1)-(A-5)), the
continuous kinematics of eq. (1) integrate exactly to::

    C_m = C_{m-1} G_C(Δα_m)                                                     (2)
    V_m = V_{m-1} + C_{m-1} G_V(Δα_m) Δv_m + ½ (g_m + g_{m-1}) T                (3)
    R_m = R_{m-1} + V_{m-1} T + C_{m-1} G_R(Δα_m) Δv_m T + (g_m + 2 g_{m-1}) T²/6 (4)

with ``C = C_B^E0`` (body to E0 DCM), ``V = dR^E0/dt`` (inertial velocity, m/s), ``R = R^E0``
(m), ``Δα`` the integrated body angular rate (rad, body axes) and ``Δv`` the integrated
specific force (m/s, body axes). These are the docs/interface.md §3 exactness equations: every
stream this
project generates satisfies them, and :func:`one_step_residuals` measures how well.

Everything here is vectorized over leading array axes (cycles), except :func:`integrate`,
which is the sequential recursion needed when the states are not known in advance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import _skew_terms, rotvec_from_dcm
from strapdown_ros.core.series import rotation_coefficients

__all__ = [
    "Residuals",
    "exact_update",
    "exact_update_single",
    "g_c",
    "g_matrices",
    "g_r",
    "g_v",
    "integrate",
    "one_step_residuals",
]

#: Gravity (m/s², E0) at positions (..., 3) in E0 (m).
GravityFn = Callable[[F64], F64]


def g_matrices(dalpha: ArrayLike) -> tuple[F64, F64, F64]:
    """``G_C``, ``G_V``, ``G_R`` of Savage 2020 eqs. (2), (3), (4) for rotation increments.

    ``G_C = I + f1 (Δα×) + f2 (Δα×)²``, ``G_V = I + f2 (Δα×) + f3 (Δα×)²``,
    ``G_R = ½ I + f3 (Δα×) + f4 (Δα×)²`` with the coefficient functions of
    :mod:`strapdown_ros.core.series` (exact at any angle).

    Parameters
    ----------
    dalpha : array (..., 3)
        Integrated body angular rate over the cycle, Δα_m (rad, body axes).

    Returns
    -------
    (G_C, G_V, G_R) : arrays (..., 3, 3), dimensionless
        ``G_C = C_{B_m}^{B_{m-1}}``; ``G_V``, ``G_R`` map Δv_m from body axes at the cycle's
        end into the velocity and (divided by T) position increments in ``B_{m-1}`` axes.
    """
    dalpha = np.asarray(dalpha, dtype=np.float64)
    x = np.linalg.norm(dalpha, axis=-1)
    k1, k2, k3, k4 = (c[..., None, None] for c in rotation_coefficients(x))
    k, kk = _skew_terms(dalpha)
    eye = np.eye(3)
    return eye + k1 * k + k2 * kk, eye + k2 * k + k3 * kk, 0.5 * eye + k3 * k + k4 * kk


def g_c(dalpha: ArrayLike) -> F64:
    """``G_C(Δα)`` of Savage 2020 eq. (2) (rad in, DCM ``C_{B_m}^{B_{m-1}}`` out)."""
    return g_matrices(dalpha)[0]


def g_v(dalpha: ArrayLike) -> F64:
    """``G_V(Δα)`` of Savage 2020 eq. (3) (rad in, dimensionless 3x3 out)."""
    return g_matrices(dalpha)[1]


def g_r(dalpha: ArrayLike) -> F64:
    """``G_R(Δα)`` of Savage 2020 eq. (4) (rad in, dimensionless 3x3 out)."""
    return g_matrices(dalpha)[2]


def _mv(m: F64, v: F64) -> F64:
    return np.einsum("...ij,...j->...i", m, v)


def exact_update(
    c_prev: ArrayLike,
    v_prev: ArrayLike,
    r_prev: ArrayLike,
    dalpha: ArrayLike,
    dv: ArrayLike,
    g_prev: ArrayLike,
    g_cur: ArrayLike,
    period: float | ArrayLike,
) -> tuple[F64, F64, F64]:
    """One exact cycle of Savage 2020 eqs. (2)-(4), vectorized over any number of cycles.

    Parameters
    ----------
    c_prev : array (..., 3, 3)
        ``C_{B_{m-1}}^{E0}``, body-to-E0 DCM at the start of the cycle.
    v_prev : array (..., 3)
        ``V_{m-1}^{E0}``, inertial velocity (m/s, E0 axes).
    r_prev : array (..., 3)
        ``R_{m-1}^{E0}``, position (m, E0 axes).
    dalpha, dv : arrays (..., 3)
        Δα_m (rad) and Δv_m (m/s), integrated angular rate and specific force, body axes.
    g_prev, g_cur : arrays (..., 3)
        Gravitation ``g_{m-1}``, ``g_m`` (m/s², E0 axes) at the start and end of the cycle
        (Appendix A: gravity linear in time over the cycle).
    period : float or array (...)
        T (s).

    Returns
    -------
    (C_m, V_m, R_m)
        Attitude ``C_{B_m}^{E0}``, velocity (m/s) and position (m) at the cycle's end, E0.
    """
    c_prev = np.asarray(c_prev, dtype=np.float64)
    v_prev = np.asarray(v_prev, dtype=np.float64)
    r_prev = np.asarray(r_prev, dtype=np.float64)
    dalpha = np.asarray(dalpha, dtype=np.float64)
    dv = np.asarray(dv, dtype=np.float64)
    g_prev = np.asarray(g_prev, dtype=np.float64)
    g_cur = np.asarray(g_cur, dtype=np.float64)
    t = np.asarray(period, dtype=np.float64)[..., None]
    x2 = np.einsum("...i,...i", dalpha, dalpha)
    k1, k2, k3, k4 = (c[..., None] for c in rotation_coefficients(np.sqrt(x2)))
    # G_V Δv and G_R Δv through cross products: (Δα×)² w = Δα (Δα·w) - |Δα|² w.
    a_x_dv = np.cross(dalpha, dv)
    a_x_a_x_dv = dalpha * np.einsum("...i,...i", dalpha, dv)[..., None] - x2[..., None] * dv
    gv_dv = dv + k2 * a_x_dv + k3 * a_x_a_x_dv
    gr_dv = 0.5 * dv + k3 * a_x_dv + k4 * a_x_a_x_dv
    k, kk = _skew_terms(dalpha)
    c_cur = c_prev @ (np.eye(3) + k1[..., None] * k + k2[..., None] * kk)
    v_cur = v_prev + _mv(c_prev, gv_dv) + 0.5 * (g_cur + g_prev) * t
    r_cur = r_prev + v_prev * t + _mv(c_prev, gr_dv) * t + (g_cur + 2.0 * g_prev) * t * t / 6.0
    return c_cur, v_cur, r_cur


def exact_update_single(
    c_prev: F64,
    v_prev: F64,
    r_prev: F64,
    dalpha: F64,
    dv: F64,
    g_prev: F64,
    g_cur: F64,
    period: float,
) -> tuple[F64, F64, F64]:
    """Single-cycle form of :func:`exact_update` (same arguments, one cycle, plain 3-vectors).

    Written as the per-cycle Python form of Savage 2020 eqs. (2)-(4): a reference for the
    vectorized version and the body of the naive loop that ``bench/bench_exact.py`` times.
    """
    x = float(np.sqrt(dalpha @ dalpha))
    k1, k2, k3, k4 = (float(c) for c in rotation_coefficients(x))
    k = np.array(
        [[0.0, -dalpha[2], dalpha[1]], [dalpha[2], 0.0, -dalpha[0]], [-dalpha[1], dalpha[0], 0.0]]
    )
    kk = k @ k
    eye = np.eye(3)
    gc = eye + k1 * k + k2 * kk
    gv = eye + k2 * k + k3 * kk
    gr = 0.5 * eye + k3 * k + k4 * kk
    c_cur = c_prev @ gc
    v_cur = v_prev + c_prev @ (gv @ dv) + 0.5 * (g_cur + g_prev) * period
    r_cur = (
        r_prev
        + v_prev * period
        + c_prev @ (gr @ dv) * period
        + (g_cur + 2.0 * g_prev) * period**2 / 6.0
    )
    return c_cur, v_cur, r_cur


@dataclass(frozen=True)
class Residuals:
    """One-step residuals of a stream against Savage 2020 eqs. (2)-(4) (docs/interface.md §3).

    Attributes
    ----------
    attitude : array (M,)
        Angle (rad) of ``C_m^T C_pred``, the rotation between published and predicted attitude.
    velocity : array (M,)
        ``|V_m - V_pred|`` (m/s).
    position : array (M,)
        ``|R_m - R_pred|`` (m).
    """

    attitude: F64
    velocity: F64
    position: F64

    #: docs/interface.md §3 tolerances: a one-step residual above these is a defect.
    TOL_ATTITUDE = 1e-11
    TOL_VELOCITY = 1e-9
    TOL_POSITION = 1e-7

    @property
    def max_attitude(self) -> float:
        """Largest attitude residual (rad)."""
        return float(np.max(self.attitude, initial=0.0))

    @property
    def max_velocity(self) -> float:
        """Largest velocity residual (m/s)."""
        return float(np.max(self.velocity, initial=0.0))

    @property
    def max_position(self) -> float:
        """Largest position residual (m)."""
        return float(np.max(self.position, initial=0.0))

    def within_spec(self) -> bool:
        """True when every residual is within the docs/interface.md §3 tolerances."""
        return (
            self.max_attitude <= self.TOL_ATTITUDE
            and self.max_velocity <= self.TOL_VELOCITY
            and self.max_position <= self.TOL_POSITION
        )


def one_step_residuals(
    c: ArrayLike,
    v: ArrayLike,
    r: ArrayLike,
    dalpha: ArrayLike,
    dv: ArrayLike,
    g: ArrayLike,
    period: float,
) -> Residuals:
    """docs/interface.md §3 one-step residuals of a published stream, all cycles at once.

    Parameters
    ----------
    c : array (M+1, 3, 3)
        Published attitudes ``C_{B_m}^{E0}``, m = 0..M.
    v, r : arrays (M+1, 3)
        Published inertial velocity (m/s) and position (m) in E0, m = 0..M.
    dalpha, dv : arrays (M, 3)
        Published increments of cycles m = 1..M (rad, m/s, body axes).
    g : array (M+1, 3)
        Gravitation at the published positions (m/s², E0), from the stream's model.
    period : float
        T (s).

    Returns
    -------
    Residuals
        Published minus predicted by eqs. (2)-(4) from the previous published state.
    """
    c = np.asarray(c, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    c_p, v_p, r_p = exact_update(c[:-1], v[:-1], r[:-1], dalpha, dv, g[:-1], g[1:], period)
    err = np.swapaxes(c[1:], -1, -2) @ c_p
    return Residuals(
        attitude=np.linalg.norm(rotvec_from_dcm(err), axis=-1),
        velocity=np.linalg.norm(v[1:] - v_p, axis=-1),
        position=np.linalg.norm(r[1:] - r_p, axis=-1),
    )


def integrate(
    c0: ArrayLike,
    v0: ArrayLike,
    r0: ArrayLike,
    dalpha: ArrayLike,
    dv: ArrayLike,
    period: float,
    gravity: GravityFn,
    iterations: int = 3,
) -> tuple[F64, F64, F64]:
    """Integrate increments from an initial state with eqs. (2)-(4), gravity at the new position.

    ``g_m = g(R_m)`` appears on both sides of eq. (4); it is solved by fixed-point iteration
    starting from the linear extrapolation ``2 g_{m-1} - g_{m-2}``. The contraction factor is
    ``|∂g/∂R| T²/6`` (about 1e-11 at 100 Hz), so ``iterations`` = 3 reaches machine precision.

    Parameters
    ----------
    c0 : array (3, 3)
        ``C_{B_0}^{E0}``.
    v0, r0 : arrays (3,)
        Inertial velocity (m/s) and position (m) at t0, E0 axes.
    dalpha, dv : arrays (M, 3)
        Increments of cycles 1..M (rad, m/s, body axes).
    period : float
        T (s).
    gravity : callable
        ``g(R)`` (m/s², E0) for an array (..., 3) of E0 positions (m), e.g.
        :func:`strapdown_ros.core.gravity.gravitation`.
    iterations : int
        Fixed-point iterations for the implicit ``g_m``.

    Returns
    -------
    (C, V, R) : arrays (M+1, 3, 3), (M+1, 3), (M+1, 3)
        The integrated states at m = 0..M.
    """
    dalpha = np.asarray(dalpha, dtype=np.float64)
    dv = np.asarray(dv, dtype=np.float64)
    n = dalpha.shape[0]
    gc, gv, gr = g_matrices(dalpha)  # all cycles at once; only the recursion is sequential
    c = np.empty((n + 1, 3, 3))
    v = np.empty((n + 1, 3))
    r = np.empty((n + 1, 3))
    c[0], v[0], r[0] = c0, v0, r0
    t = float(period)
    g_prev = np.asarray(gravity(r[0]), dtype=np.float64)
    g_prev2 = g_prev
    for m in range(1, n + 1):
        cp = c[m - 1]
        dv_r = cp @ (gr[m - 1] @ dv[m - 1]) * t
        r_base = r[m - 1] + v[m - 1] * t + dv_r + g_prev * (t * t / 3.0)
        g_cur = 2.0 * g_prev - g_prev2
        for _ in range(iterations):
            g_cur = np.asarray(gravity(r_base + g_cur * (t * t / 6.0)), dtype=np.float64)
        r[m] = r_base + g_cur * (t * t / 6.0)
        v[m] = v[m - 1] + cp @ (gv[m - 1] @ dv[m - 1]) + 0.5 * (g_cur + g_prev) * t
        c[m] = cp @ gc[m - 1]
        g_prev2, g_prev = g_prev, g_cur
    return c, v, r
