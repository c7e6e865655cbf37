"""Filter consistency statistics over Monte Carlo runs.

Bar-Shalom, Li & Kirubarajan 2001, *Estimation with Applications to Tracking and Navigation*,
§5.4: for N independent runs, the average NEES (or NIS) of an epoch, ``ε̄ = (1/N) Σ εᵢ``, is
``χ²_{N d} / N`` distributed for a consistent filter with d degrees of freedom (eq. (5.4.2-4)),
so its two-sided ``1 - α`` acceptance interval is ``[χ²_{Nd}(α/2)/N, χ²_{Nd}(1 - α/2)/N]``
(eq. (5.4.2-6)). A consistent filter's ε̄ is inside the interval at about ``1 - α`` of the
epochs. The same test applies to a normalized squared error of one scalar (d = 1), e.g. a bias
estimate error over its σ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

__all__ = ["Inside", "average_interval", "fraction_inside", "normalized_squares"]


def average_interval(dof: int, runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` interval of the N-run average of a χ²_dof statistic."""
    if runs < 1 or dof < 1:
        raise ValueError(f"need runs >= 1 and dof >= 1, got {runs}, {dof}")
    a = 0.5 * (1.0 - probability)
    k = dof * runs
    return float(chi2.ppf(a, k) / runs), float(chi2.ppf(1.0 - a, k) / runs)


@dataclass(frozen=True)
class Inside:
    """Average statistic per epoch against its interval.

    The fraction of epochs inside and the fractions below and above, the mean of the average,
    the interval, the number of epochs.
    """

    fraction: float
    below: float
    above: float
    mean: float
    interval: tuple[float, float]
    epochs: int


def fraction_inside(values: ArrayLike, dof: int, probability: float = 0.95) -> Inside:
    """Check the run-average of a χ²_dof statistic per epoch.

    ``values`` (N runs, K epochs); the average per epoch is checked against
    :func:`average_interval` (epochs with a NaN entry, which a run lacks, are left out).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2:
        raise ValueError("values must be (runs, epochs)")
    ok = np.all(np.isfinite(v), axis=0)
    v = v[:, ok]
    runs, k = v.shape
    lo, hi = average_interval(dof, runs, probability)
    avg = v.mean(axis=0)
    if k == 0:
        return Inside(float("nan"), float("nan"), float("nan"), float("nan"), (lo, hi), 0)
    return Inside(
        float(np.mean((avg >= lo) & (avg <= hi))), float(np.mean(avg < lo)),
        float(np.mean(avg > hi)), float(avg.mean()), (lo, hi), int(k),
    )  # fmt: skip


def normalized_squares(errors: ArrayLike, sigmas: ArrayLike) -> NDArray[np.float64]:
    """``(e / σ)²`` element-wise (a χ²_1 statistic per component for a consistent estimate)."""
    return (np.asarray(errors, dtype=np.float64) / np.asarray(sigmas, dtype=np.float64)) ** 2

