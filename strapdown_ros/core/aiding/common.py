"""Shared pieces of the aiding models: epochs, seeded generators, sampled Gauss–Markov processes.

Chunk invariance (as in :mod:`strapdown_ros.core.imu_errors`): every per-epoch operation is
element-wise or a sequential recursion with carried state (``scipy.signal.lfilter`` with its
initial condition), and each epoch consumes a fixed number of normals, so processing the epochs
in pieces of any size gives the same bits as processing them at once. See ``docs/aiding.md``.
"""

from __future__ import annotations

import math
from dataclasses import field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from strapdown_ros.core.array_types import F64

__all__ = [
    "SENSOR_STREAMS",
    "GaussMarkov",
    "check_period",
    "epoch_mask",
    "mat_t_vec",
    "mat_vec",
    "per_axis",
    "rate_cross_lever",
    "sensor_rng",
]


#: Spawn key of each sensor's random stream: the same ``seed`` on two sensors gives
#: independent noise.
SENSOR_STREAMS = {"gnss": 1, "baro": 2, "magnetometer": 3, "wheel_odometer": 4}


def per_axis(fill: float = 0.0) -> Any:
    """A dataclass field of one value per axis: a (3,) float64 array, ``fill`` by default."""
    return field(default_factory=partial(np.full, 3, fill))


def sensor_rng(seed: int, sensor: str) -> np.random.Generator:
    """``Generator(PCG64(SeedSequence(seed, spawn_key=(k,))))`` of one sensor (k by sensor)."""
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    sequence = np.random.SeedSequence(seed, spawn_key=(SENSOR_STREAMS[sensor],))
    return np.random.Generator(np.random.PCG64(sequence))


def epoch_mask(stamps_ns: ArrayLike, period_ns: int) -> NDArray[np.bool_]:
    """True where a stamp (ns since the Unix epoch) is a sensor epoch: a multiple of ``period_ns``.

    Epochs are aligned on the absolute time grid (``period_ns`` divides 1e9 for whole-second
    alignment; checked by the configuration), not on the first stamp seen.
    """
    t = np.asarray(stamps_ns, dtype=np.int64)
    return (t % int(period_ns)) == 0


def mat_vec(c: F64, v: F64) -> F64:
    """``c @ v`` of stacked 3×3 matrices (n, 3, 3) and vectors (n, 3), element-wise sums.

    Written out so that each output element is the same sum in the same order whatever n
    (a batched matrix product may change its summation with the array size).
    """
    return (c[..., 0] * v[..., 0:1] + c[..., 1] * v[..., 1:2]) + c[..., 2] * v[..., 2:3]


def mat_t_vec(c: F64, v: F64) -> F64:
    """``cᵀ @ v`` of stacked 3×3 matrices and vectors (see :func:`mat_vec`)."""
    return (c[..., 0, :] * v[..., 0:1] + c[..., 1, :] * v[..., 1:2]) + c[..., 2, :] * v[..., 2:3]


def rate_cross_lever(omega_eb_b: ArrayLike, lever_arm_b: ArrayLike) -> F64:
    """``ω × l`` (n, 3): velocity (m/s, body FRD) of a point on the body relative to the IMU.

    ``lever_arm_b``: the point from the IMU (m, FRD, (3,) or (n, 3)); ``omega_eb_b``: body
    rates relative to the Earth (n, 3, rad/s, FRD). Written out, one sum order whatever n.
    """
    w = np.asarray(omega_eb_b, dtype=np.float64)
    lever = np.broadcast_to(np.asarray(lever_arm_b, dtype=np.float64), w.shape)
    return np.stack(
        [
            w[:, 1] * lever[:, 2] - w[:, 2] * lever[:, 1],
            w[:, 2] * lever[:, 0] - w[:, 0] * lever[:, 2],
            w[:, 0] * lever[:, 1] - w[:, 1] * lever[:, 0],
        ],
        axis=-1,
    )


class GaussMarkov:
    """First-order Gauss–Markov processes sampled at epochs of period P, one per column.

    ``x_{k+1} = φ x_k + σ √(1 − φ²) ξ_k``, ``φ = e^{−P/τ}`` (exact discretization of
    ``ẋ = −x/τ + w``, stationary deviation σ); ``x_0 = σ ξ_init``. A zero σ gives zeros.

    Parameters
    ----------
    sigma, tau : array_like (k,)
        Stationary deviation (any unit) and correlation time τ (s, > 0 where σ > 0).
    period_s : float
        Epoch period P (s).
    initial : array_like (k,)
        Standard normals of the initial state.
    """

    def __init__(self, sigma: ArrayLike, tau: ArrayLike, period_s: float, initial: ArrayLike):
        self.sigma = np.asarray(sigma, dtype=np.float64).copy()
        tau_ = np.asarray(tau, dtype=np.float64)
        active = self.sigma > 0
        if np.any(active & ~(tau_ > 0)):
            raise ValueError("a Gauss–Markov process with sigma > 0 needs tau > 0")
        x = np.where(active, period_s / np.where(active, tau_, 1.0), 0.0)
        self.phi = np.where(active, np.exp(-x), 0.0)
        self.drive = np.where(active, self.sigma * np.sqrt(-np.expm1(-2.0 * x)), 0.0)
        self.state = self.sigma * np.asarray(initial, dtype=np.float64)
        self.active = bool(np.any(active))

    def take(self, xi: F64) -> F64:
        """Values at the next n epochs (n, k) from standard normals ``xi`` (n, k); advances."""
        n, k = xi.shape
        out = np.zeros((n, k))
        if not self.active or n == 0:
            return out
        for j in range(k):
            if self.sigma[j] == 0.0:
                continue
            phi = float(self.phi[j])
            y = lfilter([1.0], [1.0, -phi], self.drive[j] * xi[:, j], zi=[phi * self.state[j]])[0]
            out[0, j] = self.state[j]
            out[1:, j] = y[:-1]
            self.state[j] = y[-1]
        return out

    @property
    def variance(self) -> F64:
        """Stationary variance σ² per column."""
        return self.sigma**2


def check_period(period_s: float) -> float:
    """``period_s`` if finite and > 0 (ValueError otherwise)."""
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period_s must be finite and > 0, got {period_s}")
    return float(period_s)
