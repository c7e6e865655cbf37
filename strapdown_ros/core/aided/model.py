"""The stochastic model of the aided filter: P0 and Q from the IMU and aiding-sensor error models.

:func:`build_model` turns the error parameters the simulation uses (``ImuErrorParameters`` of
:mod:`strapdown_ros.core.imu_errors`, the sensor error dataclasses of
:mod:`strapdown_ros.core.aiding`) into the filter's continuous-time model: for every error state
its initial σ, its decay rate β = 1/τ (0: random constant or random walk) and the power
spectral density q of its driving white noise; for the navigation states the body-axis white
noise PSDs of the accelerometers (velocity random walk) and gyros (angle random walk).
docs/theory/aided_ins.md §3 lists the correspondences:

* white noise of the mean rate of one cycle, ``σ² = N²/T + q_Q²/(6 T²)`` per axis
  (:meth:`~strapdown_ros.core.imu_errors.ImuErrorModel.rate_noise_variance`: ARW/VRW and
  quantization), as a continuous white noise of PSD ``σ² T``;
* bias: random constant with ``σ0 = turn-on σ`` plus the rate random walk, PSD ``K²``;
* Gauss–Markov bias (bias instability): ``σ_GM = 0.664 B / 0.6174`` (the model's own
  conversion), ``β = 1/τ_c``, ``q = 2 σ_GM² / τ_c``, ``σ0 = σ_GM`` (stationary start);
* scale factor: random constant, ``σ0 = scale_factor_sigma``;
* sensors: barometer turn-on bias (constant) and drift (Gauss–Markov), GNSS Gauss–Markov
  position/velocity errors per NED axis, magnetometer hard iron (constant), wheel scale factor
  (constant), the wheel encoder's quantization residuals (as speeds, σ0 = (q/P)/√12 each, no
  dynamics: they change at the wheel epochs only, :func:`~.update.carry_quantization`).

Fixed (deterministic) error terms, misalignments, g-sensitivity and saturation are not modelled
(the cost of leaving them out is measured in docs/aided.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from strapdown_ros.core.aided.layout import (
    B_BA,
    B_BARO_BIAS,
    B_BARO_DRIFT,
    B_BG,
    B_GMA,
    B_GMG,
    B_GNSS_POS,
    B_GNSS_VEL,
    B_MAG,
    B_SFA,
    B_SFG,
    B_WHEEL_QUANT,
    B_WHEEL_SF,
    N_INS,
    StateLayout,
)
from strapdown_ros.core.aiding.baro import BaroErrors
from strapdown_ros.core.aiding.gnss import GnssErrors
from strapdown_ros.core.aiding.magnetometer import MagnetometerErrors
from strapdown_ros.core.aiding.odometer import OdometerErrors
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters

__all__ = ["FilterModel", "SensorModels", "StateOptions", "build_model"]



@dataclass(frozen=True)
class StateOptions:
    """Which optional states to model.

    ``True`` always, ``False`` never, ``None`` when the error model has the term (a σ > 0).
    """

    gauss_markov: bool | None = None
    scale_factors: bool | None = None
    sensor_errors: bool | None = None


@dataclass(frozen=True)
class SensorModels:
    """The error models of the aiding sensors the filter uses (None: not used).

    ``wheel_period_s``: the wheel odometer's epoch period P (s), needed with an encoder
    quantization (``wheel.pulses_per_m > 0``).
    """

    gnss: GnssErrors | None = None
    baro: BaroErrors | None = None
    mag: MagnetometerErrors | None = None
    wheel: OdometerErrors | None = None
    wheel_period_s: float = 0.0


@dataclass(frozen=True)
class FilterModel:
    """The filter's continuous-time stochastic model.

    Attributes
    ----------
    layout : StateLayout
    sigma0 : (n,) array
        Initial σ of the error states (navigation entries 0: set from the initial sigmas).
    beta : (n,) array
        Decay rate 1/τ of each non-navigation state (1/s; 0: constant or random walk).
    q : (n,) array
        PSD of the white noise driving each non-navigation state (unit²/s).
    q_ins : (6,) array
        Body-axis PSDs: accelerometer white noise (m²/s³) x, y, z, then gyro ((rad)²/s).
    period_s : float
        IMU period T (s).
    """

    layout: StateLayout
    sigma0: F64
    beta: F64
    q: F64
    q_ins: F64
    period_s: float

    def scaled(self, q_scale: float) -> FilterModel:
        """The model with every PSD multiplied by ``q_scale`` (mistuning studies)."""
        return FilterModel(
            self.layout, self.sigma0, self.beta, self.q * q_scale, self.q_ins * q_scale,
            self.period_s,
        )  # fmt: skip


def _on(option: bool | None, present: bool) -> bool:
    return present if option is None else bool(option)


def _set(arr: F64, layout: StateLayout, block: int, values: F64 | float) -> None:
    arr[layout.slice(block)] = values


def build_model(
    imu: ImuErrorParameters,
    period_s: float,
    sensors: SensorModels,
    options: StateOptions = StateOptions(),
) -> FilterModel:
    """The filter model matching the error models ``imu`` and ``sensors``.

    ``period_s``: the IMU period; ``options`` choose the optional states
    (docs/theory/aided_ins.md §3).
    """
    g, a = imu.gyro, imu.accel
    gm = _on(options.gauss_markov, bool(np.any(g.bias_instability > 0)
                                        or np.any(a.bias_instability > 0)))  # fmt: skip
    sf = _on(options.scale_factors, bool(np.any(g.scale_factor_sigma > 0)
                                         or np.any(a.scale_factor_sigma > 0)))  # fmt: skip
    se = options.sensor_errors
    blocks = [B_BG, B_BA]
    if gm:
        blocks += [B_GMG, B_GMA]
    if sf:
        blocks += [B_SFG, B_SFA]
    if sensors.baro is not None:
        if _on(se, sensors.baro.turn_on_bias_sigma > 0 or sensors.baro.bias != 0):
            blocks.append(B_BARO_BIAS)
        if _on(se, sensors.baro.drift_sigma > 0):
            blocks.append(B_BARO_DRIFT)
    if sensors.gnss is not None:
        if _on(se, bool(np.any(np.asarray(sensors.gnss.position_gm_sigma) > 0))):
            blocks.append(B_GNSS_POS)
        if _on(se, bool(np.any(np.asarray(sensors.gnss.velocity_gm_sigma) > 0))):
            blocks.append(B_GNSS_VEL)
    if sensors.mag is not None and _on(se, bool(np.any(np.asarray(sensors.mag.hard_iron_sigma)
                                                       > 0))):  # fmt: skip
        blocks.append(B_MAG)
    if sensors.wheel is not None and _on(se, sensors.wheel.scale_factor_sigma > 0):
        blocks.append(B_WHEEL_SF)
    if sensors.wheel is not None and sensors.wheel.pulses_per_m > 0 and _on(se, True):
        if not (sensors.wheel_period_s > 0 and math.isfinite(sensors.wheel_period_s)):
            raise ValueError(f"wheel_period_s must be finite and > 0 with an encoder "
                             f"quantization, got {sensors.wheel_period_s}")  # fmt: skip
        blocks.append(B_WHEEL_QUANT)
    layout = StateLayout(tuple(blocks))
    n = layout.n
    sigma0, beta, q = np.zeros(n), np.zeros(n), np.zeros(n)

    # IMU: biases (turn-on σ, rate random walk K²), Gauss–Markov parts, scale factors.
    _set(sigma0, layout, B_BG, g.turn_on_bias_sigma)
    _set(sigma0, layout, B_BA, a.turn_on_bias_sigma)
    _set(q, layout, B_BG, g.random_walk**2)
    _set(q, layout, B_BA, a.random_walk**2)
    for block, sensor in ((B_GMG, g), (B_GMA, a)):
        if layout.has(block):
            s, tau = sensor.gauss_markov_sigma, np.asarray(sensor.correlation_time_s, float)
            _set(sigma0, layout, block, s)
            _set(beta, layout, block, 1.0 / tau)
            _set(q, layout, block, 2.0 * s**2 / tau)
    if layout.has(B_SFG):
        _set(sigma0, layout, B_SFG, g.scale_factor_sigma)
        _set(sigma0, layout, B_SFA, a.scale_factor_sigma)

    # Aiding sensors.
    if layout.has(B_BARO_BIAS):
        _set(sigma0, layout, B_BARO_BIAS, sensors.baro.turn_on_bias_sigma)  # type: ignore[union-attr]
    if layout.has(B_BARO_DRIFT):
        b = sensors.baro
        assert b is not None
        _set(sigma0, layout, B_BARO_DRIFT, b.drift_sigma)
        _set(beta, layout, B_BARO_DRIFT, 1.0 / b.drift_tau_s)
        _set(q, layout, B_BARO_DRIFT, 2.0 * b.drift_sigma**2 / b.drift_tau_s)
    for block, sig, tau in (
        (B_GNSS_POS, "position_gm_sigma", "position_gm_tau_s"),
        (B_GNSS_VEL, "velocity_gm_sigma", "velocity_gm_tau_s"),
    ):
        if layout.has(block):
            s = np.asarray(getattr(sensors.gnss, sig), float)
            t = np.asarray(getattr(sensors.gnss, tau), float)
            _set(sigma0, layout, block, s)
            _set(beta, layout, block, 1.0 / t)
            _set(q, layout, block, 2.0 * s**2 / t)
    if layout.has(B_MAG):
        _set(sigma0, layout, B_MAG, np.asarray(sensors.mag.hard_iron_sigma, float))  # type: ignore[union-attr]
    if layout.has(B_WHEEL_SF):
        _set(sigma0, layout, B_WHEEL_SF, sensors.wheel.scale_factor_sigma)  # type: ignore[union-attr]
    if layout.has(B_WHEEL_QUANT):  # each residual: (q/P)²/12, half the speed's (q/P)²/6
        var = sensors.wheel.quantization_variance(sensors.wheel_period_s) / 2.0  # type: ignore[union-attr]
        _set(sigma0, layout, B_WHEEL_QUANT, math.sqrt(var))

    # White noise of the navigation states: σ² T of the mean rate of a cycle.
    var_g, var_a = ImuErrorModel(imu, period_s).rate_noise_variance()
    q_ins = np.concatenate([var_a * period_s, var_g * period_s])
    beta[:N_INS] = 0.0
    q[:N_INS] = 0.0
    for arr in (sigma0, beta, q, q_ins):
        arr.setflags(write=False)
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period_s must be finite and > 0, got {period_s}")
    return FilterModel(layout, sigma0, beta, q, q_ins, float(period_s))
