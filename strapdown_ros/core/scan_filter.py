"""Smoothing of a specified attitude offset: Savage 2020 Appendix D.

An attitude offset ``C_{Bvar_m}^{Bref}`` given by constant-rate pieces has steps in angular rate
where the pieces meet. Appendix D smooths it without losing the specified orientation:

1. Δβ_m, the rotation vector of ``G = C_{m-1}ᵀ C_m`` (eq. (D-2));
2. a linear filter ``Δβ_Flt,m = Σ a_i Δβ_{m-i} + Σ b_i Δβ_Flt,{m-i}`` (eq. (D-4)) whose
   coefficients obey ``Σ a_i + Σ b_i = 1`` (eq. (D-3)), so that the filtered increments equal
   the input ones in steady state;
3. ``γ_m = γ_{m-1} + Δβ_Flt,m - Δβ_m`` (eq. (D-11)), bounded thanks to (D-3);
4. ``C_filt = C G_C(γ)`` (eqs. (D-9), (D-10)): a proper rotation, equal to C whenever the
   rotation has stopped, and lagging it by ``τ_Flt`` (eq. (D-7)) during steady rotation.

Response time: for ``H(z) = A(z)/(1 - B(z))`` the DC group delay is
``τ_Flt = (Σ_{i>=1} i a_i + Σ_{i>=1} i b_i) / Σ_{i>=0} a_i · T`` — eqs. (D-6)/(D-7) (the
denominator is the sum of the a_i; with (D-3) it equals ``1 - Σ b_i``). For the walking window
(``a_i = 1/(r_a + 1)``, i = 0..r_a, no b_i) this is ``r_a T / 2``, eq. (D-8). Lag compensation
shifts the filter input ``τ_Flt/T`` cycles ahead (the scan is known in advance); it needs an
integer shift, i.e. an odd window length.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm

__all__ = ["LinearFilter", "attitude_offset_increments", "smooth_attitude_offset"]

Array = NDArray[np.float64]


def attitude_offset_increments(c_bvar_bref: ArrayLike) -> Array:
    """Δβ_m (rad, Bvar axes), m = 1..N-1: rotation vectors of ``C_{m-1}ᵀ C_m`` (eq. (D-2))."""
    c = np.asarray(c_bvar_bref, dtype=np.float64)
    return rotvec_from_dcm(np.swapaxes(c[:-1], -1, -2) @ c[1:])


class LinearFilter:
    """The general linear filter of eq. (D-4) with the exactness constraint (D-3).

    Parameters
    ----------
    a : sequence of float
        ``a_0, a_1, ...`` (weights of the current and past inputs).
    b : sequence of float
        ``b_1, b_2, ...`` (weights of past outputs).
    """

    def __init__(self, a: Sequence[float], b: Sequence[float] = ()) -> None:
        self.a = np.asarray(a, dtype=np.float64)
        self.b = np.asarray(b, dtype=np.float64)
        if self.a.ndim != 1 or self.a.size == 0 or self.b.ndim != 1:
            raise ValueError("filter: a must be a non-empty list of numbers, b a list of numbers")
        if not (np.all(np.isfinite(self.a)) and np.all(np.isfinite(self.b))):
            raise ValueError("filter: coefficients must be finite")
        total = float(self.a.sum() + self.b.sum())
        if abs(total - 1.0) > 1e-12:
            raise ValueError(
                f"filter: coefficients must satisfy Savage eq. (D-3), sum(a) + sum(b) = 1; "
                f"got {total!r} for a={self.a.tolist()}, b={self.b.tolist()}"
            )
        if abs(self.a.sum()) < 1e-12:
            raise ValueError("filter: sum(a) must not vanish (no DC response)")

    @classmethod
    def walking_window(cls, length: int) -> LinearFilter:
        """Walking-window filter: ``a_i = 1/length``, i = 0..length-1, no b_i (eq. (D-8))."""
        if length < 1:
            raise ValueError(f"filter.window: must be >= 1 cycles, got {length}")
        return cls(np.full(length, 1.0 / length))

    def response_time(self, period: float) -> float:
        """τ_Flt (s) of eq. (D-7): lag of the filtered rotation during steady rotation."""
        ia = np.arange(self.a.size) @ self.a
        ib = np.arange(1, self.b.size + 1) @ self.b
        return float((ia + ib) / self.a.sum() * period)

    def apply(self, dbeta: ArrayLike) -> Array:
        """Filter increments (N, 3) with eq. (D-4), at rest (zero) before the first one."""
        x = np.asarray(dbeta, dtype=np.float64)
        return lfilter(self.a, np.concatenate([[1.0], -self.b]), x, axis=0)


def smooth_attitude_offset(
    c_bvar_bref: ArrayLike, filt: LinearFilter, lag_compensation: bool = False
) -> Array:
    """Smoothed attitude offset ``C_{Bvar/filt_m}^{Bref}`` (eqs. (D-2), (D-4), (D-9)-(D-11)).

    Parameters
    ----------
    c_bvar_bref : array (N, 3, 3)
        Specified offset on the cycle grid m = 0..N-1 (at rest before m = 0).
    filt : LinearFilter
        Smoothing filter (eq. (D-4)).
    lag_compensation : bool
        Shift the filter input ahead by τ_Flt/T cycles (an integer, else ValueError) so the
        smoothed offset has no steady lag; the last increments are held at the end.

    Returns
    -------
    array (N, 3, 3)
        ``C G_C(γ_m)``, orthonormal to rounding.
    """
    c = np.asarray(c_bvar_bref, dtype=np.float64)
    dbeta = attitude_offset_increments(c)
    x = dbeta
    if lag_compensation:
        shift = filt.response_time(1.0)
        k = int(round(shift))
        if abs(shift - k) > 1e-9:
            raise ValueError(
                f"lag_compensation: needs a whole-cycle response time, got {shift} cycles "
                "(use a walking window of odd length)"
            )
        if k:
            pad = np.repeat(dbeta[-1:], k, axis=0) if dbeta.size else np.zeros((k, 3))
            x = np.concatenate([dbeta[k:], pad])[: dbeta.shape[0]]
    flt = filt.apply(x)
    gamma = np.zeros((c.shape[0], 3))
    gamma[1:] = np.cumsum(flt - dbeta, axis=0)  # eq. (D-11)
    return c @ dcm_from_rotvec(gamma)  # eqs. (D-9), (D-10)
