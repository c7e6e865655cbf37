"""Variation trajectories from a published reference stream: Savage 2020 Methods 1 and 2.

Given the reference stream (increments and truth in E0, docs/interface.md §3) and the offset history
on the
same cycle grid (lever arm ``l^Bref``, displacement ``s^Bvar``, attitude offset
``C_Bvar^Bref``), the variation stream is the one whose truth meets

* the attitude constraint ``C_{Bvar_m}^{E0} = C_{Bref_m}^{E0} C_{Bvar_m}^{Bref}`` (eq. (5));
* the position constraint ``R_var = R_ref + S`` with
  ``S = C_{Bvar}^{E0} [C_{Bvar}^{Bref T} l^{Bref} + s^{Bvar}]`` (eqs. (6), (7));
* for Method 2, the velocity constraint ``V_var = V_ref + (S_{m+1} - S_{m-1}) / 2T`` (eq. (10)),

at every cycle (attitude), every even cycle (Method 2) or every cycle (Method 1, eq. (9)), and
whose increments and truth obey eqs. (2)-(4). Δα follows from eq. (8); Δv from eq. (31)
(Method 2, :func:`strapdown_ros.core.method2.method2`) or eq. (9) (Method 1).

Conventions of this implementation (documented in ``docs/variation.md``):

* Look-ahead: eq. (10) needs ``S_{m+1}``, so a variation of a reference with cycles 0..M ends
  at the last even cycle ``M_var <= M - 1``. At the first cycle of a run, ``S_{-1}`` does not
  exist and the derivative of S is the second-order one-sided difference
  ``(-3 S_0 + 4 S_1 - S_2) / 2T``.
* Pair displacements ``R_{2n} - R_{2n-2}`` are formed from the reference's own increments
  (eq. (4) twice, all small terms) plus ``S_{2n} - S_{2n-2}``, never as a difference of two
  Earth-centred coordinates (which would add ~1e-9/T² m/s² of rounding noise to Δv).
* Gravity at the variation point: the stream's full model at the published positions
  (``gravity="full"``, Appendix B's role) or Appendix C's first-order expansion about the
  reference's gravity (``gravity="first_order"``, eq. (C-12)).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.exact_update import g_matrices
from strapdown_ros.core.gravity import gravitation, gravitation_first_order
from strapdown_ros.core.method2 import attitude_increments, method2
from strapdown_ros.core.series import rotation_coefficients
from strapdown_ros.core.stream import Stream

__all__ = [
    "GRAVITY_MODES",
    "METHODS",
    "OffsetArrays",
    "VariationConstraints",
    "generate_variation",
    "reference_pair_displacement",
    "variation_constraints",
]

METHODS = (1, 2)
GRAVITY_MODES = ("full", "first_order")


def _mv(m: F64, v: F64) -> F64:
    return np.einsum("...ij,...j->...i", m, v)


@dataclass(frozen=True)
class OffsetArrays:
    """Offsets on the cycle grid m = 0..N-1 (Savage 2020 eq. (7) inputs).

    Attributes
    ----------
    lever_arm : array (N, 3)
        ``l^{Bref_m}`` (m, reference body FRD axes).
    displacement : array (N, 3)
        ``s^{Bvar_m}`` (m, variation body FRD axes).
    c_bvar_bref : array (N, 3, 3)
        ``C_{Bvar_m}^{Bref}``: variation body to reference body.
    """

    lever_arm: F64
    displacement: F64
    c_bvar_bref: F64

    @classmethod
    def zero(cls, n: int) -> OffsetArrays:
        """No offsets (the regenerated reference): l = 0, s = 0, C = I."""
        return cls(np.zeros((n, 3)), np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)))

    def __len__(self) -> int:
        return int(self.lever_arm.shape[0])


@dataclass(frozen=True)
class VariationConstraints:
    """The constraints of eqs. (5)-(7) and (10) at cycles m = 0..M_var (+ S at M_var + 1)."""

    c_b_e0: F64  # (M_var+1, 3, 3) eq. (5)
    r_e0: F64  # (M_var+1, 3) eqs. (6)-(7)
    v_e0: F64  # (M_var+1, 3) eq. (10)
    s_e0: F64  # (M_var+2, 3) eq. (7)


def variation_constraints(
    reference: Stream, offsets: OffsetArrays, cycles: int, lead: int = 0
) -> VariationConstraints:
    """Constraints (5)-(7), (10) of a variation with ``cycles`` cycles.

    Parameters
    ----------
    reference : Stream
        Published reference with at least ``lead + cycles + 2`` truth samples.
    offsets : OffsetArrays
        Offsets on the same grid, at least as many samples.
    cycles : int
        M_var, the number of variation cycles.
    lead : {0, 1}
        0: reference sample 0 is the start of the run (eq. (10) one-sided there). 1: sample 0 is
        the cycle before the first variation cycle (a window of a running stream: eq. (10)
        central everywhere); the returned constraints start at reference sample 1.
    """
    n = lead + cycles + 2
    if reference.cycles + 1 < n or len(offsets) < n:
        raise ValueError(
            f"a variation of {cycles} cycles needs {n} reference and offset samples "
            f"(eq. (10) looks one cycle ahead); got {reference.cycles + 1} and {len(offsets)}"
        )
    c_ref = reference.c_b_e0[:n]
    c_var = matmul33(c_ref, offsets.c_bvar_bref[:n])  # eq. (5)
    body = (
        np.einsum("nji,nj->ni", offsets.c_bvar_bref[:n], offsets.lever_arm[:n])
        + offsets.displacement[:n]
    )
    s = _mv(c_var, body)  # eq. (7)
    t = reference.period
    ds = np.empty((n, 3))
    ds[1:-1] = (s[2:] - s[:-2]) / (2.0 * t)  # eq. (10)
    ds[0] = (-3.0 * s[0] + 4.0 * s[1] - s[2]) / (2.0 * t)  # one-sided at the start of a run
    out = slice(lead, lead + cycles + 1)
    return VariationConstraints(
        c_b_e0=c_var[out],
        r_e0=reference.r_e0[out] + s[out],  # eq. (6)
        v_e0=reference.v_e0[out] + ds[out],
        s_e0=s[lead:],
    )


def reference_pair_displacement(reference: Stream, g: F64, pairs: int) -> F64:
    """``R_{2n} - R_{2n-2}`` of a published stream from its increments (eq. (4) twice).

    Every term is small (velocity × T, Δv × T, g T²), so the result carries no rounding of
    Earth-centred coordinates. ``g``: gravitation at the published positions.
    """
    t = reference.period
    n = 2 * pairs
    da, dv = reference.dalpha[:n], reference.dv[:n]
    x2 = np.einsum("ni,ni->n", da, da)
    _, _, f3, f4 = (c[:, None] for c in rotation_coefficients(np.sqrt(x2)))
    a_x_dv = np.cross(da, dv)
    gr_dv = (
        0.5 * dv
        + f3 * a_x_dv
        + f4 * (da * np.einsum("ni,ni->n", da, dv)[:, None] - x2[:, None] * dv)
    )
    step = (
        reference.v_e0[:n] * t
        + _mv(reference.c_b_e0[:n], gr_dv) * t
        + (g[1 : n + 1] + 2.0 * g[:n]) * (t * t / 6.0)
    )  # eq. (4) without R_{m-1}, cycles 1..2*pairs; G_R Δv via cross products
    return step[0::2] + step[1::2]


def generate_variation(
    reference: Stream,
    offsets: OffsetArrays,
    method: int = 2,
    gravity: str = "full",
    lead: int = 0,
) -> Stream:
    """The variation stream of ``reference`` under ``offsets`` (Savage 2020 Method 1 or 2).

    Parameters
    ----------
    reference : Stream
        Published reference (increments and E0 truth obeying eqs. (2)-(4)).
    offsets : OffsetArrays
        Offsets at the reference's cycles (at least as many samples as the reference truth).
    method : {1, 2}
        Method 2 (eq. (31), position and velocity constrained at even cycles; default) or
        Method 1 (eq. (9), position constrained every cycle; shows the odd/even oscillation).
    gravity : {"full", "first_order"}
        Gravitation at the variation point: the stream's model at the published positions, or
        Appendix C's first-order expansion about the reference gravity (eq. (C-12)).
    lead : {0, 1}
        0: the reference starts the run. 1: the reference (and offsets) begin one cycle before
        the first variation cycle, as in a window of a running stream (see
        :func:`variation_constraints`); the output then starts at reference sample 1.

    Returns
    -------
    Stream
        Cycles 0..M_var after the lead, with M_var the last even cycle for which eq. (10) has
        its look-ahead sample; same period and gravitation model as the reference.
    """
    if method not in METHODS:
        raise ValueError(f"variation.method: must be 1 or 2, got {method!r}")
    if gravity not in GRAVITY_MODES:
        raise ValueError(f"variation.gravity: must be one of {GRAVITY_MODES}, got {gravity!r}")
    if lead not in (0, 1):
        raise ValueError(f"lead must be 0 or 1, got {lead!r}")
    cycles = reference.cycles - 1 - lead
    cycles -= cycles % 2
    if cycles < 2:
        raise ValueError(
            f"a variation needs a reference of at least {3 + lead} cycles, got {reference.cycles}"
        )
    model = reference.gravity_model
    t = reference.period
    con = variation_constraints(reference, offsets, cycles, lead)
    ref = _window(reference, lead, cycles + 1)
    g_ref = gravitation(ref.r_e0, model)

    def cycle_gravity(r: F64, m: F64) -> F64:
        if gravity == "full":
            return gravitation(r, model)
        r_ref = ref.r_e0[m]
        return gravitation_first_order(g_ref[m], r_ref, r - r_ref)  # eq. (C-12)

    pairs = cycles // 2
    disp = reference_pair_displacement(ref, g_ref, pairs)
    disp = disp + con.s_e0[2 : cycles + 1 : 2] - con.s_e0[0 : cycles - 1 : 2]
    if method == 2:
        sol = method2(
            con.c_b_e0,
            con.r_e0,
            con.v_e0,
            t,
            lambda r: gravitation(r, model),
            displacement=disp,
            cycle_gravity=cycle_gravity,
        )
        dalpha, dv, c, v, r = sol.dalpha, sol.dv, sol.c_b_e0, sol.v_e0, sol.r_e0
    else:
        dalpha, dv, v = _method1(ref, con, cycles, cycle_gravity, g_ref)
        c, r = con.c_b_e0, con.r_e0
    # The reference window's timing, E0 and gravitation model; the variation's motion.
    return replace(ref, dalpha=dalpha, dv=dv, c_b_e0=c, v_e0=v, r_e0=r)


def _window(stream: Stream, start: int, samples: int) -> Stream:
    """Truth samples start..start+samples-1 and the increments between them."""
    return stream.window(start, start + samples - 1)


def _method1(
    reference: Stream,
    con: VariationConstraints,
    cycles: int,
    cycle_gravity: object,
    g_ref: F64,
) -> tuple[F64, F64, F64]:
    """Savage 2020 eq. (9) with eqs. (3), (6): sequential in V (the recursion it is known for).

    ``Δv_m = (C_{m-1} G_R,m)^-1 [R_m - R_{m-1} - V_{m-1} T - (g_m + 2 g_{m-1}) T²/6] / T``,
    ``V_m`` from eq. (3); ``R_m`` is the constraint (6). ``R_m - R_{m-1}`` is formed from the
    reference's increments plus ``S_m - S_{m-1}``; V_0 is the constraint of eq. (10).
    """
    t = reference.period
    dalpha = attitude_increments(con.c_b_e0)
    _, gv, gr = g_matrices(dalpha)
    g = cycle_gravity(con.r_e0, np.arange(cycles + 1))  # type: ignore[operator]
    _, _, gr_ref = g_matrices(reference.dalpha[:cycles])
    c_ref, v_ref = reference.c_b_e0[:cycles], reference.v_e0[:cycles]
    dr = (
        v_ref * t
        + _mv(c_ref, _mv(gr_ref, reference.dv[:cycles])) * t
        + (g_ref[1 : cycles + 1] + 2.0 * g_ref[:cycles]) * (t * t / 6.0)
        + con.s_e0[1 : cycles + 1]
        - con.s_e0[:cycles]
    )  # R_m - R_{m-1}, m = 1..cycles
    c = con.c_b_e0
    cgr_inv = np.linalg.inv(matmul33(c[:-1], gr))
    cgv = matmul33(c[:-1], gv)
    rhs_fixed = dr - (g[1:] + 2.0 * g[:-1]) * (t * t / 6.0)
    g_avg = 0.5 * (g[1:] + g[:-1]) * t
    v = np.empty((cycles + 1, 3))
    dv = np.empty((cycles, 3))
    v[0] = con.v_e0[0]
    for m in range(cycles):  # the recursion through V_{m-1} is inherent to Method 1
        dv[m] = cgr_inv[m] @ (rhs_fixed[m] - v[m] * t) / t
        v[m + 1] = v[m] + cgv[m] @ dv[m] + g_avg[m]
    return dalpha, dv, v
