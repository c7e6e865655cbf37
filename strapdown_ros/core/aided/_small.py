"""Compiled 3×3 algebra of the aided filter: skew matrices, products, the rotation exponential.

Plain loops over preallocated arrays (numba; no BLAS call per 3×3 product). ``skew(v)`` is
``[v×]`` with ``[v×] w = v × w``; ``rotation_exp(φ)`` is ``exp([φ×])`` by Rodrigues' formula
(Savage 1998 Part 1 eq. (12); the series form near zero as in
:func:`strapdown_ros.core.navigation._kernels.rotation_coefficients_scalar`).
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aided._jit import jit
from strapdown_ros.core.navigation._kernels import rotation_coefficients_scalar

__all__ = [
    "cross",
    "matmul3",
    "matvec3",
    "matvec3_t",
    "rot_z",
    "rotation_exp",
    "skew",
]


@jit
def skew(v):
    """``[v×]`` (3, 3) of a 3-vector."""
    s = np.zeros((3, 3))
    s[0, 1], s[0, 2] = -v[2], v[1]
    s[1, 0], s[1, 2] = v[2], -v[0]
    s[2, 0], s[2, 1] = -v[1], v[0]
    return s


@jit
def cross(a, b):
    """``a × b`` (3,)."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@jit
def matvec3(m, v):
    """``m v`` (3,) of a (3, 3) matrix and a 3-vector."""
    out = np.empty(3)
    for i in range(3):
        out[i] = m[i, 0] * v[0] + m[i, 1] * v[1] + m[i, 2] * v[2]
    return out


@jit
def matvec3_t(m, v):
    """``mᵀ v`` (3,)."""
    out = np.empty(3)
    for i in range(3):
        out[i] = m[0, i] * v[0] + m[1, i] * v[1] + m[2, i] * v[2]
    return out


@jit
def matmul3(a, b):
    """``a b`` of two (3, 3) matrices."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]
    return out


@jit
def rot_z(angle):
    """``Rz(angle)`` = [[c, -s, 0], [s, c, 0], [0, 0, 1]] (``C_E^E0(t)`` for angle ω_ie t)."""
    c, s = math.cos(angle), math.sin(angle)
    out = np.zeros((3, 3))
    out[0, 0], out[0, 1], out[1, 0], out[1, 1], out[2, 2] = c, -s, s, c, 1.0
    return out


@jit
def rotation_exp(phi):
    """``exp([φ×]) = I + f1 [φ×] + f2 [φ×]²`` (Rodrigues; f1 = sin x / x, f2 = (1 - cos x)/x²)."""
    x = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    f1, f2, _, _ = rotation_coefficients_scalar(x)
    s = skew(phi)
    s2 = matmul3(s, s)
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = f1 * s[i, j] + f2 * s2[i, j] + (1.0 if i == j else 0.0)
    return out
