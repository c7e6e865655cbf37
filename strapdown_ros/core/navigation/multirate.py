"""Waldmann's multirate modified b–l split-coordinate navigator (seeds/004, Table 1).

Three computation rates (Waldmann §4.4, Table 1), with ``T_nav = N T_gyr = P T_int``:

* **fast** (``T_gyr``, every IMU increment): thrust velocity in body axes, eq. (19) Euler form
  ``V_f,b(k+1) = V_f,b(k) - [Δφ_b(k)×] V_f,b(k) + Δβ_b(k)``, ``V_f,b ← 0`` every ``T_nav``;
  and the relative quaternion ``q_b^l`` of eq. (33) (first order):
  ``q(k+1) = (I_4 - ½[Δφ_l] + ½[Δφ_b]) q(k)``, i.e. in Hamilton form
  ``q(k+1) = q + ½ q ⊗ (0, Δφ_b) - ½ (0, Δφ_l) ⊗ q`` with ``Δφ_l = T_gyr ω_il^l``,
  ``ω_il^l = [(Ω + Λ') cos λ, -λ', -(Ω + Λ') sin λ]`` held over the ``T_nav`` cycle.
* **intermediate** (``T_int = T_nav / P``): gravity-driven ground velocity, eq. (29) Euler form
  ``U_g,l(k+1) = U_g,l(k) + T_int {-[(2Ω + ρ)×] U_g,l(k) + g_l(R(k))}`` with position, ρ and
  ``g_l`` frozen at the start of the ``T_nav`` cycle; ``U_g,l ← U_l`` every ``T_nav`` (27).
* **slow** (``T_nav``): ground velocity by eq. (32) ``U_l = U_g,l + D_l^b V_f,b`` and
  latitude, longitude, altitude by eq. (9) Euler form with ``V(k)`` and ``R_N(λ(k))``,
  ``R_E(λ(k))``.

``g_l`` is the plumb-bob gravity of the stream's gravitation model in NED
(:func:`strapdown_ros.core.gravity.gravity_ned`), which Waldmann takes "from WGS-84". The
radii are the exact WGS-84 ones by default; ``table1_radii=True`` uses Table 1's first-order
``R_N = R_0 (1 - 2e + 3e sin²λ)``, ``R_E = R_0 (1 + e sin²λ)`` (``R_0 = a``, ``e = f``).
Vertical-channel damping (``s'``, ``s''``) is not implemented (no altimeter input yet).

:func:`navigate_simultaneous` is the simultaneous l-frame scheme of Table 2 (Euler on (14) and
(9) at ``T_nav`` with the sampled specific force, quaternion (33) at ``T_gyr``), for comparison.

Deviation from a literal reading, documented in ``docs/navigator.md``: the quaternion is
normalized after each fast step when ``normalize=True`` (default); eq. (33) itself does not
say, and ``D_l^b`` is computed from the normalized quaternion in any case.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.earth import A_WGS84, F_WGS84, OMEGA_IE, radii
from strapdown_ros.core.gravity import GRAVITY_MODELS, gravity_ned
from strapdown_ros.core.navigation import _kernels
from strapdown_ros.core.navigation.state import NavState
from strapdown_ros.core.rotations import dcm_from_quat

Array = NDArray[np.float64]

__all__ = ["NavSolution", "fast_cycle", "navigate_multirate", "navigate_simultaneous"]


@dataclass(frozen=True)
class NavSolution:
    """Navigation outputs at every ``T_nav`` (including the initial state).

    Attributes
    ----------
    t : array (K+1,)
        Time since the stream's E0 epoch, s.
    lat, lon, alt : arrays (K+1,)
        Geodetic latitude, longitude (rad) and ellipsoidal altitude (m).
    v_ned : array (K+1, 3)
        Ground velocity ``U_l``, m/s.
    q_b_n : array (K+1, 4)
        Quaternion ``q_b^l`` of ``C_B^N`` (body FRD to NED), scalar first.
    n : int
        Fast steps per ``T_nav`` (N).
    """

    t: Array
    lat: Array
    lon: Array
    alt: Array
    v_ned: Array
    q_b_n: Array
    n: int


def fast_cycle(
    q: Array, dalpha: Array, dv: Array, dphi_l: Array, normalize: bool = True
) -> tuple[Array, Array]:
    """One ``T_nav`` cycle of the fast boundary layer: eqs. (19) and (33) over N increments.

    Runs the plain-Python form of :func:`~strapdown_ros.core.navigation._kernels.fast_cycle_kernel`
    (the scalar loop the compiled engine uses).

    Parameters
    ----------
    q : array (4,)
        ``q_b^l`` at the start of the cycle (Hamilton, scalar first, body FRD to NED).
    dalpha, dv : arrays (N, 3)
        Angle and velocity increments ``Δφ_b``, ``Δβ_b`` (FRD), rad and m/s.
    dphi_l : array (3,)
        ``Δφ_l = T_gyr ω_il^l`` (rad), the local-level rotation per fast step, eq. (33).
    normalize : bool
        Normalize ``q`` after each step.

    Returns
    -------
    q : array (4,)
        ``q_b^l`` at the end of the cycle.
    v_fb : array (3,)
        Thrust velocity ``V_f,b`` at the end of the cycle (from ``V_f,b = 0``), body axes, m/s.
    """
    # One implementation of the loop: the kernel's plain-Python form (numba keeps it as
    # ``py_func``); the compiled engine runs the same code in ``_kernels.multirate_kernel``.
    kernel = getattr(_kernels.fast_cycle_kernel, "py_func", _kernels.fast_cycle_kernel)
    q_out = np.empty(4)
    v_out = np.empty(3)
    half = 0.5 * np.asarray(dphi_l, dtype=np.float64)
    da = np.asarray(dalpha, dtype=np.float64)
    dvv = np.asarray(dv, dtype=np.float64)
    hx, hy, hz = (float(h) for h in half)
    kernel(np.asarray(q, dtype=np.float64), da, dvv, 0, da.shape[0], hx, hy, hz, bool(normalize),
           q_out, v_out)  # fmt: skip
    return q_out, v_out


def _radii(lat: float, table1: bool) -> tuple[float, float]:
    """``(R_N, R_E)``: exact WGS-84 or Table 1's first-order forms."""
    if table1:
        s2 = math.sin(lat) ** 2
        return (
            A_WGS84 * (1.0 - 2.0 * F_WGS84 + 3.0 * F_WGS84 * s2),
            A_WGS84 * (1.0 + F_WGS84 * s2),
        )
    rn, re = radii(lat)
    return float(rn), float(re)


def _check_increments(dalpha: ArrayLike, dv: ArrayLike, n: int) -> tuple[Array, Array]:
    """Validate N and the increment arrays (M, 3)."""
    if n < 1:
        raise ValueError(f"N must be >= 1, got N={n}")
    da = np.asarray(dalpha, dtype=np.float64)
    dvv = np.asarray(dv, dtype=np.float64)
    if da.ndim != 2 or da.shape[1] != 3 or dvv.shape != da.shape:
        raise ValueError("dalpha and dv must both have shape (M, 3)")
    return da, dvv


def _rates(
    lat: float, alt: float, u: Array, table1_radii: bool
) -> tuple[float, float, Array, Array]:
    """``λ'``, ``Λ'`` (9), ``ω_il^l = Ω_l + ρ_l`` (33) and ``2Ω_l + ρ_l`` (14), NED."""
    rn, re = _radii(lat, table1_radii)
    sl, cl = math.sin(lat), math.cos(lat)
    lat_dot = float(u[0]) / (rn + alt)
    lon_dot = float(u[1]) / ((re + alt) * cl)
    w_il = np.array([(OMEGA_IE + lon_dot) * cl, -lat_dot, -(OMEGA_IE + lon_dot) * sl])
    w_cor = np.array([(2 * OMEGA_IE + lon_dot) * cl, -lat_dot, -(2 * OMEGA_IE + lon_dot) * sl])
    return lat_dot, lon_dot, w_il, w_cor


def navigate_multirate(
    initial: NavState,
    dalpha: ArrayLike,
    dv: ArrayLike,
    t_gyr: float,
    n: int,
    p: int,
    gravity_model: str = "j2",
    normalize: bool = True,
    table1_radii: bool = False,
    mode: str = "paper",
    engine: str | None = None,
) -> NavSolution:
    """Run the multirate b–l split navigator of Waldmann Table 1 (``paper`` mode).

    Parameters
    ----------
    initial : NavState
        State at the start (``λ(0), Λ(0), h(0)`` (9), ``U_l(0)`` (27), ``q_b^l(0)`` (33)).
    dalpha, dv : array_like (M, 3)
        Increments ``Δφ_b`` (rad) and ``Δβ_b`` (m/s) in body FRD at ``T_gyr``; only the first
        ``(M // N) N`` are used.
    t_gyr : float
        Fast period ``T_gyr`` (the IMU period), s.
    n : int
        ``N = T_nav / T_gyr`` (fast steps per navigation cycle), ≥ 1.
    p : int
        ``P = T_nav / T_int`` (intermediate steps per navigation cycle), ≥ 1.
    gravity_model : str
        Gravitation model for ``g_l`` (SPEC §1).
    normalize : bool
        Normalize ``q_b^l`` after each fast step.
    table1_radii : bool
        Use Table 1's first-order ``R_N``, ``R_E`` instead of the exact WGS-84 radii.
    mode : str
        ``"paper"`` (Table 1 and eq. (33) literally, first order); no other mode yet.
    engine : str or None
        ``"numba"``: all cycles in the compiled kernel
        (:func:`strapdown_ros.core.navigation._kernels.multirate_kernel`); ``"python"``: the
        per-cycle Python loop below. ``None`` (default): ``"numba"`` if numba is importable,
        else ``"python"``. The two agree to rounding (~1e-13 relative).

    Returns
    -------
    NavSolution
        State at ``t0 + j T_nav``, j = 0..M // N.
    """
    if mode != "paper":
        raise ValueError(f"unknown mode {mode!r}; available: 'paper'")
    if p < 1:
        raise ValueError(f"P must be >= 1, got P={p}")
    if engine is None:
        engine = "numba" if _kernels.HAVE_NUMBA else "python"
    if engine not in ("numba", "python"):
        raise ValueError(f"unknown engine {engine!r}; available: 'numba', 'python'")
    if engine == "numba" and not _kernels.HAVE_NUMBA:
        raise ImportError("engine='numba' requires numba")
    if gravity_model not in GRAVITY_MODELS:
        raise ValueError(f"unknown gravity model {gravity_model!r}")
    da, dvv = _check_increments(dalpha, dv, n)
    cycles = da.shape[0] // n
    t_nav = n * t_gyr
    t_int = t_nav / p

    out_t = initial.t + t_nav * np.arange(cycles + 1)
    out_pos = np.empty((cycles + 1, 3))
    out_v = np.empty((cycles + 1, 3))
    out_q = np.empty((cycles + 1, 4))
    lat, lon, alt = float(initial.lat), float(initial.lon), float(initial.alt)
    u = np.asarray(initial.v_ned, dtype=np.float64).copy()
    q = np.asarray(initial.q_b_n, dtype=np.float64).copy()
    out_pos[0], out_v[0], out_q[0] = (lat, lon, alt), u, q

    if engine == "numba":
        _kernels.multirate_kernel(
            lat, lon, alt, u, q, np.ascontiguousarray(da), np.ascontiguousarray(dvv),
            float(t_gyr), int(n), int(p), _kernels.GRAVITY_CODES[gravity_model],
            bool(normalize), bool(table1_radii), out_pos, out_v, out_q,
        )  # fmt: skip
        return NavSolution(out_t, out_pos[:, 0], out_pos[:, 1], out_pos[:, 2], out_v, out_q, n)

    for j in range(cycles):
        lat_dot, lon_dot, w_il, w_cor = _rates(lat, alt, u, table1_radii)
        g_l = gravity_ned(lat, alt, gravity_model)

        # Fast boundary layer, V_f,b(0) = 0 (19), q_b^l (33).
        sl_ = slice(j * n, (j + 1) * n)
        q, v_fb = fast_cycle(q, da[sl_], dvv[sl_], t_gyr * w_il, normalize)

        # Intermediate boundary layer (29), U_g,l(0) = U_l (27).
        u_g = u.copy()
        for _ in range(p):
            u_g = u_g + t_int * (-np.cross(w_cor, u_g) + g_l)

        # Slow: position (9) with V(k), then U_l (32) with the updated D_l^b (33).
        lat, lon, alt = (
            lat + t_nav * lat_dot,
            lon + t_nav * lon_dot,
            alt - t_nav * u[2],
        )
        u = u_g + dcm_from_quat(q) @ v_fb
        out_pos[j + 1], out_v[j + 1], out_q[j + 1] = (lat, lon, alt), u, q

    return NavSolution(out_t, out_pos[:, 0], out_pos[:, 1], out_pos[:, 2], out_v, out_q, n)


def navigate_simultaneous(
    initial: NavState,
    dalpha: ArrayLike,
    dv: ArrayLike,
    t_gyr: float,
    n: int,
    gravity_model: str = "j2",
    normalize: bool = True,
    table1_radii: bool = False,
) -> NavSolution:
    """Waldmann's simultaneous l-frame scheme (Table 2), for comparison with Table 1.

    The quaternion (33) is updated at ``T_gyr`` as in :func:`navigate_multirate`; velocity (14)
    and position (9) are integrated together by Euler at ``T_nav = N T_gyr``:
    ``U_l(k+1) = U_l(k) + T_nav {-[(2Ω + ρ)×] U_l(k) + f_l(k) + g_l(R(k))}`` with
    ``f_l = D_l^b f_b`` (15) and the *sampled* specific force
    ``f_b(k) = Δβ_b(n T_gyr) / T_gyr`` at ``k T_nav = n T_gyr`` (the first increment of the
    cycle, Table 2), ``D_l^b`` at ``k T_nav``. No vertical damping.

    Parameters
    ----------
    initial, dalpha, dv, t_gyr, n, gravity_model, normalize, table1_radii
        As in :func:`navigate_multirate`.

    Returns
    -------
    NavSolution
        State at ``t0 + j T_nav``, j = 0..M // N.
    """
    da, dvv = _check_increments(dalpha, dv, n)
    cycles = da.shape[0] // n
    t_nav = n * t_gyr
    out_t = initial.t + t_nav * np.arange(cycles + 1)
    out_pos = np.empty((cycles + 1, 3))
    out_v = np.empty((cycles + 1, 3))
    out_q = np.empty((cycles + 1, 4))
    lat, lon, alt = initial.lat, initial.lon, initial.alt
    u = np.asarray(initial.v_ned, dtype=np.float64).copy()
    q = np.asarray(initial.q_b_n, dtype=np.float64).copy()
    out_pos[0], out_v[0], out_q[0] = (lat, lon, alt), u, q
    for j in range(cycles):
        lat_dot, lon_dot, w_il, w_cor = _rates(lat, alt, u, table1_radii)
        g_l = gravity_ned(lat, alt, gravity_model)
        f_l = dcm_from_quat(q) @ (dvv[j * n] / t_gyr)  # (15) with the sampled f_b(k)
        sl_ = slice(j * n, (j + 1) * n)
        q, _ = fast_cycle(q, da[sl_], dvv[sl_], t_gyr * w_il, normalize)  # (33)
        lat, lon, alt = lat + t_nav * lat_dot, lon + t_nav * lon_dot, alt - t_nav * u[2]  # (9)
        u = u + t_nav * (-np.cross(w_cor, u) + f_l + g_l)  # (14)
        out_pos[j + 1], out_v[j + 1], out_q[j + 1] = (lat, lon, alt), u, q
    return NavSolution(out_t, out_pos[:, 0], out_pos[:, 1], out_pos[:, 2], out_v, out_q, n)
