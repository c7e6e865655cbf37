"""The measurement update of the aided filter: χ² gate, Joseph form, closed-loop reset (compiled).

With ``ν = z̃ - h(x̂)``, ``H = ∂h/∂x`` and measurement covariance R (docs/theory/aided_ins.md §6):

    S = H P Hᵀ + R,   NIS = νᵀ S⁻¹ ν      (gate: rejected if NIS > χ²_m(p_gate))
    K = P Hᵀ S⁻¹,     dx = K ν            (the correction added to the estimate)
    P ← (I - K H) P (I - K H)ᵀ + K R Kᵀ   (Joseph form, Bucy & Joseph 1968)

The Joseph product is evaluated with the rank-m structure of ``A = I - K H``:
``B = A P = P - K (P Hᵀ)ᵀ``, ``A P Aᵀ = B - (B Hᵀ) Kᵀ``, ``B Hᵀ = P Hᵀ - K (H P Hᵀ)`` — the same
congruence as the dense product at O(n² m) cost; P is symmetrized after.

Closed loop: the correction is injected into the nominal state and the error mean reset to zero;
the attitude injection ``Ĉ ← exp([dφ×]) Ĉ`` changes the attitude error's coordinates by
``φ' = (I + ½ [dφ×]) φ - dφ`` to first order (Solà 2017, "Quaternion kinematics for the
error-state Kalman filter", eq. (287)), so ``P ← G P Gᵀ`` with that block.
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aided._jit import jit

__all__ = ["carry_quantization", "cholesky_solve", "joseph_update", "reset_attitude"]


@jit
def _cholesky(s):
    """Lower Cholesky factor of a small SPD matrix (m, m); ok False if not positive."""
    m = s.shape[0]
    low = np.zeros((m, m))
    for j in range(m):
        d = s[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not d > 0.0:
            return low, False
        low[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            x = s[i, j]
            for k in range(j):
                x -= low[i, k] * low[j, k]
            low[i, j] = x / low[j, j]
    return low, True


@jit
def cholesky_solve(low, b):
    """``S⁻¹ b`` (m,) for ``S = L Lᵀ``."""
    m = low.shape[0]
    x = b.copy()
    for i in range(m):
        for k in range(i):
            x[i] -= low[i, k] * x[k]
        x[i] /= low[i, i]
    for i in range(m - 1, -1, -1):
        for k in range(i + 1, m):
            x[i] -= low[k, i] * x[k]
        x[i] /= low[i, i]
    return x


@jit
def _cholesky_solve_columns(low, b):
    """``S⁻¹ B`` (m, k) for ``S = L Lᵀ``, column by column."""
    x = np.empty_like(b)
    for c in range(b.shape[1]):
        x[:, c] = cholesky_solve(low, b[:, c].copy())
    return x


@jit
def _h_times(h, x):
    """``H X`` (m, k) of ``h`` (m, n) and ``x`` (n, k), the zero entries of H skipped."""
    m, n, k = h.shape[0], h.shape[1], x.shape[1]
    out = np.empty((m, k))
    for a in range(m):
        for c in range(k):
            s = 0.0
            for j in range(n):
                hj = h[a, j]
                if hj != 0.0:
                    s += hj * x[j, c]
            out[a, c] = s
    return out


@jit
def joseph_update(p, nu, h, rm, gate):
    """Gate and update: returns ``(dx, nis, accepted)``; P updated in place when accepted.

    ``p`` (n, n); ``nu`` (m,) innovation; ``h`` (m, n); ``rm`` (m, m); ``gate`` the χ²
    threshold (``inf``: no gate). A non-positive S rejects the measurement (NIS = inf).
    """
    n, m = p.shape[0], nu.shape[0]
    ph = _h_times(h, p.T).T  # P Hᵀ (n, m)
    hph = _h_times(h, ph)
    sm = np.empty((m, m))
    for a in range(m):
        for b in range(m):
            sm[a, b] = 0.5 * (hph[a, b] + hph[b, a]) + rm[a, b]
    low, ok = _cholesky(sm)
    dx = np.zeros(n)
    if not ok:
        return dx, np.inf, False
    w = cholesky_solve(low, nu)
    nis = 0.0
    for a in range(m):
        nis += nu[a] * w[a]
    if not nis <= gate:
        return dx, nis, False
    # K = P Hᵀ S⁻¹ (n, m): solve S Kᵀ = (P Hᵀ)ᵀ
    kt = _cholesky_solve_columns(low, ph.T.copy())
    k = kt.T.copy()
    for i in range(n):
        s = 0.0
        for a in range(m):
            s += k[i, a] * nu[a]
        dx[i] = s
    # B = P - K (P Hᵀ)ᵀ ;  C = B Hᵀ = P Hᵀ - K (H P Hᵀ)
    bm = _minus_product_t(p, k, ph)
    cm = _minus_product_t(ph, k, hph.T.copy())
    kr = np.empty((n, m))
    for i in range(n):
        for a in range(m):
            s = 0.0
            for b in range(m):
                s += k[i, b] * rm[b, a]
            kr[i, a] = s
    for i in range(n):
        for j in range(n):
            s = bm[i, j]
            for a in range(m):
                s += kr[i, a] * k[j, a] - cm[i, a] * k[j, a]
            p[i, j] = s
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = s
            p[j, i] = s
    return dx, nis, True


@jit
def _minus_product_t(a, b, c):
    """``A - B Cᵀ`` (each term subtracted in turn, as the loops it replaces did)."""
    out = np.empty(a.shape)
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            s = a[i, j]
            for q in range(b.shape[1]):
                s -= b[i, q] * c[j, q]
            out[i, j] = s
    return out


@jit
def reset_attitude(p, dphi):
    """``P ← G P Gᵀ`` with ``G = I`` but ``G[6:9, 6:9] = I + ½ [dφ×]`` (after injecting dφ)."""
    n = p.shape[0]
    g = np.eye(3)
    g[0, 1], g[0, 2] = -0.5 * dphi[2], 0.5 * dphi[1]
    g[1, 0], g[1, 2] = 0.5 * dphi[2], -0.5 * dphi[0]
    g[2, 0], g[2, 1] = -0.5 * dphi[1], 0.5 * dphi[0]
    rows = np.empty((3, n))
    for i in range(3):
        for j in range(n):
            rows[i, j] = g[i, 0] * p[6, j] + g[i, 1] * p[7, j] + g[i, 2] * p[8, j]
    for i in range(3):
        for j in range(n):
            p[6 + i, j] = rows[i, j]
    cols = np.empty((n, 3))
    for i in range(n):
        for j in range(3):
            cols[i, j] = p[i, 6] * g[j, 0] + p[i, 7] * g[j, 1] + p[i, 8] * g[j, 2]
    for i in range(n):
        for j in range(3):
            p[i, 6 + j] = cols[i, j]
    for i in range(6, 9):
        for j in range(n):
            s = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = s
            p[j, i] = s


@jit
def carry_quantization(est, p, k, variance):
    """After a wheel update: the next residual becomes the last one, a fresh next one is drawn.

    ``k``: index of ρ_last (ρ_next at ``k + 1``). The row and column of ρ_next (its correlations
    with every state from the update) move to ρ_last; ρ_next restarts uncorrelated with
    estimate 0 and ``variance`` ((q/P)²/12: the residual of the next count, independent of
    the last one when the distance per epoch varies by a pulse or more; at a steady speed the
    residuals follow each other and this is an approximation).
    """
    n = p.shape[0]
    for j in range(n):
        p[k, j] = p[k + 1, j]
    for j in range(n):
        p[j, k] = p[j, k + 1]
    for j in range(n):
        p[k + 1, j] = 0.0
        p[j, k + 1] = 0.0
    p[k + 1, k + 1] = variance
    est[k] = est[k + 1]
    est[k + 1] = 0.0
