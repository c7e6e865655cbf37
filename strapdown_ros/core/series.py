"""Rotation-vector coefficient functions of Savage 2020 eqs. (2)-(4), exact at every angle.

The matrices G_C, G_V, G_R of Savage 2020 eqs. (2)-(4) (and the rotation vector to direction
cosine matrix conversion) are built from four scalar functions of the rotation angle
``x = |Δα|`` (rad):

=====  ===========================  ======================  ==================
name   closed form                  value at x = 0          used in
=====  ===========================  ======================  ==================
f1     sin x / x                    1                       G_C, eq. (2)
f2     (1 - cos x) / x²             1/2                     G_C (2), G_V (3)
f3     (1 - sin x / x) / x²         1/6                     G_V (3), G_R (4)
f4     (1/2 - (1 - cos x)/x²) / x²  1/24                    G_R (4)
=====  ===========================  ======================  ==================

The closed forms of f3 and f4 lose up to 12 ε/x² relative accuracy to cancellation, so below
``SERIES_SWITCH`` each function is evaluated from its Taylor series in x² (Horner form, enough
terms that the truncation is below 1e-18 relative at the switch). Above the switch the closed
forms are used, written to avoid cancellation where possible (f2 = ½ (sin(x/2)/(x/2))²). At the
switch both forms agree to better than 1e-15 relative (tested against mpmath).
"""

from __future__ import annotations

from math import factorial

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SERIES_SWITCH", "f1", "f2", "f3", "f4", "rotation_coefficients"]

#: Angle (rad) below which the Taylor series are used instead of the closed forms.
SERIES_SWITCH = 2.0

_N_TERMS = 16


def _taylor(offset: int) -> NDArray[np.float64]:
    """Coefficients c_k of Σ (-1)^k x^{2k} / (2k + offset)!, k = 0.._N_TERMS-1."""
    return np.array([(-1) ** k / factorial(2 * k + offset) for k in range(_N_TERMS)])


# f1 = Σ (-1)^k x^2k/(2k+1)!, f2 = Σ (-1)^k x^2k/(2k+2)!, f3 = Σ (-1)^k x^2k/(2k+3)!,
# f4 = Σ (-1)^k x^2k/(2k+4)!.
_COEFFS = {n: _taylor(n) for n in (1, 2, 3, 4)}


def _horner(coeffs: NDArray[np.float64], x2: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.full_like(x2, coeffs[-1])
    for c in coeffs[-2::-1]:
        out = out * x2 + c
    return out


def _split(x: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    x = np.abs(np.asarray(x, dtype=np.float64))
    small = x < SERIES_SWITCH
    x_big = np.where(small, SERIES_SWITCH, x)  # closed forms never see small x
    return x, small, x_big


def f1(x: ArrayLike) -> NDArray[np.float64]:
    """sin x / x (dimensionless), x = rotation angle in rad; Savage 2020 eq. (2)."""
    x, small, xb = _split(x)
    return np.where(small, _horner(_COEFFS[1], x * x), np.sin(xb) / xb)


def f2(x: ArrayLike) -> NDArray[np.float64]:
    """(1 - cos x) / x² (dimensionless), x in rad; Savage 2020 eqs. (2), (3)."""
    x, small, xb = _split(x)
    half = 0.5 * xb
    return np.where(small, _horner(_COEFFS[2], x * x), 0.5 * (np.sin(half) / half) ** 2)


def f3(x: ArrayLike) -> NDArray[np.float64]:
    """(1 - sin x / x) / x² (dimensionless), x in rad; Savage 2020 eqs. (3), (4)."""
    x, small, xb = _split(x)
    return np.where(small, _horner(_COEFFS[3], x * x), (1.0 - np.sin(xb) / xb) / (xb * xb))


def f4(x: ArrayLike) -> NDArray[np.float64]:
    """(1/2 - (1 - cos x)/x²) / x² (dimensionless), x in rad; Savage 2020 eq. (4)."""
    x, small, xb = _split(x)
    half = 0.5 * xb
    closed = (0.5 - 0.5 * (np.sin(half) / half) ** 2) / (xb * xb)
    return np.where(small, _horner(_COEFFS[4], x * x), closed)


def rotation_coefficients(
    x: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """All four coefficient functions (f1, f2, f3, f4) of angle x (rad) in one call.

    Shares the series/closed-form split between the four functions; same values as calling
    :func:`f1` .. :func:`f4` separately. Savage 2020 eqs. (2)-(4).
    """
    x, small, xb = _split(x)
    x2 = x * x
    s = np.sin(xb) / xb
    half = 0.5 * xb
    c = 0.5 * (np.sin(half) / half) ** 2
    xb2 = xb * xb
    return (
        np.where(small, _horner(_COEFFS[1], x2), s),
        np.where(small, _horner(_COEFFS[2], x2), c),
        np.where(small, _horner(_COEFFS[3], x2), (1.0 - s) / xb2),
        np.where(small, _horner(_COEFFS[4], x2), (0.5 - c) / xb2),
    )
