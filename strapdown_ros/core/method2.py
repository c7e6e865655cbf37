"""Savage 2020 Method 2: increments that meet attitude, position and velocity constraints.

Given, at every cycle m = 0..M of period T, the constrained attitude ``C_{Bvar_m}^{E0}``
(eq. (5)), and at the even cycles m = 2n the constrained position ``R_var`` (eqs. (6)-(7)) and
velocity ``V_var`` (eq. (10)), Method 2 finds the integrated angular rate Δα_m (eq. (8)) and,
pair by pair, the integrated specific force Δv_{2n-1}, Δv_{2n} (eq. (31), i.e. eqs. (23)-(30))
such that the exact update of eqs. (2)-(4) reproduces the constraints at every even cycle.

Every quantity of eq. (31) is known from the constraints, so all pairs are solved at once
(vectorized, no loop over cycles). The only coupling is gravity at the odd cycles,
``g_{2n-1} = g(R_{2n-1})``, where R_{2n-1} is the (unconstrained) odd-cycle position that eq. (4)
produces: it is found by fixed-point iteration over the whole array (contraction factor
``|∂g/∂R| T²`` ≈ 1e-11, so two passes reach machine precision).

The reference trajectory itself is *regenerated* through the same routine with zero offsets
(S = 0, ``C_Bvar^Bref = I``): Savage 2020, "Generating variation and reference trajectory
outputs". That makes every stream obey the docs/interface.md §3 exactness rule by construction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core import _compiled as _k
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.exact_update import GravityFn, g_matrices
from strapdown_ros.core.rotations import rotvec_from_dcm
from strapdown_ros.core.series import rotation_coefficients

__all__ = [
    "Method2Solution",
    "attitude_increments",
    "method2",
    "PairSystem",
    "pair_displacement",
]



def _mv(m: F64, v: F64) -> F64:
    return np.einsum("...ij,...j->...i", m, v)


def attitude_increments(c_b_e0: ArrayLike) -> F64:
    """Δα_m of Savage 2020 eq. (8): rotation vector of ``G_C = C_{m-1}ᵀ C_m``.

    Parameters
    ----------
    c_b_e0 : array (M+1, 3, 3)
        Constrained attitudes ``C_{Bvar_m}^{E0}`` (eq. (5)), m = 0..M.

    Returns
    -------
    array (M, 3)
        Δα_m (rad, body axes), m = 1..M; exact at any angle up to π per cycle.
    """
    c = np.asarray(c_b_e0, dtype=np.float64)
    return rotvec_from_dcm(_k.matmul33(c[:-1], c[1:], transpose_a=True))


def _inv3(m: F64) -> F64:
    """Inverses of an array of 3x3 matrices by the adjugate (fast for well-conditioned ones)."""
    # Work on contiguous rows (one per matrix element) rather than strided views.
    a, b, c, d, e, f, g, h, i = np.ascontiguousarray(m.reshape(-1, 9).T)
    co = np.empty((9, a.shape[0]))
    co[0], co[1], co[2] = e * i - f * h, c * h - b * i, b * f - c * e
    co[3], co[4], co[5] = f * g - d * i, a * i - c * g, c * d - a * f
    co[6], co[7], co[8] = d * h - e * g, b * g - a * h, a * e - b * d
    co /= a * co[0] + b * co[3] + c * co[6]
    return np.ascontiguousarray(co.T).reshape(m.shape)


class PairSystem:
    """Savage 2020 eq. (31) for arrays of cycle pairs, factored once for repeated solves.

    Subscripts: ``prev2`` = m-2 = 2n-2, ``prev1`` = m-1 = 2n-1, ``cur`` = m = 2n. ``gv1, gr1``
    are G_V, G_R of cycle 2n-1; ``gv2, gr2`` of cycle 2n (eqs. (3), (4)). ``displacement``,
    if given, replaces ``R_{2n} - R_{2n-2}`` (see :func:`method2`).

    Everything but the odd-cycle gravity ``g_{2n-1}`` is fixed by the constraints, and the
    numerators B_num of eqs. (26) and (29) are linear in it, so A (eqs. (23), (28)) and B_den
    (eqs. (26), (29)) are formed and inverted once; :meth:`solve` then costs a few matrix-vector
    products per pair.
    """

    def __init__(
        self,
        c_prev2: F64,
        c_prev1: F64,
        gv1: F64,
        gr1: F64,
        gv2: F64,
        gr2: F64,
        r_prev2: F64,
        r_cur: F64,
        v_prev2: F64,
        v_cur: F64,
        g_prev2: F64,
        g_cur: F64,
        period: float,
        displacement: F64 | None = None,
    ) -> None:
        t = period
        eye = np.eye(3)
        self.period = t
        self.c_prev2 = c_prev2
        self.cgv1 = c_prev2 @ gv1  # C_{2n-2} G_V,2n-1
        self.cgr1 = c_prev2 @ gr1  # C_{2n-2} G_R,2n-1
        cgrv1 = self.cgr1 + self.cgv1  # C_{2n-2} (G_R,2n-1 + G_V,2n-1)
        cgv2 = c_prev1 @ gv2  # C_{2n-1} G_V,2n
        cgr2 = c_prev1 @ gr2  # C_{2n-1} G_R,2n
        dr = (r_cur - r_prev2 if displacement is None else displacement) - 2.0 * v_prev2 * t
        dvel = v_cur - v_prev2
        self.r_prev2, self.v_prev2, self.g_prev2 = r_prev2, v_prev2, g_prev2
        # eq. (23): A_{2n-1} = C_{2n-1} G_R,2n (C_{2n-1} G_V,2n)^-1
        a_odd = cgr2 @ _inv3(cgv2)
        # eq. (28): A_{2n} = C_{2n-2} (G_R + G_V)_{2n-1} (C_{2n-2} G_V,2n-1)^-1
        a_even = cgrv1 @ _inv3(self.cgv1)
        # eqs. (26), (29): B_den, inverted once
        self.b_inv_odd = _inv3((cgrv1 - a_odd @ self.cgv1) * t)
        self.b_inv_even = _inv3((cgr2 - a_even @ cgv2) * t)

        # B_num of eqs. (26), (29) regrouped:  dr - A dV T + [(A/2 - I/6) g_2n + (A - I) g_2n-1
        #   + (A/2 - 5I/6) g_2n-2] T²  =  base + A w + (A - I) g_2n-1 T²
        base = dr - (g_cur + 5.0 * g_prev2) * (t * t / 6.0)
        w = -dvel * t + 0.5 * (g_cur + g_prev2) * (t * t)
        self.num_odd = base + _mv(a_odd, w)
        self.num_even = base + _mv(a_even, w)
        self.k_odd = (a_odd - eye) * (t * t)  # coefficient of g_{2n-1} in B_num
        self.k_even = (a_even - eye) * (t * t)

    def solve(self, g_prev1: F64) -> tuple[F64, F64]:
        """Δv_{2n-1} (eq. (27)) and Δv_{2n} (eq. (30)) for odd-cycle gravity ``g_prev1``."""
        dv_odd = _mv(self.b_inv_odd, self.num_odd + _mv(self.k_odd, g_prev1))
        dv_even = _mv(self.b_inv_even, self.num_even + _mv(self.k_even, g_prev1))
        return dv_odd, dv_even

    def odd_state(self, dv_odd: F64, g_prev1: F64) -> tuple[F64, F64]:
        """V_{2n-1}, R_{2n-1} from eqs. (3), (4) applied over cycle 2n-1."""
        t = self.period
        v = self.v_prev2 + _mv(self.cgv1, dv_odd) + 0.5 * (g_prev1 + self.g_prev2) * t
        r = (
            self.r_prev2
            + self.v_prev2 * t
            + _mv(self.cgr1, dv_odd) * t
            + (g_prev1 + 2.0 * self.g_prev2) * (t * t / 6.0)
        )
        return v, r


def pair_displacement(v_e0: ArrayLike, period: float) -> F64:
    """``R_{2n} - R_{2n-2}`` by Simpson's rule on a smooth velocity sampled at every cycle.

    ``∫ V dt ≈ (T/3) (V_{2n-2} + 4 V_{2n-1} + V_{2n})``; the rule's error is
    ``(2T)⁵ max|V⁗| / 2880`` (below 1e-13 m at 200 Hz for aircraft motion), far below the
    ~1e-9 m rounding of a difference of two Earth-centred coordinates.

    Parameters
    ----------
    v_e0 : array (M+1, 3)
        Velocity (m/s) of a continuous trajectory whose derivative-consistent position is the
        constraint, at every cycle m = 0..M.
    period : float
        T (s).

    Returns
    -------
    array (M//2, 3)
        Displacement (m) over each pair of cycles.
    """
    v = np.asarray(v_e0, dtype=np.float64)
    pairs = (v.shape[0] - 1) // 2
    e0 = np.arange(pairs) * 2
    return (period / 3.0) * (v[e0] + 4.0 * v[e0 + 1] + v[e0 + 2])


@dataclass(frozen=True)
class Method2Solution:
    """Increments and the published truth they generate, all in E0 / body axes.

    Attributes
    ----------
    dalpha, dv : arrays (M, 3)
        Δα_m (rad), Δv_m (m/s), body axes, m = 1..M.
    c_b_e0 : array (M+1, 3, 3)
        Attitude at every cycle (the constraint, eq. (5)).
    v_e0, r_e0 : arrays (M+1, 3)
        Velocity (m/s) and position (m): the constraints at even cycles, eqs. (3)-(4) at odd.
    g_e0 : array (M+1, 3)
        Gravitation at the published positions (m/s²).
    """

    dalpha: F64
    dv: F64
    c_b_e0: F64
    v_e0: F64
    r_e0: F64
    g_e0: F64


def method2(
    c_b_e0: ArrayLike,
    r_e0: ArrayLike,
    v_e0: ArrayLike,
    period: float,
    gravity: GravityFn,
    iterations: int = 2,
    displacement: ArrayLike | None = None,
    cycle_gravity: Callable[[F64, F64], F64] | None = None,
) -> Method2Solution:
    """Generate increments meeting the constraints with Savage 2020 Method 2, vectorized.

    Parameters
    ----------
    c_b_e0 : array (M+1, 3, 3)
        Attitude constraint ``C_{Bvar_m}^{E0}`` at every cycle (eq. (5)).
    r_e0 : array (M+1, 3)
        Position constraint (eqs. (6)-(7)), m; used at even cycles (odd entries are only the
        starting guess for the odd-cycle gravity).
    v_e0 : array (M+1, 3)
        Velocity constraint (eq. (10)), m/s; used at even cycles.
    period : float
        T (s).
    gravity : callable
        Gravitation ``g(R)`` (m/s², E0) of the stream's model.
    iterations : int
        Passes of the odd-cycle gravity fixed point.
    displacement : array (M//2, 3), optional
        ``R_{2n} - R_{2n-2}`` of each pair computed without the rounding of two ~6e6 m
        coordinates (e.g. :func:`pair_displacement`, Simpson's rule on the velocity). The
        difference of rounded positions carries ~1e-9 m of noise, which eq. (31) turns into
        ~1e-9/T² m/s² of white noise on the specific force (1e-3 m/s² at 1 kHz). The published
        positions stay the constraints, so the docs/interface.md §3 residuals change by at most that
        1e-9 m.
    cycle_gravity : callable, optional
        ``g(R, m)`` taking positions and their cycle indices, replacing ``gravity``: for models
        that depend on the cycle, e.g. Savage 2020 Appendix C's expansion about the
        reference's gravity at the same cycle (eq. (C-12)).

    Returns
    -------
    Method2Solution
        If M is odd, the last cycle is solved alone with eq. (9) (Method 1, position
        constraint at m = M), which is exact in the same sense.
    """
    c = np.asarray(c_b_e0, dtype=np.float64)
    r_con = np.asarray(r_e0, dtype=np.float64)
    v_con = np.asarray(v_e0, dtype=np.float64)
    n_cycles = c.shape[0] - 1
    if n_cycles < 1:
        raise ValueError("Method 2 needs at least one cycle (two attitude samples)")
    if r_con.shape != (n_cycles + 1, 3) or v_con.shape != (n_cycles + 1, 3):
        raise ValueError("r_e0 and v_e0 must have one row per attitude sample")
    t = float(period)
    dalpha = attitude_increments(c)
    fast = _k.HAVE_NUMBA and n_cycles > 1
    if fast:  # G_V, G_R formed inside the kernel
        _, f2, f3, f4 = rotation_coefficients(np.linalg.norm(dalpha, axis=-1))
    else:
        gc, gv, gr = g_matrices(dalpha)  # gc unused: C comes from the constraint (eq. (8))
        del gc
    m_pairs = n_cycles // 2
    e0 = np.arange(m_pairs) * 2  # 2n-2
    od = e0 + 1  # 2n-1
    e1 = e0 + 2  # 2n

    r = np.empty_like(r_con)
    v = np.empty_like(v_con)
    g = np.empty_like(r_con)
    dv = np.empty_like(dalpha)
    r[0::2], v[0::2] = r_con[0::2], v_con[0::2]

    def grav(x: F64, m: F64 | int) -> F64:
        return gravity(x) if cycle_gravity is None else cycle_gravity(x, np.asarray(m))

    g[0::2] = grav(r[0::2], np.arange(0, n_cycles + 1, 2))
    g_odd = grav(r_con[od], od) if m_pairs else np.empty((0, 3))
    disp = None if displacement is None else np.asarray(displacement, dtype=np.float64)
    if disp is not None and disp.shape != (m_pairs, 3):
        raise ValueError(f"displacement must have shape ({m_pairs}, 3), got {disp.shape}")
    if fast:
        # The same arithmetic in one compiled pass per pair (bit-identical, core/_compiled.py).
        cgv1, cgr1, b_odd, b_even, k_odd, k_even = (np.empty((m_pairs, 3, 3)) for _ in range(6))
        num_odd, num_even, dv_odd, dv_even, v_odd, r_odd = (
            np.empty((m_pairs, 3)) for _ in range(6)
        )
        use_disp = disp is not None
        _k.pair_system_kernel(
            np.ascontiguousarray(c), dalpha, f2, f3, f4, r, v, g,
            np.ascontiguousarray(disp) if use_disp else r[:0], use_disp, t,
            cgv1, cgr1, b_odd, b_even, num_odd, num_even, k_odd, k_even,
        )  # fmt: skip
        for _ in range(max(1, iterations)):
            _k.pair_solve_kernel(
                cgv1, cgr1, b_odd, b_even, num_odd, num_even, k_odd, k_even,
                r, v, g, np.ascontiguousarray(g_odd, dtype=np.float64), t,
                dv_odd, dv_even, v_odd, r_odd,
            )  # fmt: skip
            g_odd = grav(r_odd, od)
    else:
        system = PairSystem(
            c[e0], c[od], gv[od - 1], gr[od - 1], gv[e1 - 1], gr[e1 - 1],
            r[e0], r[e1], v[e0], v[e1], g[e0], g[e1], t, disp,
        )  # fmt: skip
        for _ in range(max(1, iterations)):
            dv_odd, dv_even = system.solve(g_odd)
            v_odd, r_odd = system.odd_state(dv_odd, g_odd)
            g_odd = grav(r_odd, od)
    dv[od - 1], dv[e1 - 1] = dv_odd, dv_even
    r[od], v[od], g[od] = r_odd, v_odd, g_odd

    if n_cycles % 2:  # final single cycle: eq. (9), position constraint at m = M
        m = n_cycles
        _, gv_m, gr_m = (x[0] for x in g_matrices(dalpha[m - 1 : m]))
        r[m] = r_con[m]
        g[m] = grav(r[m], m)
        rhs = r[m] - r[m - 1] - v[m - 1] * t - (g[m] + 2.0 * g[m - 1]) * t * t / 6.0
        dv[m - 1] = np.linalg.solve(c[m - 1] @ gr_m, rhs / t)
        v[m] = v[m - 1] + c[m - 1] @ (gv_m @ dv[m - 1]) + 0.5 * (g[m] + g[m - 1]) * t
    return Method2Solution(dalpha=dalpha, dv=dv, c_b_e0=c.copy(), v_e0=v, r_e0=r, g_e0=g)
