"""Smoothing of a specified attitude offset ``C_Bvar^Bref``: Savage 2020 Appendix D.

An attitude offset built from constant-rate pieces (a scanning platform) has steps in angular
rate where the pieces meet. Appendix D smooths it without losing the specified orientation:

1. ``Δβ_m`` (rad, Bvar axes), the rotation vector of ``G_Cvar2ref,m = C_{m-1}ᵀ C_m``
   (eq. (D-2), extraction as for eq. (8));
2. a linear filter (eq. (D-4))
   ``Δβ_Flt,m = a_0 Δβ_m + a_1 Δβ_{m-1} + ... + b_1 Δβ_Flt,m-1 + b_2 Δβ_Flt,m-2 + ...``
   whose coefficients obey the exactness constraint ``Σ a_i + Σ b_i = 1`` (eq. (D-3)), so that
   the filtered increments equal the input ones in steady state;
3. ``γ_m = Σ_{i<=m} (Δβ_Flt,i - Δβ_i)``, i.e. ``γ_m = γ_{m-1} + Δβ_Flt,m - Δβ_m``
   (eqs. (D-5), (D-11)), bounded thanks to (D-3);
4. ``C_filt,m = C_m G_Cγ,m`` with ``G_Cγ = G_C(γ)`` (eqs. (D-9), (D-10)): a proper rotation,
   equal to ``C_m`` once the rotation has stopped, lagging it by ``τ_Flt`` during steady
   rotation.

Conventions and decisions
-------------------------
* The offset is at rest before cycle 0: ``Δβ_m = 0`` and ``Δβ_Flt,m = 0`` for m <= 0 (zero
  filter state), hence ``γ_0 = 0`` without lag compensation.
* **Response time** (eqs. (D-6), (D-7)). With ``H(z) = A(z) / (1 - B(z))`` the steady-state
  ``γ`` under a constant ``Δβ`` is ``-(τ_Flt/T) Δβ`` with

      ``τ_Flt = (Σ_{i=1}^{r_a} i a_i + Σ_{i=1}^{r_b} i b_i) / Σ_{i=0}^{r_a} a_i · T``,

  the DC group delay of H. The denominator is the plain sum of the ``a_i`` (equal to
  ``1 - Σ b_i`` by (D-3)); the extracted text of (D-6)/(D-7) shows ``Σ i a_i`` there, which
  would give ``τ_Flt = T`` for every walking window and contradict (D-8), so it is read as a
  typo. For the walking window (``a_i = 1/n``, i = 0..n-1, no ``b_i``) the highest subscript is
  ``r_a = n - 1`` and ``τ_Flt = r_a T / 2`` (eq. (D-8)); the tests measure it from ``γ``.
* **γ without drift.** By (D-3) the transfer function from ``Δβ`` to ``γ``,
  ``(H - 1) / (1 - z⁻¹)``, reduces exactly to ``Q(z) / (1 - B(z))`` with the finite numerator
  ``q_i = Σ_{j<=i} (a_j + b_j) - 1`` (``b_0 = 0``). ``γ`` is computed with that filter: it is
  the (D-11) sum in closed form (the tests compare both), but it does not accumulate the
  rounding of ``Σ a_i + Σ b_i - 1`` over the whole run. For a finite-response filter (the
  walking window) ``γ_m`` depends only on the last ``r_a`` increments, so ``C_filt = C``
  *exactly* after ``r_a`` cycles at rest, however long the run was.
* **Lag compensation** (text after (D-8)): the input of (D-4) is time-shifted ``k`` cycles
  ahead, ``Δβ_Flt = H(z) z^k Δβ`` (the scan is a known function of time), with
  ``k = round(τ_Flt / T)`` (halves round up). A centred walking window (odd ``n``) has
  ``k = (n - 1)/2`` exactly and no steady lag at all; otherwise a steady residual
  ``γ = -(τ_Flt/T - k) Δβ`` remains, at most half a cycle of rotation. The shifted filter runs
  from cycle ``1 - k``, so every specified increment enters it: a motion that starts within
  ``k`` cycles of t0 is anticipated, and ``γ_0`` is the filtered rotation accrued before t0
  (``C_filt,0 = C_0 G_C(γ_0)``). The ``k`` increments beyond the last given cycle are needed
  too; :func:`smooth_attitude_offset` holds the last one (the caller can pass ``k`` more cycles
  and drop them, as :meth:`strapdown_ros.core.offsets.OffsetModel.history` does). A negative
  ``τ_Flt`` (a lead filter) gives a delay ``k < 0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import lfilter

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm

__all__ = [
    "D3_TOLERANCE",
    "LinearFilter",
    "SmoothingTerms",
    "attitude_offset_increments",
    "smooth_attitude_offset",
    "smoothing_terms",
]


#: Allowed ``|Σ a_i + Σ b_i - 1|`` of eq. (D-3).
D3_TOLERANCE = 1e-12


def attitude_offset_increments(c_bvar_bref: ArrayLike) -> F64:
    """Rotation increments of an attitude offset, eq. (D-2).

    Parameters
    ----------
    c_bvar_bref : array (N, 3, 3)
        ``C_{Bvar_m}^{Bref}`` at cycles m = 0..N-1.

    Returns
    -------
    array (N-1, 3)
        ``Δβ_m`` (rad, Bvar axes), m = 1..N-1: the rotation vector of
        ``G_Cvar2ref,m = (C_{Bvar_{m-1}}^{Bref})ᵀ C_{Bvar_m}^{Bref}`` (exact extraction).
    """
    c = np.asarray(c_bvar_bref, dtype=np.float64)
    return rotvec_from_dcm(np.swapaxes(c[:-1], -1, -2) @ c[1:])


def _coefficients(values: Sequence[float] | ArrayLike, name: str) -> F64:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a list of numbers, got {values!r}") from None
    if arr.ndim != 1 or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be a list of finite numbers, got {values!r}")
    return arr


class LinearFilter:
    """General linear filter of eq. (D-4) obeying the exactness constraint (D-3).

    ``Δβ_Flt,m = Σ_{i=0}^{r_a} a_i Δβ_{m-i} + Σ_{i=1}^{r_b} b_i Δβ_Flt,m-i``.

    Parameters
    ----------
    a : sequence of float
        ``a_0, a_1, ..., a_{r_a}``: weights of the current and past inputs (non-empty).
    b : sequence of float, optional
        ``b_1, ..., b_{r_b}``: weights of past outputs (empty: finite impulse response).

    Raises
    ------
    ValueError
        If ``|Σ a_i + Σ b_i - 1| > 1e-12`` (eq. (D-3), the message names the coefficients), if a
        coefficient is not finite, or if the recursion is unstable (a root of
        ``1 - Σ b_i z^-i`` on or outside the unit circle; γ would be unbounded).
    """

    def __init__(self, a: Sequence[float] | ArrayLike, b: Sequence[float] | ArrayLike = ()) -> None:
        self.a = _coefficients(a, "a")
        self.b = _coefficients(b, "b")
        if self.a.size == 0:
            raise ValueError("a: must have at least one coefficient (a_0)")
        total = math.fsum(self.a.tolist()) + math.fsum(self.b.tolist())
        if abs(total - 1.0) > D3_TOLERANCE:
            raise ValueError(
                f"coefficients a={self.a.tolist()}, b={self.b.tolist()} violate Savage eq. "
                f"(D-3): sum(a) + sum(b) = {total!r}, must be 1 (within {D3_TOLERANCE:g})"
            )
        if self.b.size:
            radius = float(np.max(np.abs(np.roots(np.concatenate([[1.0], -self.b])))))
            if radius >= 1.0:
                raise ValueError(
                    f"b: the recursion with b={self.b.tolist()} is unstable (pole radius "
                    f"{radius:.6g} >= 1)"
                )
        self.a.setflags(write=False)
        self.b.setflags(write=False)

    @classmethod
    def walking_window(cls, n: int) -> LinearFilter:
        """Walking-window filter: ``a_i = 1/n``, i = 0..n-1, no ``b_i`` (``r_a = n - 1``).

        Parameters
        ----------
        n : int
            Window length in cycles (>= 1). ``τ_Flt = (n - 1) T / 2`` (eq. (D-8)).
        """
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"window: must be a positive integer (cycles), got {n!r}")
        return cls(np.full(int(n), 1.0 / n))

    def __repr__(self) -> str:
        return f"LinearFilter(a={self.a.tolist()}, b={self.b.tolist()})"

    def response_time(self, period: float) -> float:
        """``τ_Flt`` (s) of eq. (D-7): the steady-state lag of the filtered rotation.

        ``τ_Flt = (Σ_{i>=1} i a_i + Σ_{i>=1} i b_i) / Σ_{i>=0} a_i · T`` (see the module notes
        on the denominator). Positive for a lag, negative for a lead.

        Parameters
        ----------
        period : float
            Cycle period T (s).
        """
        ia = np.arange(self.a.size) @ self.a
        ib = np.arange(1, self.b.size + 1) @ self.b
        return float((ia + ib) / self.a.sum() * period)

    def compensation_shift(self) -> int:
        """Cycles ``k = round(τ_Flt / T)`` (halves up) the input is advanced by lag compensation."""
        # the tolerance absorbs the rounding of τ_Flt/T (e.g. 9.499999999999996 for n = 20)
        return math.floor(self.response_time(1.0) + 0.5 + 1e-9)

    def apply(self, dbeta: ArrayLike) -> F64:
        """Filter increments with eq. (D-4), at rest (zero state) before the first one.

        Parameters
        ----------
        dbeta : array (N, 3)
            ``Δβ_m`` (rad, Bvar axes) of consecutive cycles.

        Returns
        -------
        array (N, 3)
            ``Δβ_Flt,m`` (rad, Bvar axes).
        """
        x = np.asarray(dbeta, dtype=np.float64)
        return lfilter(self.a, np.concatenate([[1.0], -self.b]), x, axis=0)

    def gamma_numerator(self, shift: int = 0) -> F64:
        """Numerator ``q`` of the filter ``Q(z)/(1 - B(z))`` from ``Δβ`` to ``γ`` (eq. (D-11)).

        With input advanced by ``k = shift`` cycles, ``γ = (z^k H - 1)/(1 - z⁻¹) Δβ``; delaying
        by ``max(k, 0)`` makes it causal: ``P = z^-max(-k,0) A - z^-max(k,0) (1 - B)``, and
        ``Q = P/(1 - z⁻¹)`` is finite because ``P(1) = 0`` by (D-3): ``q_i = Σ_{j<=i} p_j``.

        Parameters
        ----------
        shift : int
            Input advance k (cycles); negative: delay.

        Returns
        -------
        array (L,)
            ``q_0 .. q_{L-1}``; ``γ_m = Σ q_i Δβ_{m+max(k,0)-i} + Σ b_i γ_{m-i}``.
        """
        delay_a, delay_1 = max(-shift, 0), max(shift, 0)
        size = max(self.a.size + delay_a, self.b.size + 1 + delay_1)
        p = np.zeros(size)
        p[delay_a : delay_a + self.a.size] += self.a
        p[delay_1] -= 1.0
        p[delay_1 + 1 : delay_1 + 1 + self.b.size] += self.b
        return np.cumsum(p)[:-1] if size > 1 else np.zeros(1)


@dataclass(frozen=True)
class SmoothingTerms:
    """Intermediate quantities of Appendix D on the cycle grid.

    Attributes
    ----------
    dbeta : array (N-1, 3)
        ``Δβ_m`` (rad, Bvar axes), m = 1..N-1 (eq. (D-2)).
    dbeta_flt : array (N-1, 3)
        ``Δβ_Flt,m`` (rad), m = 1..N-1: the output of (D-4) (with the input shifted by ``shift``).
    gamma : array (N, 3)
        ``γ_m`` (rad), m = 0..N-1 (eqs. (D-5), (D-11)).
    shift : int
        Lag-compensation advance k (cycles) of the (D-4) input; 0 without compensation.
    """

    dbeta: F64
    dbeta_flt: F64
    gamma: F64
    shift: int


def smoothing_terms(
    c_bvar_bref: ArrayLike, filt: LinearFilter, lag_compensation: bool = False
) -> SmoothingTerms:
    """``Δβ``, ``Δβ_Flt`` and ``γ`` of an attitude offset (eqs. (D-2), (D-4), (D-11)).

    Parameters
    ----------
    c_bvar_bref : array (N, 3, 3)
        Specified offset ``C_{Bvar_m}^{Bref}``, m = 0..N-1 (at rest before m = 0).
    filt : LinearFilter
        Smoothing filter (eq. (D-4)).
    lag_compensation : bool
        Advance the (D-4) input by ``k = filt.compensation_shift()`` cycles (text after (D-8));
        the ``k`` increments after m = N-1 are taken equal to the last one.

    Returns
    -------
    SmoothingTerms
    """
    c = np.asarray(c_bvar_bref, dtype=np.float64)
    if c.ndim != 3 or c.shape[1:] != (3, 3) or c.shape[0] < 1:
        raise ValueError(f"c_bvar_bref: expected shape (N, 3, 3), got {c.shape}")
    dbeta = attitude_offset_increments(c)
    n = dbeta.shape[0]
    k = filt.compensation_shift() if lag_compensation else 0
    ahead = max(k, 0)
    last = dbeta[-1:] if n else np.zeros((1, 3))
    # Δβ_m for m = 1..N-1+ahead (zero before m = 1: at rest), future increments held.
    ext = np.concatenate([dbeta, np.repeat(last, ahead, axis=0)])
    den = np.concatenate([[1.0], -filt.b])
    # γ_m = ĝ[m + ahead], ĝ[0] = γ at rest, ĝ[j] the Q/(1-B) filter output for m' = j.
    g_hat = np.concatenate([np.zeros((1, 3)), lfilter(filt.gamma_numerator(k), den, ext, axis=0)])
    gamma = g_hat[ahead : ahead + n + 1]
    # (D-4) on the shifted input x_m = Δβ_{m+k} (zero for m + k <= 0): the filter starts at
    # m = 1 - k from rest, so ext is exactly x_{1-k}..x_{N-1}; keep m = 1..N-1.
    if k >= 0:
        flt = filt.apply(ext)[k:]
    else:
        flt = filt.apply(np.concatenate([np.zeros((-k, 3)), dbeta])[:n])
    return SmoothingTerms(dbeta, flt, gamma, k)


def smooth_attitude_offset(
    c_bvar_bref: ArrayLike, filt: LinearFilter, lag_compensation: bool = False
) -> F64:
    """Smoothed attitude offset ``C_{Bvar/filt_m}^{Bref} = C_{Bvar_m}^{Bref} G_Cγ,m``.

    Eqs. (D-2), (D-4), (D-11), (D-9), (D-10); see the module notes for the conventions.

    Parameters
    ----------
    c_bvar_bref : array (N, 3, 3)
        Specified offset ``C_{Bvar_m}^{Bref}`` at cycles m = 0..N-1 (at rest before m = 0).
    filt : LinearFilter
        Smoothing filter (eq. (D-4)).
    lag_compensation : bool
        Advance the filter input by ``round(τ_Flt/T)`` cycles (no steady lag for an odd walking
        window); the increments beyond the last given cycle are held.

    Returns
    -------
    array (N, 3, 3)
        The smoothed offset: a product of two proper rotations, orthonormal to rounding; equal
        to the input wherever ``γ = 0`` (e.g. ``r_a`` cycles after a walking-window scan stops).
    """
    c = np.asarray(c_bvar_bref, dtype=np.float64)
    gamma = smoothing_terms(c, filt, lag_compensation).gamma
    moving = np.any(gamma != 0.0, axis=1)
    out = c.copy()
    # eqs. (D-9), (D-10); dcm_from_rotvec is the G_C form of eq. (2) (bit-identical to
    # exact_update.g_c, which also builds G_V and G_R: 5x the cost)
    out[moving] = c[moving] @ dcm_from_rotvec(gamma[moving])
    return out
