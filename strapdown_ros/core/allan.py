"""Overlapping Allan deviation of rate samples and the standard noise-term readings.

The Allan variance of a rate ``Ω`` sampled at period ``T`` (rad/s of a gyro, m/s² of an
accelerometer) at averaging time ``τ = m T`` is computed from the integrated signal
``θ_k = Σ_{i<k} Ω_i T`` (rad or m/s, k = 0..M) with fully overlapping clusters
(IEEE Std 952-1997, Annex C; IEEE Std 1554-2005):

    σ²(τ) = 1 / (2 τ² (M + 1 - 2m)) Σ_{k=0}^{M-2m} (θ_{k+2m} - 2 θ_{k+m} + θ_k)².

The mean rate is removed before integrating (a constant rate cancels in the second difference;
removing it only keeps ``θ`` small for rounding). The Allan deviation ``σ(τ)`` has the units
of the rate.

Noise terms and how they show on the log-log ``σ(τ)`` plot (IEEE Std 952, Table C.2), with the
readings implemented here:

* white rate noise (angle/velocity random walk) ``N`` (rad/s·√s = rad/√s, or m/s/√s):
  ``σ = N / √τ``, slope −½, read at τ = 1 s (:func:`white_noise_coefficient`);
* bias instability ``B`` (rad/s or m/s²): the flat part (slope 0), ``σ_flat = √(2 ln 2 / π) B
  ≈ 0.664 B`` (:func:`bias_instability`, factor :data:`BIAS_INSTABILITY_FACTOR`): the floor
  of flicker noise, the top of the bump of a Gauss–Markov bias;
* rate random walk ``K`` (rad/s/√s or m/s²/√s): ``σ = K √(τ/3)``, slope +½, read at τ = 3 s
  (:func:`rate_random_walk`);
* quantization ``Q`` of the integrated signal (rad or m/s): ``σ = √3 Q / τ``, slope −1; a
  uniform quantizer of step ``q`` with the residual carried gives ``Q = q / √12``.

A first-order Gauss–Markov rate of steady-state deviation ``σ_GM`` and correlation time ``τ_c``
has ``σ²(τ) = σ_GM² g(τ/τ_c)`` with ``g(x) = (2/x)[1 - (3 - 4e^{-x} + e^{-2x}) / (2x)]``
(:func:`gauss_markov_allan_variance`); its deviation peaks at ``τ ≈ 1.89 τ_c`` at
``≈ 0.617 σ_GM`` (:data:`GAUSS_MARKOV_PEAK_X`, :data:`GAUSS_MARKOV_PEAK`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize_scalar

from strapdown_ros.core.array_types import F64

__all__ = [
    "BIAS_INSTABILITY_FACTOR",
    "GAUSS_MARKOV_PEAK",
    "GAUSS_MARKOV_PEAK_X",
    "bias_instability",
    "default_cluster_sizes",
    "gauss_markov_allan_variance",
    "model_allan_deviation",
    "overlapping_allan_deviation",
    "rate_random_walk",
    "white_noise_coefficient",
]


#: ``σ_min / B`` of flicker (1/f) rate noise: ``√(2 ln 2 / π) ≈ 0.6643`` (IEEE Std 952).
BIAS_INSTABILITY_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)


def _gm_g(x: ArrayLike) -> F64:
    """``g(x) = σ²(τ) / σ_GM²`` of a first-order Gauss–Markov rate at ``x = τ / τ_c`` (> 0)."""
    x = np.asarray(x, dtype=np.float64)
    # -expm1 forms keep the bracket accurate for small x (where it is ~ x²/3).
    e1 = -np.expm1(-x)  # 1 - e^{-x}
    e2 = -np.expm1(-2.0 * x)  # 1 - e^{-2x}
    # 3 - 4 e^{-x} + e^{-2x} = 4 (1 - e^{-x}) - (1 - e^{-2x})
    bracket = 1.0 - (4.0 * e1 - e2) / (2.0 * x)
    small = x < 1e-4
    if np.any(small):  # series of the bracket: x²/3 - x³/4 + 7x⁴/60 (g → 2x/3: random walk)
        xs = np.where(small, x, 1.0)
        bracket = np.where(small, xs**2 * (1.0 / 3.0 - xs / 4.0 + 7.0 * xs**2 / 60.0), bracket)
    return 2.0 / x * bracket


_PEAK = minimize_scalar(
    lambda x: -float(_gm_g(x)), bounds=(0.5, 5.0), method="bounded", options={"xatol": 1e-10}
)
#: ``τ / τ_c`` at which the Allan deviation of a Gauss–Markov rate peaks (≈ 1.893).
GAUSS_MARKOV_PEAK_X = float(_PEAK.x)
#: Peak Allan deviation of a Gauss–Markov rate divided by its steady-state deviation (≈ 0.6174).
GAUSS_MARKOV_PEAK = math.sqrt(float(_gm_g(GAUSS_MARKOV_PEAK_X)))


def default_cluster_sizes(
    samples: int, per_decade: int = 10, max_fraction: float = 1 / 3
) -> NDArray[np.int64]:
    """Log-spaced distinct cluster sizes ``m`` from 1 to ``max_fraction · samples``.

    Parameters
    ----------
    samples : int
        Number M of rate samples.
    per_decade : int
        Approximate number of sizes per decade of τ.
    max_fraction : float
        Largest ``m`` as a fraction of M (at most 1/2, the definition's limit).

    Returns
    -------
    (K,) int64 array
        Increasing cluster sizes (empty if M < 3).
    """
    m_max = int(samples * min(max_fraction, 0.5))
    if m_max < 1:
        return np.zeros(0, dtype=np.int64)
    count = max(2, int(math.ceil(per_decade * math.log10(m_max))) + 1)
    return np.unique(np.round(np.logspace(0.0, math.log10(m_max), count)).astype(np.int64))


def overlapping_allan_deviation(
    rate: ArrayLike, period_s: float, cluster_sizes: ArrayLike | None = None
) -> tuple[F64, F64]:
    """Fully overlapping Allan deviation of rate samples.

    Parameters
    ----------
    rate : (M,) or (M, k) array
        Samples of a rate (rad/s, m/s², ...) at period ``period_s``; each column is a
        separate signal (e.g. the x, y, z axes).
    period_s : float
        Sample period T (s), > 0.
    cluster_sizes : array of int, optional
        Cluster sizes ``m`` (τ = m T), each in 1..M//2. Default:
        :func:`default_cluster_sizes` (log-spaced, up to M//3).

    Returns
    -------
    taus : (K,) array
        Averaging times τ = m T (s).
    adev : (K,) or (K, k) array
        Allan deviation at each τ (units of ``rate``).
    """
    r = np.asarray(rate, dtype=np.float64)
    if r.ndim not in (1, 2):
        raise ValueError(f"rate must have shape (M,) or (M, k), got {r.shape}")
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period_s must be finite and > 0, got {period_s}")
    samples = r.shape[0]
    if cluster_sizes is None:
        sizes = default_cluster_sizes(samples)
    else:
        sizes = np.asarray(cluster_sizes, dtype=np.int64).reshape(-1)
        if sizes.size and (sizes.min() < 1 or 2 * sizes.max() > samples):
            raise ValueError(f"cluster sizes must be within 1..{samples // 2} for M = {samples}")
    theta = np.zeros((samples + 1,) + r.shape[1:])
    np.cumsum((r - r.mean(axis=0)) * period_s, axis=0, out=theta[1:])
    adev = np.empty((sizes.size,) + r.shape[1:])
    for i, m in enumerate(sizes):
        m = int(m)
        d = theta[2 * m :] - 2.0 * theta[m:-m] + theta[: -2 * m]
        tau = m * period_s
        adev[i] = np.sqrt(np.einsum("i...,i...->...", d, d) / (2.0 * tau**2 * d.shape[0]))
    return sizes * float(period_s), adev


def _log_interp(taus: F64, values: F64, tau_s: float) -> F64:
    """Interpolate ``values`` (K,) or (K, k) linearly in log-log at ``tau_s``."""
    t = np.asarray(taus, dtype=np.float64)
    if not (t[0] <= tau_s <= t[-1]):
        raise ValueError(f"τ = {tau_s} s is outside the computed range [{t[0]}, {t[-1]}] s")
    lv = np.log(np.asarray(values, dtype=np.float64))
    j = int(np.clip(np.searchsorted(t, tau_s), 1, t.size - 1))
    w = (math.log(tau_s) - math.log(t[j - 1])) / (math.log(t[j]) - math.log(t[j - 1]))
    return np.exp(lv[j - 1] + w * (lv[j] - lv[j - 1]))


def white_noise_coefficient(taus: ArrayLike, adev: ArrayLike, tau_s: float = 1.0) -> F64:
    """ARW / VRW coefficient ``N = σ(τ) √τ`` read on the −½ slope at ``τ = tau_s``.

    With ``rate`` in rad/s this is rad/√s (× 180/π × 60 for deg/√h); in m/s², m/s/√s
    (× 60 for m/s/√h). ``σ`` is interpolated log-log between the computed τ.

    Parameters
    ----------
    taus : (K,) array
        Increasing averaging times (s).
    adev : (K,) or (K, k) array
        Allan deviation.
    tau_s : float
        Where to read (s); 1 s by convention, inside the white-noise region.

    Returns
    -------
    float array, shape () or (k,)
        ``N`` per column.
    """
    return _log_interp(np.asarray(taus), np.asarray(adev), tau_s) * math.sqrt(tau_s)


def rate_random_walk(taus: ArrayLike, adev: ArrayLike, tau_s: float = 3.0) -> F64:
    """Rate random walk ``K = σ(τ) √(3/τ)`` read on the +½ slope at ``τ = tau_s``.

    ``tau_s`` must lie where the +½ slope dominates (the convention τ = 3 s reads the line
    extended there, so pass a larger τ on the actual +½ region).

    Returns
    -------
    float array, shape () or (k,)
        ``K`` (units of the rate per √s).
    """
    return _log_interp(np.asarray(taus), np.asarray(adev), tau_s) * math.sqrt(3.0 / tau_s)


def bias_instability(
    taus: ArrayLike,
    adev: ArrayLike,
    tau_min: float | None = None,
    tau_max: float | None = None,
) -> tuple[F64, F64]:
    """Bias instability ``B = σ_flat / 0.664`` read on the flat part of the Allan deviation.

    The flat part is where the log-log slope is closest to 0 (the usual reading, e.g. IEEE
    Std 952 Annex C): the minimum of a flicker floor, or the top of the bump of a Gauss–Markov
    bias. The slope at τ_i is the central difference over the neighbours i-1, i+1.

    Parameters
    ----------
    taus, adev
        As in :func:`white_noise_coefficient`.
    tau_min, tau_max : float, optional
        Only τ in ``[tau_min, tau_max]`` are searched. Default ``tau_max``: a third of the
        largest τ (the longest τ have few independent clusters and noisy slopes).

    Returns
    -------
    B : float array, shape () or (k,)
        ``σ_flat / BIAS_INSTABILITY_FACTOR`` per column (units of the rate).
    tau_flat : float array, shape () or (k,)
        τ (s) of the reading.
    """
    t = np.asarray(taus, dtype=np.float64)
    a = np.asarray(adev, dtype=np.float64)
    if t.ndim != 1 or t.size < 3 or a.shape[0] != t.size:
        raise ValueError("need >= 3 increasing τ and an adev with one row per τ")
    lt = np.log(t)
    la = np.log(a.reshape(t.size, -1))
    slope = (la[2:] - la[:-2]) / (lt[2:] - lt[:-2])[:, None]
    inner = t[1:-1]
    hi = t[-1] / 3.0 if tau_max is None else tau_max
    keep = inner <= hi
    if tau_min is not None:
        keep &= inner >= tau_min
    if not keep.any():
        raise ValueError("no τ in the requested range")
    idx = np.flatnonzero(keep)
    j = idx[np.argmin(np.abs(slope[idx]), axis=0)] + 1
    cols = np.arange(la.shape[1])
    b = np.exp(la[j, cols]) / BIAS_INSTABILITY_FACTOR
    shape = a.shape[1:]
    return b.reshape(shape), t[j].reshape(shape)


def gauss_markov_allan_variance(taus: ArrayLike, sigma: float, correlation_time_s: float) -> F64:
    """Allan variance of a first-order Gauss–Markov rate (steady-state σ, correlation τ_c).

    ``σ²(τ) = σ² g(τ/τ_c)``, ``g(x) = (2/x)[1 - (3 - 4e^{-x} + e^{-2x}) / (2x)]`` for the
    continuous process ``ḃ = -b/τ_c + w``.

    Returns
    -------
    (K,) array
        Allan variance (units of the rate, squared).
    """
    if not correlation_time_s > 0:
        raise ValueError(f"correlation_time_s must be > 0, got {correlation_time_s}")
    return sigma**2 * _gm_g(np.asarray(taus, dtype=np.float64) / correlation_time_s)


def model_allan_deviation(
    taus: ArrayLike,
    *,
    white: float = 0.0,
    gauss_markov_sigma: float = 0.0,
    correlation_time_s: float = 1.0,
    random_walk: float = 0.0,
    quantization: float = 0.0,
) -> F64:
    """Allan deviation of a sum of independent noise terms (theory, for plots and checks).

    Parameters
    ----------
    taus : (K,) array
        Averaging times (s).
    white : float
        White rate noise ``N`` (rate·√s): ``N²/τ``.
    gauss_markov_sigma, correlation_time_s : float
        Gauss–Markov rate (steady-state σ in rate units, τ_c in s).
    random_walk : float
        Rate random walk ``K`` (rate/√s): ``K² τ / 3``.
    quantization : float
        ``Q`` of the integrated signal (rate·s): ``3 Q² / τ²``.

    Returns
    -------
    (K,) array
        ``σ(τ)`` in the units of the rate.
    """
    t = np.asarray(taus, dtype=np.float64)
    var = white**2 / t + random_walk**2 * t / 3.0 + 3.0 * quantization**2 / t**2
    if gauss_markov_sigma:
        var = var + gauss_markov_allan_variance(t, gauss_markov_sigma, correlation_time_s)
    return np.sqrt(var)
