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
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    A_WGS84,
    F_WGS84,
    OMEGA_IE,
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    e0_state_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
    radii,
)
from strapdown_ros.core.gravity import GRAVITY_MODELS, gravity_ned
from strapdown_ros.core.navigation import _kernels
from strapdown_ros.core.navigation.state import NavState
from strapdown_ros.core.rotations import dcm_from_quat, quat_from_dcm

__all__ = [
    "MODES",
    "MultirateNavigator",
    "NavSolution",
    "SimultaneousNavigator",
    "VerticalDamping",
    "fast_cycle",
    "navigate_multirate",
    "navigate_simultaneous",
]


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

    t: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    q_b_n: F64
    n: int


def fast_cycle(
    q: F64, dalpha: F64, dv: F64, dphi_l: F64, normalize: bool = True
) -> tuple[F64, F64]:
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


def _check_increments(dalpha: ArrayLike, dv: ArrayLike, n: int) -> tuple[F64, F64]:
    """Validate N and the increment arrays (M, 3)."""
    if n < 1:
        raise ValueError(f"N must be >= 1, got N={n}")
    da = np.asarray(dalpha, dtype=np.float64)
    dvv = np.asarray(dv, dtype=np.float64)
    if da.ndim != 2 or da.shape[1] != 3 or dvv.shape != da.shape:
        raise ValueError("dalpha and dv must both have shape (M, 3)")
    return da, dvv


def _rates(
    lat: float, alt: float, u: F64, table1_radii: bool
) -> tuple[float, float, F64, F64]:
    """``λ'``, ``Λ'`` (9), ``ω_il^l = Ω_l + ρ_l`` (33) and ``2Ω_l + ρ_l`` (14), NED."""
    rn, re = _radii(lat, table1_radii)
    sl, cl = math.sin(lat), math.cos(lat)
    lat_dot = float(u[0]) / (rn + alt)
    lon_dot = float(u[1]) / ((re + alt) * cl)
    w_il = np.array([(OMEGA_IE + lon_dot) * cl, -lat_dot, -(OMEGA_IE + lon_dot) * sl])
    w_cor = np.array([(2 * OMEGA_IE + lon_dot) * cl, -lat_dot, -(2 * OMEGA_IE + lon_dot) * sl])
    return lat_dot, lon_dot, w_il, w_cor


@dataclass(frozen=True)
class VerticalDamping:
    """Vertical-channel damping with an auxiliary altitude (Waldmann Table 1, ``s'``, ``s''``).

    Table 1 adds ``s'(h) = (h - h_aux)`` to ``ḣ`` (9) and ``s''(h) = [0, 0, h_aux - h]`` to
    ``U̇_g,l`` (29). With ``ḣ = -V_D`` those signs make the loop unstable (``δḧ = +δh ...``),
    so by default the loop is ``ḣ = -V_D - k1 (h - h_aux)``, ``U̇_D += k2 (h - h_aux)``:
    ``δḧ + k1 δḣ + (k2 - 2g/R) δh = 0``, stable for ``k1 > 0``, ``k2 > 2g/R ≈ 3.1e-6 s⁻²``.
    ``paper_signs=True`` applies Table 1 literally (``+k1``, ``-k2``) to reproduce it.

    Attributes
    ----------
    k1 : float
        Altitude-rate gain, 1/s (Table 1: 1).
    k2 : float
        Vertical-acceleration gain, 1/s² (Table 1: 1).
    paper_signs : bool
        Use Table 1's printed (destabilizing) signs.
    """

    k1: float = 1.0
    k2: float = 1.0
    paper_signs: bool = False

    @property
    def coefficients(self) -> tuple[float, float]:
        """``(c1, c2)`` with ``ḣ = -V_D + c1 (h - h_aux)`` and ``U̇_D += c2 (h - h_aux)``."""
        if self.paper_signs:
            return float(self.k1), -float(self.k2)
        return -float(self.k1), float(self.k2)


#: Navigator modes: Table 1 literally, or the high-accuracy mode.
MODES = ("paper", "exact")


def _engine(engine: str | None) -> str:
    if engine is None:
        return "numba" if _kernels.HAVE_NUMBA else "python"
    if engine not in ("numba", "python"):
        raise ValueError(f"unknown engine {engine!r}; available: 'numba', 'python'")
    if engine == "numba" and not _kernels.HAVE_NUMBA:
        raise ImportError("engine='numba' requires numba")
    return engine


def _kernel(fn, engine: str):
    """The compiled kernel, or its plain-Python form (``py_func``) for ``engine='python'``."""
    return fn if engine == "numba" else getattr(fn, "py_func", fn)


class _CycleNavigator:
    """What both stateful navigators share (a subclass computes the cycles, ``_cycles``).

    The checks of ``N``, ``T_gyr`` and the gravitation model, increments kept until they complete
    a ``T_nav`` cycle, the output times and the state carried from cycle to cycle.
    """

    n: int
    t_gyr: float
    damping: VerticalDamping | None

    def _init_cycles(
        self, initial: NavState, n: int, t_gyr: float, gravity_model: str,
        damping: VerticalDamping | None,
    ) -> None:  # fmt: skip
        if n < 1:
            raise ValueError(f"N must be >= 1, got N={n}")
        if not (t_gyr > 0.0 and math.isfinite(t_gyr)):
            raise ValueError(f"T_gyr must be a positive number of seconds, got {t_gyr!r}")
        if gravity_model not in GRAVITY_MODELS:
            raise ValueError(f"unknown gravity model {gravity_model!r}")
        self.n, self.t_gyr, self.gravity_model = int(n), float(t_gyr), gravity_model
        self.damping = damping
        self._pending_da = np.empty((0, 3))
        self._pending_dv = np.empty((0, 3))
        self._t_start, self._done = float(initial.t), 0

    @property
    def t_nav(self) -> float:
        """Navigation period ``T_nav = N T_gyr``, s."""
        return self.n * self.t_gyr

    @property
    def state(self) -> NavState:
        """The state at the end of the last completed ``T_nav`` cycle."""
        return self._state

    @property
    def pending(self) -> int:
        """Increments received but not yet used (fewer than N)."""
        return int(self._pending_da.shape[0])

    def run(self, dalpha: ArrayLike, dv: ArrayLike, h_aux: ArrayLike | None = None) -> NavSolution:
        """Process increments; return the outputs of the ``T_nav`` cycles they complete.

        Parameters
        ----------
        dalpha, dv : array_like (M, 3)
            Next increments ``Δφ_b`` (rad), ``Δβ_b`` (m/s), body FRD, at ``T_gyr``. Increments
            that do not complete a cycle are kept for the next call.
        h_aux : array_like (K,), optional
            Auxiliary altitude (m) at the start of each completed cycle (``damping`` only);
            K = ``(pending + M) // N``.

        Returns
        -------
        NavSolution
            The K new outputs (at the ends of the completed cycles; may be empty).
        """
        da, dvv, cycles, haux = _take_cycles(self, dalpha, dv, h_aux)
        out = self._cycles(da, dvv, cycles, haux)
        self._done += cycles
        if cycles:
            self._state = NavState(
                float(out.t[-1]), float(out.lat[-1]), float(out.lon[-1]), float(out.alt[-1]),
                out.v_ned[-1].copy(), out.q_b_n[-1].copy(),
            )  # fmt: skip
        return out

    def _cycles(self, da: F64, dvv: F64, cycles: int, haux: F64) -> NavSolution:
        raise NotImplementedError

    def _times(self, cycles: int) -> F64:
        """Output times ``t_start + j T_nav`` from the integer cycle count (no drift)."""
        return self._t_start + self.t_nav * (self._done + np.arange(1, cycles + 1))


def _paper_start(st: NavState) -> tuple[float, float, float, F64, F64]:
    """``λ, Λ, h`` (floats) and copies of ``U_l``, ``q_b^l``: a paper-mode loop's variables."""
    u = np.asarray(st.v_ned, dtype=np.float64).copy()
    q = np.asarray(st.q_b_n, dtype=np.float64).copy()
    return float(st.lat), float(st.lon), float(st.alt), u, q


def _outputs(cycles: int) -> tuple[F64, F64, F64]:
    """Empty ``λ, Λ, h`` (cycles, 3), ``U_l`` (cycles, 3) and ``q_b^l`` (cycles, 4) rows."""
    return np.empty((cycles, 3)), np.empty((cycles, 3)), np.empty((cycles, 4))


def _cycle_terms(
    nav: _CycleNavigator, lat: float, alt: float, u: F64, h_aux: float
) -> tuple[float, float, F64, F64, F64, float]:
    """At a paper-mode cycle's start: :func:`_rates`, ``g_l`` (NED), ``h - h_aux`` (0 undamped)."""
    lat_dot, lon_dot, w_il, w_cor = _rates(lat, alt, u, nav.table1_radii)
    g_l = gravity_ned(lat, alt, nav.gravity_model)
    sv = alt - h_aux if nav.damping is not None else 0.0
    return lat_dot, lon_dot, w_il, w_cor, g_l, sv


class MultirateNavigator(_CycleNavigator):
    """Stateful multirate b–l split navigator: feed increments, get ``T_nav`` outputs.

    The offline function :func:`navigate_multirate` and the ROS ``navigator_node`` both run
    this class, so a stream processed in one call or cycle by cycle gives identical results
    (the state between calls is the float64 state the kernels carry anyway).

    Modes
    -----
    ``"paper"``
        Waldmann Table 1 and eq. (33) literally (first-order Euler in every layer); see the
        module docstring.
    ``"exact"``
        High-accuracy mode with the same three-rate structure (docs/navigator.md):

        * fast (``T_gyr``): per increment, the exact constant-rate/constant-specific-force
          update of Savage 2020 eqs. (2)-(4) (``G_C``, ``G_V``, ``G_R``), composed over the
          cycle in the body frame ``B_k`` of its start and reset every ``T_nav``
          (:func:`~strapdown_ros.core.navigation._kernels.exact_fast_kernel`). This is
          Savage 1998's two-speed velocity/position algorithm "compressed into a single
          high-speed format" (Part 2, Sec. VI): the composed ``Γ``, ``W``, ``S`` contain the
          coning (Part 1), sculling (Part 2 eq. (38)) and scrolling (eq. (85)) terms
          exactly for piecewise-constant rate and specific force — the model of docs/interface.md
          §3;
        * intermediate (``T_int``): gravitation integrated by the trapezoid rule on P
          sub-steps in the inertial frame ``I_k`` (ECEF frozen at ``t_k``), where the
          Coriolis and transport-rate terms of (29) vanish identically;
        * slow (``T_nav``): position, velocity and ``C_B^E`` updated in ``I_k`` and rotated
          back to ECEF by the Earth's rotation over the cycle in closed form — the exact
          counterpart of the ``Δφ_l`` frame rotation of eq. (33). Outputs are converted to
          ``λ, Λ, h, U_l, q_b^l`` at every ``T_nav``.

        No vertical damping (with ideal data its errors are at machine level).

    Parameters
    ----------
    initial : NavState
        State at the start.
    t_gyr : float
        Fast period ``T_gyr`` (the IMU period), s.
    n, p : int
        ``N = T_nav / T_gyr`` and ``P = T_nav / T_int``, ≥ 1.
    mode : str
        ``"paper"`` or ``"exact"``.
    gravity_model : str
        Gravitation model (docs/interface.md §1), the generator's by default.
    normalize : bool
        ``paper`` mode: normalize ``q_b^l`` after each fast step.
    table1_radii : bool
        ``paper`` mode: Table 1's first-order ``R_N``, ``R_E``.
    damping : VerticalDamping or None
        ``paper`` mode: vertical damping (needs ``h_aux`` in :meth:`run`).
    engine : str or None
        ``"numba"`` (default when numba imports) or ``"python"`` (the same kernels,
        interpreted; for ``paper`` mode the per-cycle numpy loop).
    """

    def __init__(
        self,
        initial: NavState,
        t_gyr: float,
        n: int,
        p: int,
        mode: str = "paper",
        gravity_model: str = "j2",
        normalize: bool = True,
        table1_radii: bool = False,
        damping: VerticalDamping | None = None,
        engine: str | None = None,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r}; available: {', '.join(map(repr, MODES))}")
        if p < 1:
            raise ValueError(f"P must be >= 1, got P={p}")
        if damping is not None and mode != "paper":
            raise ValueError("vertical damping is a 'paper' mode option")
        self._init_cycles(initial, n, t_gyr, gravity_model, damping)
        self.mode, self.p = mode, int(p)
        self.normalize, self.table1_radii = normalize, table1_radii
        self.engine = _engine(engine)
        self._set_state(initial)

    def _set_state(self, st: NavState) -> None:
        self._state = NavState(
            float(st.t), float(st.lat), float(st.lon), float(st.alt),
            np.array(st.v_ned, dtype=np.float64), np.array(st.q_b_n, dtype=np.float64),
        )  # fmt: skip
        if self.mode == "exact":
            # E0 of the navigator: ECEF at the initial instant (docs/interface.md §1); R, V, C_B^E0.
            c_n_e = dcm_ned_to_ecef(st.lat, st.lon)
            r_e = geodetic_to_ecef(st.lat, st.lon, st.alt)
            self._r0 = r_e.astype(np.float64)
            self._v0 = c_n_e @ self._state.v_ned + np.cross([0.0, 0.0, OMEGA_IE], r_e)
            self._c0 = c_n_e @ dcm_from_quat(self._state.q_b_n)
            self._lo = np.zeros(6)

    def _cycles(self, da: F64, dvv: F64, cycles: int, haux: F64) -> NavSolution:
        if self.mode == "exact":
            return self._run_exact(da, dvv, cycles)
        if self.engine == "numba":
            return self._run_paper_kernel(da, dvv, cycles, haux)
        return self._run_paper_python(da, dvv, cycles, haux)

    def _run_paper_kernel(self, da: F64, dvv: F64, cycles: int, haux: F64) -> NavSolution:
        st = self._state
        pos = np.empty((cycles + 1, 3))
        vel = np.empty((cycles + 1, 3))
        quat = np.empty((cycles + 1, 4))
        c1, c2 = self.damping.coefficients if self.damping is not None else (0.0, 0.0)
        _kernels.multirate_kernel(
            st.lat, st.lon, st.alt, st.v_ned, st.q_b_n, da, dvv, self.t_gyr, self.n, self.p,
            _kernels.GRAVITY_CODES[self.gravity_model], bool(self.normalize),
            bool(self.table1_radii), pos, vel, quat, self.damping is not None, c1, c2, haux,
        )  # fmt: skip
        return NavSolution(
            self._times(cycles), pos[1:, 0], pos[1:, 1], pos[1:, 2], vel[1:], quat[1:], self.n
        )

    def _run_paper_python(self, da: F64, dvv: F64, cycles: int, haux: F64) -> NavSolution:
        st, n, p = self._state, self.n, self.p
        t_nav = self.t_nav
        t_int = t_nav / p
        c1, c2 = self.damping.coefficients if self.damping is not None else (0.0, 0.0)
        lat, lon, alt, u, q = _paper_start(st)
        pos, vel, quat = _outputs(cycles)
        for j in range(cycles):
            lat_dot, lon_dot, w_il, w_cor, g_l, sv = _cycle_terms(self, lat, alt, u, haux[j])
            if self.damping is not None:
                g_l = g_l + np.array([0.0, 0.0, c2 * sv])  # s'' (29)

            # Fast boundary layer, V_f,b(0) = 0 (19), q_b^l (33).
            sl_ = slice(j * n, (j + 1) * n)
            q, v_fb = fast_cycle(q, da[sl_], dvv[sl_], self.t_gyr * w_il, self.normalize)

            # Intermediate boundary layer (29), U_g,l(0) = U_l (27).
            u_g = u.copy()
            for _ in range(p):
                u_g = u_g + t_int * (-np.cross(w_cor, u_g) + g_l)

            # Slow: position (9) with V(k) (and s'), then U_l (32) with the updated D_l^b (33).
            lat, lon = lat + t_nav * lat_dot, lon + t_nav * lon_dot
            alt = alt + t_nav * (-u[2] + c1 * sv) if self.damping else alt - t_nav * u[2]
            u = u_g + dcm_from_quat(q) @ v_fb
            pos[j], vel[j], quat[j] = (lat, lon, alt), u, q
        return NavSolution(self._times(cycles), pos[:, 0], pos[:, 1], pos[:, 2], vel, quat, n)

    def _run_exact(self, da: F64, dvv: F64, cycles: int) -> NavSolution:
        r = np.empty((cycles + 1, 3))
        v = np.empty((cycles + 1, 3))
        c = np.empty((cycles + 1, 3, 3))
        r[0], v[0], c[0] = self._r0, self._v0, self._c0
        kernel = _kernel(_kernels.exact_kernel, self.engine)
        kernel(r, v, c, self._lo, da, dvv, self.t_gyr, self.n, self.p,
               _kernels.GRAVITY_CODES[self.gravity_model])  # fmt: skip
        self._r0, self._v0, self._c0 = r[-1].copy(), v[-1].copy(), c[-1].copy()
        # E0 -> ECEF at t = j T_nav since the navigator's start (docs/interface.md §1), then l-frame
        # terms.
        j = self._done + np.arange(1, cycles + 1)
        r_e, v_e, c_be = e0_state_to_ecef(j * self.t_nav, r[1:], v[1:], c[1:])
        lat, lon, alt = ecef_to_geodetic(r_e)
        c_e_n = dcm_ecef_to_ned(lat, lon)
        v_ned = np.einsum("nij,nj->ni", c_e_n, v_e)
        q = quat_from_dcm(c_e_n @ c_be) if cycles else np.empty((0, 4))
        return NavSolution(self._times(cycles), lat, lon, alt, v_ned, q, self.n)


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
    damping: VerticalDamping | None = None,
    h_aux: ArrayLike | None = None,
) -> NavSolution:
    """Run the multirate b–l split navigator (Waldmann Table 1) over a whole increment array.

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
        Gravitation model for ``g_l`` (docs/interface.md §1).
    normalize : bool
        Normalize ``q_b^l`` after each fast step (``paper`` mode).
    table1_radii : bool
        Use Table 1's first-order ``R_N``, ``R_E`` instead of the exact WGS-84 radii.
    mode : str
        ``"paper"`` (Table 1 and eq. (33) literally, first order) or ``"exact"`` (the
        high-accuracy mode, :class:`MultirateNavigator`).
    engine : str or None
        ``"numba"``: all cycles in one compiled kernel; ``"python"``: the per-cycle Python loop
        (``paper``) or the interpreted kernel (``exact``). ``None``: numba when importable.
        The two agree to rounding (~1e-13 relative).
    damping : VerticalDamping or None
        Vertical-channel damping (``paper`` mode), with ``h_aux`` (M // N,) the auxiliary
        altitude at the start of every cycle.

    Returns
    -------
    NavSolution
        State at ``t0 + j T_nav``, j = 0..M // N.
    """
    nav = MultirateNavigator(
        initial, t_gyr, n, p, mode=mode, gravity_model=gravity_model, normalize=normalize,
        table1_radii=table1_radii, damping=damping, engine=engine,
    )  # fmt: skip
    return _with_initial(nav.state, nav.run(dalpha, dv, h_aux))


class SimultaneousNavigator(_CycleNavigator):
    """Waldmann's simultaneous l-frame scheme (Table 2), stateful like :class:`MultirateNavigator`.

    The quaternion (33) is updated at ``T_gyr`` as in the multirate ``paper`` mode; velocity
    (14) and position (9) are integrated together by Euler at ``T_nav = N T_gyr``:
    ``U_l(k+1) = U_l(k) + T_nav {-[(2Ω + ρ)×] U_l(k) + f_l(k) + g_l(R(k)) + s''(h(k))}`` with
    ``f_l = D_l^b f_b`` (15) and the *sampled* specific force
    ``f_b(k) = Δβ_b(n T_gyr) / T_gyr`` at ``k T_nav = n T_gyr`` (the first increment of the
    cycle, Table 2), ``D_l^b`` at ``k T_nav``. Optional vertical damping as in Table 1.

    Parameters
    ----------
    initial, t_gyr, n, gravity_model, normalize, table1_radii, damping
        As in :class:`MultirateNavigator`.
    """

    mode = "paper"
    p = 1
    engine = "python"

    def __init__(
        self,
        initial: NavState,
        t_gyr: float,
        n: int,
        gravity_model: str = "j2",
        normalize: bool = True,
        table1_radii: bool = False,
        damping: VerticalDamping | None = None,
    ) -> None:
        self._init_cycles(initial, n, t_gyr, gravity_model, damping)
        self.normalize, self.table1_radii = normalize, table1_radii
        self._state = initial

    def _cycles(self, da: F64, dvv: F64, cycles: int, haux: F64) -> NavSolution:
        n, t_nav = self.n, self.t_nav
        c1, c2 = self.damping.coefficients if self.damping is not None else (0.0, 0.0)
        lat, lon, alt, u, q = _paper_start(self._state)
        pos, vel, quat = _outputs(cycles)
        for j in range(cycles):
            lat_dot, lon_dot, w_il, w_cor, g_l, sv = _cycle_terms(self, lat, alt, u, haux[j])
            f_l = dcm_from_quat(q) @ (dvv[j * n] / self.t_gyr)  # (15) with the sampled f_b(k)
            sl_ = slice(j * n, (j + 1) * n)
            q, _ = fast_cycle(q, da[sl_], dvv[sl_], self.t_gyr * w_il, self.normalize)  # (33)
            lat, lon = lat + t_nav * lat_dot, lon + t_nav * lon_dot  # (9)
            alt = alt + t_nav * (-u[2] + c1 * sv)
            u = u + t_nav * (-np.cross(w_cor, u) + f_l + g_l + np.array([0.0, 0.0, c2 * sv]))
            pos[j], vel[j], quat[j] = (lat, lon, alt), u, q
        return NavSolution(self._times(cycles), pos[:, 0], pos[:, 1], pos[:, 2], vel, quat, n)


def _take_cycles(
    nav: _CycleNavigator,
    dalpha: ArrayLike,
    dv: ArrayLike,
    h_aux: ArrayLike | None,
) -> tuple[F64, F64, int, F64]:
    """The whole ``T_nav`` cycles of pending + new increments (the rest stays pending).

    Returns the increments of those cycles (contiguous), their number K and the auxiliary
    altitudes (K,) (zeros without damping; checked present and of length K with it).
    """
    da, dvv = _check_increments(dalpha, dv, nav.n)
    if nav._pending_da.shape[0]:
        da = np.concatenate([nav._pending_da, da])
        dvv = np.concatenate([nav._pending_dv, dvv])
    cycles = da.shape[0] // nav.n
    used = cycles * nav.n
    nav._pending_da, nav._pending_dv = da[used:].copy(), dvv[used:].copy()
    haux = np.zeros(cycles)
    if nav.damping is not None:
        if h_aux is None:
            raise ValueError("vertical damping needs the auxiliary altitude h_aux")
        haux = np.asarray(h_aux, dtype=np.float64).reshape(-1)
        if haux.shape[0] != cycles:
            raise ValueError(f"h_aux has {haux.shape[0]} values for {cycles} cycles")
    return np.ascontiguousarray(da[:used]), np.ascontiguousarray(dvv[:used]), cycles, haux


def _with_initial(first: NavState, out: NavSolution) -> NavSolution:
    """``out`` with the initial state prepended (the offline functions' convention)."""
    return NavSolution(
        np.concatenate([[first.t], out.t]),
        np.concatenate([[first.lat], out.lat]),
        np.concatenate([[first.lon], out.lon]),
        np.concatenate([[first.alt], out.alt]),
        np.concatenate([np.asarray(first.v_ned, dtype=np.float64)[None], out.v_ned]),
        np.concatenate([np.asarray(first.q_b_n, dtype=np.float64)[None], out.q_b_n]),
        out.n,
    )


def navigate_simultaneous(
    initial: NavState,
    dalpha: ArrayLike,
    dv: ArrayLike,
    t_gyr: float,
    n: int,
    gravity_model: str = "j2",
    normalize: bool = True,
    table1_radii: bool = False,
    damping: VerticalDamping | None = None,
    h_aux: ArrayLike | None = None,
) -> NavSolution:
    """Waldmann's simultaneous l-frame scheme (Table 2) over a whole increment array.

    See :class:`SimultaneousNavigator`; arguments as in :func:`navigate_multirate`.

    Returns
    -------
    NavSolution
        State at ``t0 + j T_nav``, j = 0..M // N.
    """
    nav = SimultaneousNavigator(initial, t_gyr, n, gravity_model, normalize, table1_radii, damping)
    return _with_initial(initial, nav.run(dalpha, dv, h_aux))
