"""Error dynamics of the aided filter and their discretization (Van Loan), compiled.

Continuous model over one covariance interval ``[t_k, t_k + Δt]`` (docs/theory/aided_ins.md
§4), E0 frame, error = estimate minus truth, ``Ĉ = exp([φ×]) C``:

    δṘ = δV
    δV̇ = G δR - [f^E0 ×] φ - C̄ K_a (δb_a + δm_a + diag(f̂) δs_a) + C̄ w_a
    φ̇  = - C̄ K_g (δb_g + δm_g + diag(ω̂) δs_g) + C̄ w_g
    δḃ = w_b,   δṁ = -δm/τ + w_m,   δṡ = 0,   sensor states: δẋ_s = -β_s δx_s + w_s

with ``G = ∂g/∂R`` (gravitation gradient at the interval's end), ``f^E0`` the mean specific
force of the interval in E0 (``Σ C_j Δv̂_j / Δt``), ``C̄`` the mean attitude of the interval,
``f̂``, ``ω̂`` the mean corrected body specific force and rate, ``K = diag(1/(1 + ŝ))``.
``F`` is held constant over the interval (its values at the interval's means) and the
discretization is exact for that F: ``Φ = exp(F Δt)`` and Van Loan's (1978)
``Q_d = ∫₀^Δt e^{Fs} Q_c e^{Fᵀs} ds``, both by their Taylor series

    Φ = Σ_k (F Δt)^k / k!,       Q_d = Σ_{k≥1} U_k,  U_1 = Q_c Δt,
    U_{k+1} = Δt/(k+1) (F U_k + U_k Fᵀ),

summed until the terms fall below 1e-17 of the sum (F is nilpotent but for the
gravitation-gradient loop, whose terms fall like (|G| Δt²)^k: a handful of terms). F is kept as
a sparse list of its entries, so each term costs nnz·n operations. The states outside the
coupled navigation/IMU block are independent scalar processes discretized in closed form
(``Φ = e^{-βΔt}``, ``Q_d = q (1 - e^{-2βΔt}) / (2β)`` or ``q Δt``).
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aided._jit import jit
from strapdown_ros.core.aided.layout import B_BA, B_BG, B_GMA, B_GMG, B_SFA, B_SFG

__all__ = [
    "MAX_NNZ",
    "continuous_noise",
    "dense_dynamics",
    "propagate_covariance",
    "propagate_estimates",
    "sparse_dynamics",
    "van_loan_series",
]

#: Upper bound on the entries of F in the coupled block.
MAX_NNZ = 96
_TOL = 1e-17
_MAX_TERMS = 60


@jit
def _add(rows, cols, vals, k, i, j, v):
    rows[k], cols[k], vals[k] = i, j, v
    return k + 1


@jit
def sparse_dynamics(cm, fe, wb, fb, grad, est, off, beta, ni):
    """Entries ``(rows, cols, vals, nnz)`` of F on the coupled block ``[0, ni)``.

    ``cm`` mean attitude C̄ (3, 3); ``fe`` mean specific force in E0 (3,); ``wb``, ``fb`` mean
    corrected body rate and specific force (3,); ``grad`` gravitation gradient (3, 3); ``est``
    estimates (n,); ``off`` layout offsets; ``beta`` decay rates (n,).
    """
    rows = np.empty(MAX_NNZ, dtype=np.int64)
    cols = np.empty(MAX_NNZ, dtype=np.int64)
    vals = np.empty(MAX_NNZ)
    k = 0
    for i in range(3):
        k = _add(rows, cols, vals, k, i, 3 + i, 1.0)
    for i in range(3):
        for j in range(3):
            k = _add(rows, cols, vals, k, 3 + i, j, grad[i, j])
    # -[fe×]
    k = _add(rows, cols, vals, k, 3, 7, fe[2])
    k = _add(rows, cols, vals, k, 3, 8, -fe[1])
    k = _add(rows, cols, vals, k, 4, 6, -fe[2])
    k = _add(rows, cols, vals, k, 4, 8, fe[0])
    k = _add(rows, cols, vals, k, 5, 6, fe[1])
    k = _add(rows, cols, vals, k, 5, 7, -fe[0])
    sfa, sfg = off[B_SFA], off[B_SFG]
    for row0, bias, gm, sf, mean in ((3, off[B_BA], off[B_GMA], sfa, fb),
                                     (6, off[B_BG], off[B_GMG], sfg, wb)):  # fmt: skip
        for j in range(3):
            kk = 1.0 / (1.0 + est[sf + j]) if sf >= 0 else 1.0
            for i in range(3):
                v = -cm[i, j] * kk
                k = _add(rows, cols, vals, k, row0 + i, bias + j, v)
                if gm >= 0:
                    k = _add(rows, cols, vals, k, row0 + i, gm + j, v)
                if sf >= 0:
                    k = _add(rows, cols, vals, k, row0 + i, sf + j, v * mean[j])
    for i in range(9, ni):
        if beta[i] != 0.0:
            k = _add(rows, cols, vals, k, i, i, -beta[i])
    return rows, cols, vals, k


@jit
def dense_dynamics(rows, cols, vals, nnz, ni):
    """The dense F (ni, ni) of sparse entries (tests, reference computations)."""
    f = np.zeros((ni, ni))
    for k in range(nnz):
        f[rows[k], cols[k]] += vals[k]
    return f


@jit
def continuous_noise(cm, q_ins, q, ni):
    """``Q_c`` (ni, ni) of the coupled block.

    ``C̄ diag(q_a) C̄ᵀ`` on δV, ``C̄ diag(q_g) C̄ᵀ`` on φ, ``diag(q)`` on the IMU error states.
    """
    qc = np.zeros((ni, ni))
    for a in range(2):
        base = 3 + 3 * a
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += cm[i, m] * q_ins[3 * a + m] * cm[j, m]
                qc[base + i, base + j] = s
    for i in range(9, ni):
        qc[i, i] = q[i]
    return qc


@jit
def _sparse_left(rows, cols, vals, nnz, x, out):
    """``out = F x`` for sparse F and dense x (ni, ni)."""
    out[:, :] = 0.0
    ni = x.shape[1]
    for k in range(nnz):
        i, j, v = rows[k], cols[k], vals[k]
        for c in range(ni):
            out[i, c] += v * x[j, c]


@jit
def _maxabs(a):
    m = 0.0
    for v in a.flat:
        if abs(v) > m:
            m = abs(v)
    return m


@jit
def van_loan_series(rows, cols, vals, nnz, qc, dt):
    """``(Φ, Q_d)`` of ``ẋ = F x + w``, ``E[w wᵀ] = Q_c δ(τ)`` over ``dt`` (F sparse, constant)."""
    ni = qc.shape[0]
    phi = np.eye(ni)
    term = np.eye(ni)
    tmp = np.empty((ni, ni))
    small = 0
    for k in range(1, _MAX_TERMS):
        _sparse_left(rows, cols, vals, nnz, term, tmp)
        scale = dt / k
        for i in range(ni):
            for j in range(ni):
                term[i, j] = tmp[i, j] * scale
                phi[i, j] += term[i, j]
        if _maxabs(term) <= _TOL * max(1.0, _maxabs(phi)):
            small += 1
            if small == 2:
                break
        else:
            small = 0
    qd = qc * dt
    u = qd.copy()
    small = 0
    for k in range(2, _MAX_TERMS):
        _sparse_left(rows, cols, vals, nnz, u, tmp)
        scale = dt / k
        for i in range(ni):
            for j in range(i, ni):
                x = (tmp[i, j] + tmp[j, i]) * scale
                u[i, j] = x
                u[j, i] = x
        for i in range(ni):
            for j in range(ni):
                qd[i, j] += u[i, j]
        top = _maxabs(qd)
        if top == 0.0 or _maxabs(u) <= _TOL * top:
            small += 1
            if small == 2:
                break
        else:
            small = 0
    return phi, qd


@jit
def propagate_estimates(est, beta, dt):
    """``x̂ ← e^{-βΔt} x̂`` in place for every Gauss–Markov state (β > 0; the others hold).

    The conditional mean of ``ẋ = -β x + w`` over ``dt``: the estimate of a Gauss–Markov
    state decays as the covariance's ``Φ = e^{-βΔt}`` says. Without it the error
    ``x̂ - x`` gains the unmodelled drift ``β x̂`` (what made the position and velocity NEES
    of long runs with GNSS Gauss–Markov errors too large, docs/aided.md).
    """
    for i in range(est.shape[0]):
        if beta[i] != 0.0:
            est[i] *= math.exp(-beta[i] * dt)


@jit
def propagate_covariance(p, phi, qd, beta, q, dt, ni):
    """``P ← Φ P Φᵀ + Q_d`` in place (n, n).

    ``Φ = [[Φ_c, 0], [0, D]]`` with the coupled block's ``Φ_c`` (ni, ni; its rows ≥ 9
    diagonal) and D the closed form of the sensor states.
    """
    n = p.shape[0]
    d = np.empty(n)
    for i in range(9, ni):
        d[i] = phi[i, i]
    for i in range(ni, n):
        d[i] = math.exp(-beta[i] * dt) if beta[i] != 0.0 else 1.0
    a = np.empty((n, n))
    for i in range(9):
        for c in range(n):
            s = 0.0
            for j in range(ni):
                s += phi[i, j] * p[j, c]
            a[i, c] = s
    for i in range(9, n):
        for c in range(n):
            a[i, c] = d[i] * p[i, c]
    for r in range(n):
        for i in range(9):
            s = 0.0
            for j in range(ni):
                s += a[r, j] * phi[i, j]
            p[r, i] = s
        for i in range(9, n):
            p[r, i] = a[r, i] * d[i]
    for i in range(ni):
        for j in range(ni):
            p[i, j] += qd[i, j]
    for i in range(ni, n):
        if beta[i] != 0.0:
            p[i, i] += q[i] * (-math.expm1(-2.0 * beta[i] * dt)) / (2.0 * beta[i])
        else:
            p[i, i] += q[i] * dt
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = s
            p[j, i] = s
