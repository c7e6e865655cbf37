"""Compiled hot loops of the generator: Method 2's pairs, stacked 3×3 products (numba).

Savage 2020 Method 2 (eq. (31) for arrays of cycle pairs) in one pass per pair instead of ~40
numpy array passes (``core/method2.py`` calls it; the theory is in docs/theory/), and
``matmul33``: ``a @ b`` for stacks of 3×3 matrices (numpy calls BLAS once per 3×3, ~1.5 µs).
The arithmetic reproduces the numpy formulation bit for bit on x86-64: a 3×3 ``@`` is
OpenBLAS' fused multiply-add chain ``fma(a₂b₂, fma(a₁b₁, a₀b₀))``, the ``einsum``
matrix-vector product sums ``(x₀ + x₂) + x₁`` (two SIMD lanes), everything else is element-wise
in the same order (numba does not contract ``a*b + c`` without ``fastmath``).
``tools/compare_generate.py`` and ``test/test_method2.py`` check the bits.

Compiled with ``cache=True``: the first import of a fresh install compiles (~2 s) and writes the
cache; later processes load it (see docs/benchmarks.md for where the cache lives). Without numba
the functions run as plain Python (correct, slow); ``HAVE_NUMBA`` tells the caller.
"""

from __future__ import annotations

import numpy as np

try:  # numba is optional: the ROS-free core must import without it.
    import numba
    from numba import types
    from numba.extending import intrinsic

    HAVE_NUMBA = True
    _jit = numba.njit(cache=True, nogil=True)

    @intrinsic
    def _fma(typingctx, a, b, c):  # pragma: no cover - compiled
        """``a * b + c`` with one rounding (LLVM ``llvm.fma.f64``)."""
        sig = types.float64(types.float64, types.float64, types.float64)

        def codegen(context, builder, signature, args):
            return builder.fma(*args)

        return sig, codegen

except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None
    HAVE_NUMBA = False

    def _jit(fn):
        return fn

    def _fma(a, b, c):
        raise NotImplementedError("the Method 2 kernels need numba")


__all__ = ["HAVE_NUMBA", "matmul33", "pair_solve_kernel", "pair_system_kernel"]


@_jit
def _mm(a, b, out):
    """``out = a @ b`` for 3×3 (OpenBLAS' FMA order)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = _fma(a[i, 2], b[2, j], _fma(a[i, 1], b[1, j], a[i, 0] * b[0, j]))


@_jit
def _mv(a, v, out):
    """``out = a v`` for 3×3 (numpy ``einsum``'s order)."""
    for i in range(3):
        out[i] = (a[i, 0] * v[0] + a[i, 2] * v[2]) + a[i, 1] * v[1]


@_jit
def _inv3(m, out):
    """Adjugate inverse, the order of ``method2._inv3``."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    c0, c1, c2 = e * i - f * h, c * h - b * i, b * f - c * e
    c3, c4, c5 = f * g - d * i, a * i - c * g, c * d - a * f
    c6, c7, c8 = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * c0 + b * c3 + c * c6
    out[0, 0], out[0, 1], out[0, 2] = c0 / det, c1 / det, c2 / det
    out[1, 0], out[1, 1], out[1, 2] = c3 / det, c4 / det, c5 / det
    out[2, 0], out[2, 1], out[2, 2] = c6 / det, c7 / det, c8 / det


@_jit
def _g_vr(phi, f2, f3, f4, gv, gr):
    """``G_V``, ``G_R`` of eqs. (3), (4), the order of ``exact_update.g_matrices``.

    ``f2, f3, f4``: the coefficient functions of ``series.rotation_coefficients`` at ``|φ|``.
    """
    x, y, z = phi[0], phi[1], phi[2]
    dot = (x * x + z * z) + y * y  # einsum "...i,...i"
    for i in range(3):
        for j in range(3):
            eye = 1.0 if i == j else 0.0
            if i == j:
                k = 0.0
            elif i == 0:
                k = -z if j == 1 else y
            elif i == 1:
                k = z if j == 0 else -x
            else:
                k = -y if j == 0 else x
            kk = phi[i] * phi[j] - dot * eye
            gv[i, j] = eye + f2 * k + f3 * kk
            gr[i, j] = 0.5 * eye + f3 * k + f4 * kk


@_jit
def pair_system_kernel(
    c, dalpha, f2, f3, f4, r, v, g, disp, use_disp, t,
    cgv1, cgr1, b_inv_odd, b_inv_even, num_odd, num_even, k_odd, k_even,
):  # fmt: skip
    """Eq. (31) factored for every pair n (cycles 2n, 2n+1, 2n+2 of ``c, r, v, g``).

    ``dalpha`` (Δα_m, row m-1 for cycle m) and its coefficient functions ``f2, f3, f4`` give
    ``G_V``, ``G_R``. Outputs per pair: ``C G_V``, ``C G_R`` of cycle 2n+1, the inverted B_den
    of eqs. (26)/(29), B_num without the odd-cycle gravity term and that term's coefficient
    (see ``method2.PairSystem``).
    """
    gv1 = np.empty((3, 3))
    gr1 = np.empty((3, 3))
    gv2 = np.empty((3, 3))
    gr2 = np.empty((3, 3))
    tt = t * t
    t6 = tt / 6.0
    cgrv1 = np.empty((3, 3))
    cgv2 = np.empty((3, 3))
    cgr2 = np.empty((3, 3))
    inv = np.empty((3, 3))
    a_odd = np.empty((3, 3))
    a_even = np.empty((3, 3))
    tmp = np.empty((3, 3))
    w = np.empty(3)
    base = np.empty(3)
    av = np.empty(3)
    for n in range(cgv1.shape[0]):
        e0 = 2 * n
        od = e0 + 1
        e1 = e0 + 2
        _g_vr(dalpha[e0], f2[e0], f3[e0], f4[e0], gv1, gr1)
        _g_vr(dalpha[od], f2[od], f3[od], f4[od], gv2, gr2)
        _mm(c[e0], gv1, cgv1[n])
        _mm(c[e0], gr1, cgr1[n])
        _mm(c[od], gv2, cgv2)
        _mm(c[od], gr2, cgr2)
        for i in range(3):
            for j in range(3):
                cgrv1[i, j] = cgr1[n, i, j] + cgv1[n, i, j]
        _inv3(cgv2, inv)
        _mm(cgr2, inv, a_odd)
        _inv3(cgv1[n], inv)
        _mm(cgrv1, inv, a_even)
        _mm(a_odd, cgv1[n], tmp)
        for i in range(3):
            for j in range(3):
                tmp[i, j] = (cgrv1[i, j] - tmp[i, j]) * t
        _inv3(tmp, b_inv_odd[n])
        _mm(a_even, cgv2, tmp)
        for i in range(3):
            for j in range(3):
                tmp[i, j] = (cgr2[i, j] - tmp[i, j]) * t
        _inv3(tmp, b_inv_even[n])
        for i in range(3):
            d = disp[n, i] if use_disp else r[e1, i] - r[e0, i]
            dr = d - 2.0 * v[e0, i] * t
            dvel = v[e1, i] - v[e0, i]
            base[i] = dr - (g[e1, i] + 5.0 * g[e0, i]) * t6
            w[i] = -dvel * t + 0.5 * (g[e1, i] + g[e0, i]) * tt
        _mv(a_odd, w, av)
        for i in range(3):
            num_odd[n, i] = base[i] + av[i]
        _mv(a_even, w, av)
        for i in range(3):
            num_even[n, i] = base[i] + av[i]
        for i in range(3):
            for j in range(3):
                eye = 1.0 if i == j else 0.0
                k_odd[n, i, j] = (a_odd[i, j] - eye) * tt
                k_even[n, i, j] = (a_even[i, j] - eye) * tt


@_jit
def pair_solve_kernel(
    cgv1, cgr1, b_inv_odd, b_inv_even, num_odd, num_even, k_odd, k_even,
    r, v, g, g_odd, t, dv_odd, dv_even, v_odd, r_odd,
):  # fmt: skip
    """Eqs. (27), (30) for odd-cycle gravity ``g_odd``, then eqs. (3), (4) over cycle 2n+1."""
    t6 = t * t / 6.0
    x = np.empty(3)
    y = np.empty(3)
    for n in range(cgv1.shape[0]):
        e0 = 2 * n
        g1 = g_odd[n]
        _mv(k_odd[n], g1, y)
        for i in range(3):
            x[i] = num_odd[n, i] + y[i]
        _mv(b_inv_odd[n], x, dv_odd[n])
        _mv(k_even[n], g1, y)
        for i in range(3):
            x[i] = num_even[n, i] + y[i]
        _mv(b_inv_even[n], x, dv_even[n])
        _mv(cgv1[n], dv_odd[n], x)
        _mv(cgr1[n], dv_odd[n], y)
        for i in range(3):
            v_odd[n, i] = v[e0, i] + x[i] + 0.5 * (g1[i] + g[e0, i]) * t
            r_odd[n, i] = (
                r[e0, i] + v[e0, i] * t + y[i] * t + (g1[i] + 2.0 * g[e0, i]) * t6
            )


@_jit
def _matmul33_kernel(a, b, transpose_a, out):
    t = np.empty((3, 3))
    for n in range(out.shape[0]):
        an = a[n] if a.shape[0] > 1 else a[0]
        bn = b[n] if b.shape[0] > 1 else b[0]
        if transpose_a:
            for i in range(3):
                for j in range(3):
                    t[i, j] = an[j, i]
            _mm(t, bn, out[n])
        else:
            _mm(an, bn, out[n])


def matmul33(a: np.ndarray, b: np.ndarray, transpose_a: bool = False) -> np.ndarray:
    """``a @ b`` (``aᵀ @ b`` with ``transpose_a``) for stacks of 3×3 matrices, same bits.

    ``a``, ``b``: (N, 3, 3) both, or one of them (3, 3) (broadcast over the other's N). Other
    shapes, and runs without numba, fall back to numpy's ``@``.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ok = a.ndim in (2, 3) and b.ndim in (2, 3) and a.shape[-2:] == (3, 3) == b.shape[-2:]
    ok = ok and not (a.ndim == b.ndim == 2) and (a.ndim == 2 or b.ndim == 2 or a.shape == b.shape)
    if not (HAVE_NUMBA and ok):
        return (np.swapaxes(a, -1, -2) if transpose_a else a) @ b
    n_a = a.shape[0] if a.ndim == 3 else 1
    n_b = b.shape[0] if b.ndim == 3 else 1
    out = np.empty((n_a if a.ndim == 3 else n_b, 3, 3))
    _matmul33_kernel(
        np.ascontiguousarray(a.reshape(n_a, 3, 3)),
        np.ascontiguousarray(b.reshape(n_b, 3, 3)),
        transpose_a,
        out,
    )
    return out


@_jit
def normal_band_kernel(indptr, indices, data, w, vals, p, ab, rhs):
    """One term of Giribet eq. (14): ``ab += band(Aᵀ W A)``, ``rhs += Aᵀ W vals``.

    ``A`` in CSR (``indptr, indices, data``; rows = samples), ``ab`` the upper band
    (``ab[p - (j - i), j] = M[i, j]``, scipy's ``cholesky_banded`` layout). Each entry is
    summed over the samples in ascending order, as scipy.sparse's ``aw.T @ a`` and
    ``aw.T @ vals`` do (``aw = A * w``), so the bits are the same.
    """
    n = ab.shape[1]
    m = vals.shape[1]
    band = np.zeros((p + 1, n))
    acc = np.zeros((n, m))
    for k in range(indptr.size - 1):
        wk = w[k]
        for e in range(indptr[k], indptr[k + 1]):
            i = indices[e]
            awi = data[e] * wk
            for f in range(indptr[k], indptr[k + 1]):
                j = indices[f]
                if j >= i:
                    band[p - (j - i), j] += awi * data[f]
            for c in range(m):
                acc[i, c] += awi * vals[k, c]
    for r in range(p + 1):
        for j in range(n):
            ab[r, j] = ab[r, j] + band[r, j]
    for i in range(n):
        for c in range(m):
            rhs[i, c] = rhs[i, c] + acc[i, c]
