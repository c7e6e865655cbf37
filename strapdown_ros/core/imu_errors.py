"""IMU error model applied to ideal increments: biases, scale factors, noise, quantization.

The ideal ``Δα`` (rad) and ``Δv`` (m/s) of consecutive cycles in body FRD axes become the
measured increments of an IMU whose sensor axes are the body axes (fixed, turn-on and
Gauss–Markov biases, rate random walk, scale factors, misalignments, g-sensitivity, white
noise, saturation, quantization with the residual carried). The model takes SI parameters
(:class:`ImuErrorParameters`; built from a scenario's ``imu_errors`` section by
``strapdown_ros.config.imu_errors.ImuErrorsSpec.parameters``); applied in chunks of any sizes it
gives the same bits as applied at once. Equations, discretizations, random-number layout:
docs/theory/imu_errors.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import lfilter

from strapdown_ros.core.allan import BIAS_INSTABILITY_FACTOR, GAUSS_MARKOV_PEAK
from strapdown_ros.core.array_types import F64

__all__ = [
    "G0",
    "NORMALS_PER_SAMPLE",
    "ImuErrorModel",
    "ImuErrorParameters",
    "SensorErrors",
    "misalignment_matrix",
]


#: Standard gravity (m/s²), the ``g`` of the ``mg`` and ``_g`` units.
G0 = 9.80665

#: Standard normals drawn per cycle (per sensor: white 3, Gauss–Markov 3 + 3, random walk 3 + 3).
NORMALS_PER_SAMPLE = 30
_UNIT_NORMALS = 15  # per sensor at construction: turn-on 3, scale factor 3, misalignment 6, GM 3

# Off-diagonal positions of the 6-value misalignment form [xy, xz, yx, yz, zx, zy].
_OFF_DIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))


@dataclass(frozen=True, eq=False)
class SensorErrors:
    """Error parameters of one sensor triad (gyros or accelerometers), SI units, FRD axes.

    Rates are rad/s for the gyros and m/s² for the accelerometers ("rate" below).

    Attributes
    ----------
    bias : (3,) array
        Fixed bias (rate).
    turn_on_bias_sigma : (3,) array
        1σ of the turn-on bias drawn once per run (rate).
    bias_instability : (3,) array
        Bias instability ``B`` as read on an Allan deviation plot (rate); 0: none.
    correlation_time_s : (3,) array
        Correlation time ``τ_c`` of the Gauss–Markov bias (s), > 0.
    white : (3,) array
        White-noise coefficient ``N`` (ARW in rad/√s, VRW in m/s/√s).
    random_walk : (3,) array
        Rate random walk ``K`` (rate/√s).
    scale_factor, scale_factor_sigma : (3,) array
        Fixed scale-factor error and 1σ of a per-run random one (dimensionless).
    misalignment, misalignment_sigma : (3, 3) array
        Fixed misalignment and 1σ of per-run random ones (rad, zero diagonal).
    quantum : (3,) array
        Quantum of the increments (rad or m/s); 0: not quantized.
    range : (3,) array
        Saturation of the mean rate over a period (rate); 0: unlimited.
    g_sensitivity : (3, 3) array
        Gyro g-sensitivity (rad/s per m/s² of specific force); zero for accelerometers.
    """

    bias: F64
    turn_on_bias_sigma: F64
    bias_instability: F64
    correlation_time_s: F64
    white: F64
    random_walk: F64
    scale_factor: F64
    scale_factor_sigma: F64
    misalignment: F64
    misalignment_sigma: F64
    quantum: F64
    range: F64
    g_sensitivity: F64

    @classmethod
    def zero(cls) -> SensorErrors:
        """A perfect sensor triad (τ_c = 1 s, unused)."""
        z3, z33 = np.zeros(3), np.zeros((3, 3))
        return cls(z3, z3, z3, np.ones(3), z3, z3, z3, z3, z33, z33, z3, z3, z33)

    @property
    def gauss_markov_sigma(self) -> F64:
        """Steady-state deviation ``σ_GM = 0.664 B / 0.6174`` of the Gauss–Markov bias (rate)."""
        return self.bias_instability * (BIAS_INSTABILITY_FACTOR / GAUSS_MARKOV_PEAK)


@dataclass(frozen=True, eq=False)
class ImuErrorParameters:
    """Parameters of one IMU run: both triads in SI units (FRD axes) and the random seed.

    ``seed`` (>= 0) seeds the run's ``PCG64`` generator: the per-run constants and all noise.
    """

    gyro: SensorErrors
    accel: SensorErrors
    seed: int = 0

    @classmethod
    def perfect(cls, seed: int = 0) -> ImuErrorParameters:
        """A perfect IMU (the measured increments are the ideal ones)."""
        return cls(SensorErrors.zero(), SensorErrors.zero(), seed)


def misalignment_matrix(values: ArrayLike) -> F64:
    """3×3 misalignment matrix of the 6 values ``[xy, xz, yx, yz, zx, zy]`` (zero diagonal)."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (6,):
        raise ValueError(f"expected 6 values, got shape {v.shape}")
    m = np.zeros((3, 3))
    for k, (i, j) in enumerate(_OFF_DIAG):
        m[i, j] = v[k]
    return m


# ---------------------------------------------------------------------------------------------
# The stateful model.


def _gm_integral_factor(x: F64) -> F64:
    """``h(x) = x - 2(1 - e^{-x}) + (1 - e^{-2x})/2`` (→ x³/3 for small x), x = T/τ_c."""
    e1 = -np.expm1(-x)
    e2 = -np.expm1(-2.0 * x)
    direct = x - 2.0 * e1 + 0.5 * e2
    series = x**3 * (1.0 / 3.0 - x / 4.0 + 7.0 * x**2 / 60.0)
    return np.where(x < 1e-3, series, direct)


class _Triad:
    """One sensor triad's realized constants, discretized noise and carried state."""

    def __init__(self, p: SensorErrors, period_s: float, unit: F64) -> None:
        T = period_s
        self.T = T
        # Per-run constants (draws in the fixed layout, whatever the sigmas).
        self.bias_T = (p.bias + p.turn_on_bias_sigma * unit[0:3]) * T
        scale = p.scale_factor + p.scale_factor_sigma * unit[3:6]
        mis = p.misalignment + p.misalignment_sigma * misalignment_matrix(unit[6:12])
        self.error_matrix = np.diag(scale) + mis  # S + M
        self.g_sensitivity = p.g_sensitivity
        self.has_g = bool(np.any(p.g_sensitivity != 0))
        # White noise.
        self.white = p.white * math.sqrt(T)
        # Gauss–Markov: b_{k+1} = φ b_k + η1, ∫b = c b_k + η2, (η1, η2) = L (ξ1, ξ2).
        sigma = p.gauss_markov_sigma
        self.has_gm = bool(np.any(sigma > 0))
        tau = p.correlation_time_s
        x = T / tau
        self.phi = np.exp(-x)
        self.gm_c = -tau * np.expm1(-x)
        var1 = sigma**2 * -np.expm1(-2.0 * x)
        cov = sigma**2 * tau * np.expm1(-x) ** 2
        var2 = 2.0 * sigma**2 * tau**2 * _gm_integral_factor(x)
        with np.errstate(invalid="ignore", divide="ignore"):
            self.l11 = np.sqrt(var1)
            self.l21 = np.where(var1 > 0, cov / np.where(var1 > 0, self.l11, 1.0), 0.0)
            self.l22 = np.sqrt(np.maximum(var2 - self.l21**2, 0.0))
        self.gm = sigma * unit[12:15]
        # Rate random walk: b_{k+1} = b_k + K√T ξ1, ∫b = T b_k + K T^{3/2} (ξ1/2 + ξ2/(2√3)).
        self.has_rw = bool(np.any(p.random_walk > 0))
        self.rw_step = p.random_walk * math.sqrt(T)
        self.rw_a1 = p.random_walk * T**1.5 / 2.0
        self.rw_a2 = p.random_walk * T**1.5 / (2.0 * math.sqrt(3.0))
        self.rw = np.zeros(3)
        # Saturation and quantization.
        self.limit = np.where(p.range > 0, p.range * T, np.inf)
        self.has_limit = bool(np.any(p.range > 0))
        self.quantum = p.quantum.copy()
        self.quantized = np.flatnonzero(p.quantum > 0)
        self.cum = np.zeros(3)  # running sum of the quantizer inputs
        self.count = np.zeros(3)  # floor(cum / q) after the last cycle

    def noise(self, z: F64) -> F64:
        """Integrated stochastic errors of n cycles, (n, 3); advances the states."""
        n = z.shape[0]
        out = self.white * z[:, 0:3]
        if self.has_gm:
            eta1 = self.l11 * z[:, 3:6]
            eta2 = self.l21 * z[:, 3:6] + self.l22 * z[:, 6:9]
            start = np.empty((n, 3))
            for axis in range(3):
                phi = float(self.phi[axis])
                y = lfilter([1.0], [1.0, -phi], eta1[:, axis], zi=[phi * self.gm[axis]])[0]
                start[0, axis] = self.gm[axis]
                start[1:, axis] = y[:-1]
                self.gm[axis] = y[-1]
            out = out + (self.gm_c * start + eta2)
        if self.has_rw:
            walk = np.cumsum(np.concatenate([self.rw[None, :], self.rw_step * z[:, 9:12]]), axis=0)
            out = out + (self.T * walk[:-1] + (self.rw_a1 * z[:, 9:12] + self.rw_a2 * z[:, 12:15]))
            self.rw = walk[-1].copy()
        return out

    def apply(self, ideal: F64, z: F64, dv: F64 | None) -> F64:
        """Measured increments (n, 3) of ideal increments (n, 3); advances the states."""
        e = self.error_matrix
        err = (
            self.bias_T
            + (ideal[:, 0:1] * e[:, 0] + ideal[:, 1:2] * e[:, 1])
            + (ideal[:, 2:3] * e[:, 2])
        )
        if dv is not None and self.has_g:
            g = self.g_sensitivity
            err = err + ((dv[:, 0:1] * g[:, 0] + dv[:, 1:2] * g[:, 1]) + dv[:, 2:3] * g[:, 2])
        out = ideal + (err + self.noise(z))
        if self.has_limit:
            out = np.clip(out, -self.limit, self.limit)
        for axis in self.quantized:
            q = self.quantum[axis]
            cum = np.cumsum(np.concatenate([[self.cum[axis]], out[:, axis]]))
            counts = np.floor(cum[1:] / q)
            previous = np.concatenate([[self.count[axis]], counts[:-1]])
            out[:, axis] = (counts - previous) * q
            self.cum[axis] = cum[-1]
            self.count[axis] = counts[-1]
        return out


class ImuErrorModel:
    """The error model of one IMU run, applied to consecutive cycles (state carried).

    Parameters
    ----------
    params : ImuErrorParameters
        The run's parameters (SI units, FRD axes).
    period_s : float
        Cycle period T (s) of the increments.

    Notes
    -----
    :meth:`apply` takes the next cycles in order; calling it on chunks of any sizes gives the
    same output bit for bit as one call on all cycles. :meth:`skip` advances the random state
    and the bias processes over cycles whose ideal increments are unknown (e.g. a gap in a live
    input), so later cycles get the noise they would have had; the quantizer's running sum does
    not include the skipped cycles.

    Attributes
    ----------
    cycles : int
        Cycles applied or skipped so far.
    """

    def __init__(self, params: ImuErrorParameters, period_s: float) -> None:
        if not (period_s > 0 and math.isfinite(period_s)):
            raise ValueError(f"period_s must be finite and > 0, got {period_s}")
        self.params = params
        self.period_s = float(period_s)
        self._rng = np.random.Generator(np.random.PCG64(params.seed))
        unit = self._rng.standard_normal((2, _UNIT_NORMALS))
        self._gyro = _Triad(params.gyro, self.period_s, unit[0])
        self._accel = _Triad(params.accel, self.period_s, unit[1])
        self.cycles = 0

    # Realized per-run constants (fixed + drawn), for checks and reports.
    @property
    def gyro_bias(self) -> F64:
        """Constant gyro bias of this run, fixed plus turn-on (rad/s, FRD)."""
        return self._gyro.bias_T / self.period_s

    @property
    def accel_bias(self) -> F64:
        """Constant accelerometer bias of this run, fixed plus turn-on (m/s², FRD)."""
        return self._accel.bias_T / self.period_s

    @property
    def gyro_error_matrix(self) -> F64:
        """``S + M`` of the gyros in this run (3×3, dimensionless)."""
        return self._gyro.error_matrix.copy()

    @property
    def accel_error_matrix(self) -> F64:
        """``S + M`` of the accelerometers in this run (3×3, dimensionless)."""
        return self._accel.error_matrix.copy()

    def apply(self, dalpha: ArrayLike, dv: ArrayLike) -> tuple[F64, F64]:
        """Measured increments of the next n cycles.

        Parameters
        ----------
        dalpha, dv : (n, 3) array
            Ideal Δα (rad) and Δv (m/s) of consecutive cycles, body FRD.

        Returns
        -------
        dalpha_measured, dv_measured : (n, 3) array
            Measured increments (rad, m/s), body FRD.
        """
        da = np.asarray(dalpha, dtype=np.float64)
        dv_ = np.asarray(dv, dtype=np.float64)
        if da.ndim != 2 or da.shape[1:] != (3,) or dv_.shape != da.shape:
            raise ValueError(
                f"dalpha and dv must both have shape (n, 3), got {da.shape}, {dv_.shape}"
            )
        n = da.shape[0]
        if n == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        z = self._rng.standard_normal((n, NORMALS_PER_SAMPLE))
        gyro = self._gyro.apply(da, z[:, :15], dv_)
        accel = self._accel.apply(dv_, z[:, 15:], None)
        self.cycles += n
        return gyro, accel

    def skip(self, n: int) -> None:
        """Advance over ``n`` cycles without input or output (random state and bias processes)."""
        if n < 0:
            raise ValueError(f"n must be >= 0, got {n}")
        if n == 0:
            return
        z = self._rng.standard_normal((n, NORMALS_PER_SAMPLE))
        self._gyro.noise(z[:, :15])
        self._accel.noise(z[:, 15:])
        self.cycles += n

    def rate_noise_variance(self) -> tuple[F64, F64]:
        """Variance of the white part of one cycle's mean-rate error, per FRD axis.

        ``N²/T`` (white noise) plus ``q²/(6 T²)`` (quantization with the residual carried: the
        mean-rate error of a cycle is the difference of two residuals, each uniform over one
        quantum). The bias terms (fixed, turn-on, instability, random walk), scale factors and
        misalignments are correlated from cycle to cycle and not included.

        Returns
        -------
        gyro : (3,) array
            (rad/s)².
        accel : (3,) array
            (m/s²)².
        """
        T = self.period_s
        out = []
        for p in (self.params.gyro, self.params.accel):
            out.append(p.white**2 / T + p.quantum**2 / (6.0 * T**2))
        return out[0], out[1]
