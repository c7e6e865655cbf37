"""Consistent kinematic functions from coarse samples: Giribet, España & Miranda (2007).

The paper (``seeds/003``) builds explicit functions of time from coarse, possibly noisy samples
by weighted least squares in a space of piecewise polynomials (B-splines) whose order and
continuity at every breakpoint the user chooses:

* **Problem 1** (eqs. (10)–(14)): per component, minimize
  ``Σ w_i |f(τ_i) − g_i|² + Σ w¹_j |f'(τ¹_j) − g'_j|² + …`` over the spline space
  ``P_{k,{t},{ν}}``; the normal equations (14) are banded and positive definite, solved by
  banded Cholesky. Implemented by :func:`fit_spline`.
* **Theorem 1** (eqs. (6)–(8)): the B-spline basis of ``P_{k,{t},{ν}}`` lives on the knot
  sequence in which breakpoint ``t_i`` is repeated ``k − ν_i`` times (:func:`knot_vector`).
* **Problem PV** (eqs. (15)–(17)): position with optional velocity and acceleration samples
  as derivative data (:func:`problem_pv`).
* **Problem ω** (eqs. (18)–(20)): angular-rate samples (:func:`problem_omega`).
* **Problem q1** (eq. (21)): integrate ``q̇ = ½ q ⊗ [0, ω̂]`` from ``q(0)``
  (:func:`problem_q1`).
* **Problem q2** (eqs. (22)–(23)): interpolate the integrated quaternions, project on the unit
  sphere ``q = q̄/‖q̄‖`` and take ``ω = 2 q* ⊗ q̇`` so that (q, ω) satisfy eq. (21) exactly
  (:func:`problem_q2`, :class:`QuaternionSpline`).

Notation of this module versus the paper
----------------------------------------
* ``degree`` ``p`` is the polynomial degree; the paper's order is ``k = p + 1``.
* ``continuity`` ``c`` at a breakpoint means the spline is ``C^c`` there (``c = −1``: the value
  itself may jump). The paper's ν ("first discontinuous derivative") is ``ν = c + 1``, so the
  breakpoint's knot multiplicity is ``k − ν = p − c`` (eq. (7)).
* Quaternions are Hamilton, scalar first (the paper writes ``[ω; 0]``, scalar last): eq. (21)
  reads ``q̇ = ½ q ⊗ [0, ω]`` and eq. (23) ``[0, ω] = 2 q* ⊗ q̇``.

Extension beyond the paper: :func:`fit_quaternion` applies Problem 1 directly to attitude
samples (sign-aligned quaternion components, with ``½ q̃ ⊗ [0, ω̃]`` as optional derivative data
when angular-rate samples come with them), followed by the projection of Problem q2.

Deviation (erratum): eq. (22) prints ``(I − q̄ q̄ᵀ) q̄̇ / ‖q̄‖``, which is the derivative of
``q̄/‖q̄‖`` only when ``‖q̄‖ = 1``; the exact derivative ``(I − q qᵀ) q̄̇ / ‖q̄‖`` with the
*normalized* ``q`` is used here.

All B-spline bases come from :class:`scipy.interpolate.BSpline` (``design_matrix``,
``derivative``, evaluation) and :func:`scipy.interpolate.make_interp_spline`; nothing here
evaluates a basis by hand.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.integrate import solve_ivp
from scipy.interpolate import BSpline, make_interp_spline
from scipy.linalg import LinAlgError, cho_solve_banded, cholesky_banded

from strapdown_ros.core import _compiled as _k
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import quat_conjugate, quat_multiply
from strapdown_ros.core.trajectory.base import TrajectoryError

__all__ = [
    "DerivativeData",
    "PiecewiseSpline",
    "QuaternionSpline",
    "align_quaternion_signs",
    "breakpoint_continuity",
    "fit_quaternion",
    "fit_spline",
    "knot_vector",
    "problem_omega",
    "problem_pv",
    "problem_q1",
    "problem_q2",
]



# --------------------------------------------------------------------------------------------
# Knots (Theorem 1) and the weighted least-squares fit (Problem 1)
# --------------------------------------------------------------------------------------------


def breakpoint_continuity(
    breakpoints: ArrayLike, degree: int, continuity: int | Sequence[int] | ArrayLike
) -> tuple[F64, NDArray[np.int64]]:
    """Validated breakpoints ``{t}_T`` and per-interior-breakpoint continuity orders.

    Parameters
    ----------
    breakpoints : array_like (T,)
        Strictly increasing breakpoint times (s), the paper's ``{t}_T``; the first and last
        delimit the fitted span.
    degree : int
        Polynomial degree ``p >= 1`` (paper order ``k = p + 1``).
    continuity : int or array_like (T − 2,)
        ``C^c`` order at every interior breakpoint (one int for all, or one per interior
        breakpoint), ``−1 <= c <= p − 1``. Paper: ``ν_i = c_i + 1`` (eq. (5)).

    Returns
    -------
    breakpoints : ndarray (T,)
    continuity : ndarray (T − 2,) of int

    Raises
    ------
    TrajectoryError
        ``where = ("knots",)`` or ``("continuity",)`` when they are inconsistent (ValueError
        for a bad ``degree``).
    """
    if int(degree) != degree or degree < 1:
        raise ValueError(f"degree must be an integer >= 1, got {degree!r}")
    p = int(degree)
    bp = np.asarray(breakpoints, dtype=np.float64)
    if bp.ndim != 1 or bp.size < 2:
        raise TrajectoryError(
            ("knots",), "need at least two breakpoints (start and end of the span)"
        )
    if not np.all(np.isfinite(bp)):
        raise TrajectoryError(("knots",), "breakpoints must be finite")
    if np.any(np.diff(bp) <= 0.0):
        i = int(np.argmax(np.diff(bp) <= 0.0))
        raise TrajectoryError(
            ("knots",),
            f"breakpoints must be strictly increasing (t[{i}]={float(bp[i])!r}, "
            f"t[{i + 1}]={float(bp[i + 1])!r}); lower the continuity instead of repeating a "
            "knot",
        )
    c = np.asarray(continuity)
    if c.ndim == 0:
        c = np.full(bp.size - 2, int(c), dtype=np.int64)
    elif c.shape != (bp.size - 2,):
        raise TrajectoryError(
            ("continuity",), f"expected one value per interior knot ({bp.size - 2}), got {c.size}"
        )
    if c.size and (np.any(c != np.round(c)) or c.min() < -1 or c.max() > p - 1):
        raise TrajectoryError(
            ("continuity",),
            f"orders must be integers in [-1, degree-1] = [-1, {p - 1}], got {c.tolist()}",
        )
    return bp, c.astype(np.int64)


def knot_vector(
    breakpoints: ArrayLike, degree: int, continuity: int | Sequence[int] | ArrayLike
) -> F64:
    """Knot sequence ``{ξ}`` of Theorem 1, eqs. (6)–(8).

    The end breakpoints are repeated ``k = p + 1`` times (eqs. (6), (8)); an interior
    breakpoint with continuity ``C^c`` is repeated ``k − ν = p − c`` times (eq. (7)).

    Parameters
    ----------
    breakpoints : array_like (T,)
        Strictly increasing breakpoints (s).
    degree : int
        Polynomial degree ``p``.
    continuity : int or array_like (T − 2,)
        ``C^c`` order at the interior breakpoints, see :func:`breakpoint_continuity`.

    Returns
    -------
    ndarray (n + k,)
        Non-decreasing knots; ``n = k (T − 1) − Σ ν_i`` basis functions.
    """
    bp, c = breakpoint_continuity(breakpoints, degree, continuity)
    p = int(degree)
    mult = np.concatenate([[p + 1], p - c, [p + 1]])
    return np.repeat(bp, mult)


@dataclass(frozen=True)
class DerivativeData:
    """Samples of the ``order``-th derivative of the function to fit (a term of eq. (10)).

    Attributes
    ----------
    order : int
        Derivative order ``s`` (0: the function values, 1: first derivative, …), ``s <= p``.
    tau : array (N,)
        Sample times (s), non-decreasing, inside the breakpoint span.
    values : array (N, m)
        Samples of ``g^{(s)}`` (any unit, consistent with the function; m components).
    weights : array (N,)
        Weights ``w^s_i >= 0`` (``1/σ²`` of the samples, paper remark after eq. (15)).
    """

    order: int
    tau: F64
    values: F64
    weights: F64


def _design(xi: F64, degree: int, tau: F64, order: int) -> sparse.csr_array:
    """Sparse matrix ``[B_j^{(order)}(τ_i)]`` (N, n) of the basis on knots ``xi``.

    ``BSpline.design_matrix`` gives the values. For a derivative, the coefficient map of
    ``BSpline.derivative`` is obtained column-compressed: basis ``j`` only touches derivative
    coefficients ``j − order … j``, so ``order + 1`` interleaved columns suffice.
    """
    n = xi.size - degree - 1
    # tau lies in the knot span (checked by the callers, _check_span); extrapolate=True only
    # skips scipy's Python-level min()/max() over tau, which costs ~20 ms per 1e5 samples.
    if order == 0:
        return sparse.csr_array(BSpline.design_matrix(tau, xi, degree, extrapolate=True))
    g = order + 1
    comp = np.zeros((n, g))
    comp[np.arange(n), np.arange(n) % g] = 1.0
    d = BSpline(xi, comp, degree).derivative(order)
    n_d = d.t.size - d.k - 1
    rows = np.repeat(np.arange(n_d), g)
    cols = rows + np.tile(np.arange(g), n_d)
    keep = cols < n
    rows, cols = rows[keep], cols[keep]
    dmap = sparse.csr_array((d.c[rows, cols % g], (rows, cols)), shape=(n_d, n))
    basis = sparse.csr_array(BSpline.design_matrix(tau, d.t, d.k, extrapolate=True))
    return sparse.csr_array(basis @ dmap)


def _check_span(name: str, tau: F64, lo: float, hi: float) -> None:
    if tau.size and (tau[0] < lo or tau[-1] > hi):
        raise TrajectoryError(
            ("knots",),
            f"{name} samples span [{float(tau[0])!r}, {float(tau[-1])!r}] s, outside the knot "
            f"span [{float(lo)!r}, {float(hi)!r}] s",
        )


def _schoenberg_whitney(bp: F64, degree: int, tau: F64) -> None:
    """Paper assumption (ii-c): at least ``k`` distinct value samples in every knot interval."""
    u = np.unique(tau)
    lo = np.searchsorted(u, bp[:-1], side="left")
    hi = np.searchsorted(u, bp[1:], side="right")
    count = hi - lo
    bad = np.flatnonzero(count < degree + 1)
    if bad.size:
        i = int(bad[0])
        raise TrajectoryError(
            ("knots",),
            f"interval [{float(bp[i])!r}, {float(bp[i + 1])!r}] s holds {int(count[i])} distinct "
            f"samples, a degree-{degree} spline needs at least {degree + 1} in every knot "
            f"interval (Giribet 2007 assumption (ii-c)); use wider knot spacing",
        )


def fit_spline(
    breakpoints: ArrayLike,
    degree: int,
    continuity: int | Sequence[int] | ArrayLike,
    data: Sequence[DerivativeData],
    *,
    check_intervals: bool = True,
) -> BSpline:
    """Problem 1 of Giribet 2007 (eqs. (10)–(14)): weighted least-squares vector spline.

    Minimizes ``Σ_s Σ_i w^s_i |f^{(s)}(τ^s_i) − g^s_i|²`` over ``f`` in ``P_{k,{t},{ν}}``
    (all m components share breakpoints and continuity; each component is fitted
    independently, as the paper's proof hint notes). The normal equations (14)
    ``M α = b`` with ``M = Σ_s Aₛᵀ Wₛ Aₛ`` are banded (bandwidth p) and solved by banded
    Cholesky, as the paper recommends.

    Parameters
    ----------
    breakpoints : array_like (T,)
        Breakpoints ``{t}_T`` (s); all sample times must lie in ``[t_1, t_T]``.
    degree : int
        Polynomial degree ``p`` (order ``k = p + 1``).
    continuity : int or array_like (T − 2,)
        ``C^c`` order at the interior breakpoints (``ν = c + 1``).
    data : sequence of DerivativeData
        The terms of eq. (10); the order-0 term is required (it anchors the function).
    check_intervals : bool
        Enforce the paper's assumption (ii-c) on the order-0 sample times.

    Returns
    -------
    scipy.interpolate.BSpline
        ``f`` with coefficients of shape (n, m); ``f(t, nu)`` evaluates the ``nu``-th
        derivative.

    Raises
    ------
    ValueError
        If the data do not determine the spline (message names ``knots``).
    """
    bp, c = breakpoint_continuity(breakpoints, degree, continuity)
    p = int(degree)
    xi = knot_vector(bp, p, c)
    n = xi.size - p - 1
    if not any(d.order == 0 and d.tau.size for d in data):
        raise ValueError("fit_spline: function-value samples (order 0) are required")
    m = None
    normal = sparse.csr_array((n, n))
    rhs: F64 | None = None
    ab: F64 | None = None  # upper band of eq. (14)'s M (compiled path)
    for d in data:
        if d.order < 0 or d.order > p:
            raise ValueError(f"derivative order {d.order} is not in [0, degree={p}]")
        tau = np.asarray(d.tau, dtype=np.float64)
        vals = np.asarray(d.values, dtype=np.float64).reshape(tau.size, -1)
        w = np.broadcast_to(np.asarray(d.weights, dtype=np.float64), tau.shape)
        if m is None:
            m = vals.shape[1]
            rhs = np.zeros((n, m))
        if vals.shape[1] != m:
            raise ValueError("all data terms must have the same number of components")
        if np.any(w < 0.0):
            raise ValueError("weights must be >= 0")
        keep = w > 0.0
        if not np.any(keep):
            continue
        tau, vals, w = tau[keep], vals[keep], w[keep]
        _check_span(f"order-{d.order}", tau, bp[0], bp[-1])
        if d.order == 0 and check_intervals:
            _schoenberg_whitney(bp, p, tau)
        a = _design(xi, p, tau, d.order)
        if _k.HAVE_NUMBA:  # the same sums in one compiled pass, straight into the band
            if ab is None:
                ab = np.zeros((p + 1, n))
            _k.normal_band_kernel(
                a.indptr, a.indices, a.data, np.ascontiguousarray(w), np.ascontiguousarray(vals),
                p, ab, rhs,
            )  # fmt: skip
            continue
        aw = sparse.csr_array(a.multiply(w[:, None]))
        normal = normal + aw.T @ a
        rhs = rhs + aw.T @ vals
    assert rhs is not None
    if ab is None:
        ab = np.zeros((p + 1, n))
        normal = sparse.csr_array(normal)
        for off in range(p + 1):
            ab[p - off, off:] = normal.diagonal(off)
    try:
        chol = cholesky_banded(ab, lower=False)
    except LinAlgError as exc:
        raise TrajectoryError(
            ("knots",),
            "the samples do not determine the spline (normal matrix of Giribet eq. (14) "
            "is not positive definite); use wider knot spacing or more samples",
        ) from exc
    alpha = cho_solve_banded((chol, False), rhs)
    return BSpline(xi, alpha, p, extrapolate=False)


# --------------------------------------------------------------------------------------------
# Problems PV and ω
# --------------------------------------------------------------------------------------------


def problem_pv(
    breakpoints: ArrayLike,
    degree: int,
    continuity: int | Sequence[int] | ArrayLike,
    tau_p: ArrayLike,
    p: ArrayLike,
    w_p: ArrayLike = 1.0,
    *,
    tau_v: ArrayLike | None = None,
    v: ArrayLike | None = None,
    w_v: ArrayLike = 0.0,
    tau_a: ArrayLike | None = None,
    a: ArrayLike | None = None,
    w_a: ArrayLike = 0.0,
) -> BSpline:
    """Problem PV (eqs. (15)–(17)): position spline fitted to position, velocity, acceleration.

    Minimizes ``Σ w^p_i |P̂(τ_i) − P̃_i|² + Σ w^v_j |P̂'(τ¹_j) − Ṽ_j|² +
    Σ w^a_r |P̂''(τ²_r) − Ã_r|²`` (eq. (15)). Velocity and acceleration are then the
    derivatives of the one spline (consistent by construction). The fit is done about the
    first position sample (B-splines sum to one, so adding a constant to every coefficient
    adds it to the function), which keeps the normal equations well scaled for ECEF data.

    Parameters
    ----------
    breakpoints, degree, continuity
        Spline space (see :func:`fit_spline`); ``continuity >= 1`` keeps velocity continuous
        (paper: ``1 < ν_i``).
    tau_p : array_like (N,)
        Position sample times (s).
    p : array_like (N, 3)
        Position samples (m), any Cartesian frame (the paper's inertial frame; ECEF here).
    w_p : float or array_like (N,)
        Position weights ``1/σ_p²`` (1/m²).
    tau_v, v, w_v
        Optional velocity samples ``dP/dt`` (m/s, same frame) and weights (s²/m²).
    tau_a, a, w_a
        Optional acceleration samples ``d²P/dt²`` (m/s²) and weights (s⁴/m²).

    Returns
    -------
    scipy.interpolate.BSpline
        ``P̂(t)``, coefficients (n, 3), in m; ``P̂(t, 1)`` velocity, ``P̂(t, 2)`` acceleration.
    """
    tau_p = np.asarray(tau_p, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64).reshape(tau_p.size, -1)
    ref = p[0].copy()
    data = [DerivativeData(0, tau_p, p - ref, np.broadcast_to(w_p, tau_p.shape))]
    for order, tau, val, w in ((1, tau_v, v, w_v), (2, tau_a, a, w_a)):
        if tau is not None and val is not None:
            tau = np.asarray(tau, dtype=np.float64)
            data.append(
                DerivativeData(
                    order, tau, np.asarray(val, dtype=np.float64), np.broadcast_to(w, tau.shape)
                )
            )
    spl = fit_spline(breakpoints, degree, continuity, data)
    return BSpline(spl.t, spl.c + ref, spl.k, extrapolate=False)


def problem_omega(
    breakpoints: ArrayLike,
    degree: int,
    continuity: int | Sequence[int] | ArrayLike,
    tau: ArrayLike,
    omega: ArrayLike,
    w: ArrayLike = 1.0,
) -> BSpline:
    """Problem ω (eqs. (18)–(20)): angular-rate spline ``ω̂(t)`` from rate samples.

    Parameters
    ----------
    breakpoints, degree, continuity
        Spline space (see :func:`fit_spline`); ``continuity = 0`` gives a corner in ω,
        ``−1`` a jump (paper: ``ν_i = 1`` resp. ``0``).
    tau : array_like (N,)
        Sample times (s).
    omega : array_like (N, 3)
        Body angular-rate samples ``ω_ib^b`` (rad/s, body axes).
    w : float or array_like (N,)
        Weights ``1/σ_ω²`` (s²/rad²).

    Returns
    -------
    scipy.interpolate.BSpline
        ``ω̂(t)`` in rad/s, coefficients (n, 3).
    """
    tau = np.asarray(tau, dtype=np.float64)
    data = [
        DerivativeData(
            0,
            tau,
            np.asarray(omega, dtype=np.float64),
            np.broadcast_to(np.asarray(w, dtype=np.float64), tau.shape),
        )
    ]
    return fit_spline(breakpoints, degree, continuity, data)


# --------------------------------------------------------------------------------------------
# Quaternion functions: projection, derivative (22) and rate (23)
# --------------------------------------------------------------------------------------------


class PiecewiseSpline:
    """Vector function made of B-splines on consecutive segments (continuous at the joins).

    Parameters
    ----------
    edges : array_like (S + 1,)
        Segment boundaries (s), strictly increasing.
    pieces : sequence of scipy.interpolate.BSpline
        ``S`` splines, piece ``i`` defined on ``[edges[i], edges[i+1]]``. At an interior
        boundary the piece on the right is used.
    """

    def __init__(self, edges: ArrayLike, pieces: Sequence[BSpline]) -> None:
        self.edges = np.asarray(edges, dtype=np.float64)
        self.pieces = list(pieces)
        if self.edges.size != len(self.pieces) + 1:
            raise ValueError("PiecewiseSpline: need len(edges) == len(pieces) + 1")

    def __call__(self, t: ArrayLike, nu: int = 0) -> F64:
        """``nu``-th derivative at times ``t`` (array (...,)), shape (..., m)."""
        t = np.asarray(t, dtype=np.float64)
        flat = t.reshape(-1)
        idx = np.clip(np.searchsorted(self.edges, flat, side="right") - 1, 0, len(self.pieces) - 1)
        out: F64 | None = None
        for i in np.unique(idx):
            sel = idx == i
            val = self.pieces[i](flat[sel], nu)
            if out is None:
                out = np.empty((flat.size,) + val.shape[1:])
            out[sel] = val
        if out is None:
            out = np.empty((0,) + np.shape(self.pieces[0].c)[1:])
        return out.reshape(t.shape + out.shape[1:])


class QuaternionSpline:
    """Consistent attitude and rate from a quaternion spline ``q̄(t)`` (Problem q2).

    ``q(t) = P(q̄(t)) = q̄/‖q̄‖`` is the attitude (scalar first, ``q_b^i``: body to the
    reference frame), ``q̇`` its exact derivative (eq. (22), see the module erratum) and
    ``ω(t) = vec(2 q* ⊗ q̇)`` (eq. (23)) the body rate ``ω_ib^b``; by construction
    ``q̇ = ½ q ⊗ [0, ω]`` (eq. (21)) holds to rounding error at every ``t``.

    Parameters
    ----------
    qbar : callable ``(t, nu) -> array (..., 4)``
        The unnormalized quaternion spline and its derivatives (a ``BSpline`` or a
        :class:`PiecewiseSpline`).
    """

    def __init__(self, qbar: BSpline | PiecewiseSpline) -> None:
        self.qbar = qbar

    def q(self, t: ArrayLike) -> F64:
        """Unit quaternion ``q(t)`` (..., 4), scalar first."""
        qb = self.qbar(np.asarray(t, dtype=np.float64), 0)
        return qb / np.linalg.norm(qb, axis=-1, keepdims=True)

    def q_dot(self, t: ArrayLike) -> F64:
        """``q̇(t) = (I − q qᵀ) q̄̇ / ‖q̄‖`` (eq. (22), exact form), 1/s, shape (..., 4)."""
        t = np.asarray(t, dtype=np.float64)
        qb = self.qbar(t, 0)
        dqb = self.qbar(t, 1)
        norm = np.linalg.norm(qb, axis=-1, keepdims=True)
        q = qb / norm
        return (dqb - q * np.sum(q * dqb, axis=-1, keepdims=True)) / norm

    def omega(self, t: ArrayLike) -> F64:
        """Body rate ``ω`` (rad/s, body axes): vector part of ``2 q* ⊗ q̇`` (eq. (23))."""
        t = np.asarray(t, dtype=np.float64)
        return 2.0 * quat_multiply(quat_conjugate(self.q(t)), self.q_dot(t))[..., 1:]


def align_quaternion_signs(q: ArrayLike) -> F64:
    """Flip signs so consecutive quaternions have non-negative dot products (same rotations).

    ``q`` and ``−q`` describe one rotation; a component-wise fit needs a continuous path.

    Parameters
    ----------
    q : array_like (N, 4)

    Returns
    -------
    ndarray (N, 4)
    """
    q = np.array(q, dtype=np.float64)
    if q.shape[0] < 2:
        return q
    flips = np.sum(q[1:] * q[:-1], axis=-1) < 0.0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)])
    return q * sign[:, None]


def fit_quaternion(
    breakpoints: ArrayLike,
    degree: int,
    continuity: int | Sequence[int] | ArrayLike,
    tau: ArrayLike,
    q: ArrayLike,
    w_q: ArrayLike = 1.0,
    *,
    omega: ArrayLike | None = None,
    w_omega: ArrayLike = 0.0,
) -> QuaternionSpline:
    """Attitude fit: Problem 1 on quaternion samples, then the projection of Problem q2.

    Extension of the paper (which obtains the quaternion from rates only): the sign-aligned
    samples ``q̃_i`` are fitted component-wise (eq. (10), m = 4) with, when rate samples are
    given at the same times, the derivative data ``q̃̇_i = ½ q̃_i ⊗ [0, ω̃_i]`` (eq. (21)).
    The result is projected on the unit sphere and ω follows from eq. (23), so the pair is
    consistent whatever the data. A quaternion error ``δq ≈ δθ/2`` and ``δq̇ ≈ δω/2``, so
    the residuals are weighted ``4 w`` with ``w = 1/σ²`` of angle and rate.

    Parameters
    ----------
    breakpoints, degree, continuity
        Spline space of ``q̄`` (see :func:`fit_spline`). ``continuity`` is that of the
        attitude: ``C^1`` gives a corner in ω, ``C^0`` a jump in ω.
    tau : array_like (N,)
        Sample times (s).
    q : array_like (N, 4)
        Attitude samples ``q_b^i`` (scalar first); signs are aligned here.
    w_q : float or array_like (N,)
        Attitude weights ``1/σ_θ²`` (1/rad²).
    omega : array_like (N, 3), optional
        Body-rate samples ``ω_ib^b`` (rad/s) at the same times.
    w_omega : float or array_like (N,)
        Rate weights ``1/σ_ω²`` (s²/rad²).

    Returns
    -------
    QuaternionSpline
    """
    tau = np.asarray(tau, dtype=np.float64)
    qs = align_quaternion_signs(np.asarray(q, dtype=np.float64))
    qs = qs / np.linalg.norm(qs, axis=-1, keepdims=True)
    data = [DerivativeData(0, tau, qs, 4.0 * np.broadcast_to(np.asarray(w_q, float), tau.shape))]
    if omega is not None:
        om = np.asarray(omega, dtype=np.float64)
        pure = np.concatenate([np.zeros(om.shape[:-1] + (1,)), om], axis=-1)
        data.append(
            DerivativeData(
                1,
                tau,
                0.5 * quat_multiply(qs, pure),
                4.0 * np.broadcast_to(np.asarray(w_omega, float), tau.shape),
            )
        )
    return QuaternionSpline(fit_spline(breakpoints, degree, continuity, data))


# --------------------------------------------------------------------------------------------
# Problems q1 and q2
# --------------------------------------------------------------------------------------------


def problem_q1(
    omega: BSpline,
    q0: ArrayLike,
    breakpoints: ArrayLike,
    *,
    step: float,
    rtol: float = 1e-12,
    atol: float = 1e-13,
) -> tuple[F64, F64, F64]:
    """Problem q1: integrate ``q̇ = ½ q ⊗ [0, ω̂]`` (eq. (21)) from ``q(t_1) = q0``.

    The integration (scipy ``solve_ivp``, DOP853, tight tolerances) restarts at every
    breakpoint of ``ω̂`` (a polynomial between breakpoints, so the right-hand side is smooth
    on every run). The paper takes the integrator's own steps as the sample sequence
    ``{τ̃}``; here the dense output is sampled on a uniform grid of spacing ``<= step`` in
    every breakpoint interval (breakpoints included), which suits the interpolation of q2.

    Parameters
    ----------
    omega : scipy.interpolate.BSpline
        ``ω̂(t)`` from :func:`problem_omega` (rad/s, body axes).
    q0 : array_like (4,)
        Initial attitude ``q_b^i(t_1)``, scalar first.
    breakpoints : array_like (T,)
        Breakpoints of ``ω̂`` (s).
    step : float
        Largest output spacing (s).
    rtol, atol : float
        Integrator tolerances (the paper's precision/compression trade-off).

    Returns
    -------
    tau : ndarray (M,)
        Output times (s), strictly increasing, containing every breakpoint.
    q : ndarray (M, 4)
        Integrated quaternions (normalized).
    piece : ndarray (M − 1,) of int
        Index of the breakpoint interval of each output interval ``[τ_j, τ_{j+1}]``.
    """
    bp = np.asarray(breakpoints, dtype=np.float64)
    q = np.asarray(q0, dtype=np.float64)
    q = q / np.linalg.norm(q)

    def rhs(t: float, y: F64) -> F64:
        w = omega(np.array([t]))[0]
        return 0.5 * quat_multiply(y, np.concatenate([[0.0], w]))

    taus: list[F64] = [bp[:1]]
    qs: list[F64] = [q[None, :]]
    pieces: list[F64] = []
    for i in range(bp.size - 1):
        a, b = bp[i], bp[i + 1]
        n = max(int(np.ceil((b - a) / step)), 1)
        grid = np.linspace(a, b, n + 1)
        sol = solve_ivp(rhs, (a, b), q, method="DOP853", rtol=rtol, atol=atol, dense_output=True)
        if not sol.success:  # pragma: no cover - DOP853 on a polynomial rate
            raise RuntimeError(f"Problem q1 integration failed: {sol.message}")
        y = sol.sol(grid[1:]).T
        y[-1] = sol.y[:, -1]
        y = y / np.linalg.norm(y, axis=-1, keepdims=True)
        taus.append(grid[1:])
        qs.append(y)
        pieces.append(np.full(n, i))
        q = y[-1]
    return np.concatenate(taus), np.concatenate(qs), np.concatenate(pieces)


def problem_q2(
    tau: ArrayLike,
    q: ArrayLike,
    corners: ArrayLike = (),
    *,
    degree: int = 5,
) -> QuaternionSpline:
    """Problem q2: interpolate the Problem q1 quaternions, project, differentiate (22)–(23).

    The paper interpolates with a cubic spline; a degree-5 not-a-knot interpolant
    (``make_interp_spline``) is the default here (``C^4``, so ω is ``C^3`` away from the
    corners). At the ``corners`` (times where the integrated rate is not smooth enough, e.g.
    breakpoints with reduced continuity) the interpolation restarts, so q̄ is only ``C^0``
    there and ω may show its corner or jump instead of being smoothed over.

    Parameters
    ----------
    tau : array_like (M,)
        Strictly increasing times (s); must contain the corners.
    q : array_like (M, 4)
        Unit quaternions at ``tau`` (signs aligned here).
    corners : array_like
        Interior times (s) at which to restart the interpolation.
    degree : int
        Interpolating spline degree (odd, >= 3).

    Returns
    -------
    QuaternionSpline
        The consistent pair (q(t), ω(t)).
    """
    tau = np.asarray(tau, dtype=np.float64)
    qs = align_quaternion_signs(q)
    inner = np.asarray(corners, dtype=np.float64).reshape(-1)
    edges = np.concatenate([[tau[0]], np.sort(inner), [tau[-1]]])
    pieces = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        i0 = int(np.searchsorted(tau, a - 1e-9 * max(1.0, abs(a)), side="left"))
        i1 = int(np.searchsorted(tau, b + 1e-9 * max(1.0, abs(b)), side="right"))
        seg_t, seg_q = tau[i0:i1], qs[i0:i1]
        if seg_t.size < degree + 1 or abs(seg_t[0] - a) > 1e-9 * max(1.0, abs(a)):
            raise ValueError(
                f"problem_q2: segment [{float(a)!r}, {float(b)!r}] has {seg_t.size} samples (need "
                f"{degree + 1}) or does not start at a sample"
            )
        pieces.append(make_interp_spline(seg_t, seg_q, k=degree))
    return QuaternionSpline(PiecewiseSpline(edges, pieces))
