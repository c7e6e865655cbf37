"""IMU error model applied to ideal increments: biases, scale factors, noise, quantization.

Increments in, increments out: the ideal ``Δα_m`` (rad) and ``Δv_m`` (m/s) of cycle m over
``(t_{m-1}, t_m]`` in body FRD axes (:class:`~strapdown_ros.core.stream.Stream`) become the
measured increments of an IMU whose sensor axes are the body FRD axes. Every error is defined on
the rate ``ω`` (rad/s) or specific force ``f`` (m/s²) and integrated over the period ``T``:

    ω̃ = ω + b + b_to + b_GM(t) + b_RW(t) + (S + M) ω + G f + n        (gyro)
    f̃ = f + b + b_to + b_GM(t) + b_RW(t) + (S + M) f + n              (accelerometer)

so that ``Δα̃ = Δα + (b + b_to) T + (S + M) Δα + G Δv + ∫(b_GM + b_RW + n) dt`` (and the same
for ``Δṽ`` without ``G``), followed by saturation and quantization:

* ``b`` fixed bias; ``b_to`` turn-on bias, a random constant drawn once per run (per seed);
* ``S = diag(s)`` scale-factor errors, ``s`` fixed plus a random constant per run;
* ``M`` misalignment / non-orthogonality, small angles with a zero diagonal: sensor axis i
  senses ``M[i, j]`` of the rate along body axis j (fixed plus a random constant per run);
* ``G`` gyro g-sensitivity (rad/s per m/s², 3×3), applied to the true specific force;
* ``n`` white noise of PSD ``N²`` (angle / velocity random walk ``N``): its integral over a
  period is ``N √T ξ`` (ξ standard normal);
* ``b_GM`` first-order Gauss–Markov bias (bias instability): ``ḃ = -b/τ_c + w``, steady-state
  deviation ``σ_GM``, discretized exactly (``φ = e^{-T/τ_c}``, joint Gaussian of the state at
  the end of the period and of its integral over the period);
* ``b_RW`` rate random walk ``ḃ = K w`` (exact joint discretization of the state and its
  integral: variance ``K² T³/3`` of the integral, covariance ``K² T²/2`` with the state);
* saturation: the mean rate of a period is clipped to ± the range (the increment to ± range T);
* quantization of the increments with the residual carried to the next sample: the emitted
  increment of cycle m is ``q (n_m - n_{m-1})`` with ``n_m = floor(C_m / q)`` and ``C_m`` the
  running sum of the (saturated) increments, so the emitted sum over any window differs from
  the sum of the quantizer's inputs by less than one quantum ``q``.

**Bias instability.** A configured bias instability ``B`` is the value the standard Allan
reading returns, ``B = σ_min / 0.664`` (IEEE Std 952): the Gauss–Markov deviation is
``σ_GM = 0.664 B / 0.6174``, which puts the peak of its Allan deviation (at
``τ ≈ 1.89 τ_c``) at ``0.664 B`` (:mod:`strapdown_ros.core.allan`).

**Randomness and chunk invariance.** One ``numpy.random.Generator(PCG64(seed))`` per model.
At construction it draws a (2, 15) block of standard normals (per sensor: turn-on bias 3,
scale factor 3, misalignment 6, initial Gauss–Markov state 3; gyro row first); then each cycle
consumes one row of :data:`NORMALS_PER_SAMPLE` = 30 standard normals (per sensor: white 3,
Gauss–Markov 3 + 3, random walk 3 + 3; gyro columns first) whatever the parameters, so a
parameter set to zero does not change the noise of the others. All per-cycle arithmetic is
element-wise or a sequential accumulation, so applying the model to the cycles in chunks of any
sizes, with the state carried by the :class:`ImuErrorModel` object, gives bit-identical results
to applying it to all of them at once. The random-walk state starts at 0, the Gauss–Markov
state is drawn from its stationary distribution, the quantizer starts with a zero residual.

**Configuration** (:func:`parse_imu_errors`, the ``imu_errors`` section of a scenario): keys
carry their units; per-axis values are a scalar (all axes) or a list of 3 (FRD x, y, z);
misalignments are 6 values ``[xy, xz, yx, yz, zx, zy]`` (``M[i, j]``) or a 3×3 matrix with zero
diagonal. A ``preset`` (:data:`PRESETS`) gives every key a value and any key given next to it
overrides the preset's. See ``docs/scenarios.md`` and ``docs/theory/imu_errors.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from strapdown_ros.core.allan import BIAS_INSTABILITY_FACTOR, GAUSS_MARKOV_PEAK

__all__ = [
    "G0",
    "IMU_ERROR_KEYS",
    "NORMALS_PER_SAMPLE",
    "PRESETS",
    "PRESET_SOURCES",
    "ImuErrorModel",
    "ImuErrorParameters",
    "ImuErrorsError",
    "SensorErrors",
    "misalignment_matrix",
    "parse_imu_errors",
]

Array = NDArray[np.float64]

#: Standard gravity (m/s²), the ``g`` of the ``mg`` and ``_g`` units.
G0 = 9.80665
_DEG = math.pi / 180.0
_DPH = _DEG / 3600.0  # deg/h -> rad/s
_DPSH = _DEG / 60.0  # deg/√h -> rad/√s
_MG = G0 * 1e-3  # mg -> m/s²
_SQRT_H = 60.0  # √(3600 s)

#: Standard normals drawn per cycle (per sensor: white 3, Gauss–Markov 3 + 3, random walk 3 + 3).
NORMALS_PER_SAMPLE = 30
_UNIT_NORMALS = 15  # per sensor at construction: turn-on 3, scale factor 3, misalignment 6, GM 3

# Off-diagonal positions of the 6-value misalignment form [xy, xz, yx, yz, zx, zy].
_OFF_DIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))

# key -> (sensor, field, SI factor, kind, sign rule)
#   kind: "axes" (scalar or 3), "misalignment" (6 or 3x3 zero diagonal), "sigma6" (scalar, 6 or
#   3x3 zero diagonal), "matrix" (scalar, 3 or 3x3); sign rule: "any", "nonneg", "positive".
_SENSOR_KEYS: dict[str, tuple[str, str, float, str, str]] = {
    "gyro_bias_dph": ("gyro", "bias", _DPH, "axes", "any"),
    "gyro_turn_on_bias_sigma_dph": ("gyro", "turn_on_bias_sigma", _DPH, "axes", "nonneg"),
    "gyro_bias_instability_dph": ("gyro", "bias_instability", _DPH, "axes", "nonneg"),
    "gyro_correlation_time_s": ("gyro", "correlation_time_s", 1.0, "axes", "positive"),
    "gyro_arw_dpsh": ("gyro", "white", _DPSH, "axes", "nonneg"),
    "gyro_rrw_dphpsh": ("gyro", "random_walk", _DPH / _SQRT_H, "axes", "nonneg"),
    "gyro_scale_factor_ppm": ("gyro", "scale_factor", 1e-6, "axes", "any"),
    "gyro_scale_factor_sigma_ppm": ("gyro", "scale_factor_sigma", 1e-6, "axes", "nonneg"),
    "gyro_misalignment_mrad": ("gyro", "misalignment", 1e-3, "misalignment", "any"),
    "gyro_misalignment_sigma_mrad": ("gyro", "misalignment_sigma", 1e-3, "sigma6", "nonneg"),
    "gyro_quantum_rad": ("gyro", "quantum", 1.0, "axes", "nonneg"),
    "gyro_range_dps": ("gyro", "range", _DEG, "axes", "nonneg"),
    "gyro_g_sensitivity_dphpg": ("gyro", "g_sensitivity", _DPH / G0, "matrix", "any"),
    "accel_bias_mg": ("accel", "bias", _MG, "axes", "any"),
    "accel_turn_on_bias_sigma_mg": ("accel", "turn_on_bias_sigma", _MG, "axes", "nonneg"),
    "accel_bias_instability_mg": ("accel", "bias_instability", _MG, "axes", "nonneg"),
    "accel_correlation_time_s": ("accel", "correlation_time_s", 1.0, "axes", "positive"),
    "accel_vrw_mpsph": ("accel", "white", 1.0 / _SQRT_H, "axes", "nonneg"),
    "accel_rrw_mgpsh": ("accel", "random_walk", _MG / _SQRT_H, "axes", "nonneg"),
    "accel_scale_factor_ppm": ("accel", "scale_factor", 1e-6, "axes", "any"),
    "accel_scale_factor_sigma_ppm": ("accel", "scale_factor_sigma", 1e-6, "axes", "nonneg"),
    "accel_misalignment_mrad": ("accel", "misalignment", 1e-3, "misalignment", "any"),
    "accel_misalignment_sigma_mrad": ("accel", "misalignment_sigma", 1e-3, "sigma6", "nonneg"),
    "accel_quantum_mps": ("accel", "quantum", 1.0, "axes", "nonneg"),
    "accel_range_g": ("accel", "range", G0, "axes", "nonneg"),
}
_OTHER_KEYS = ("preset", "seed", "input_topic", "output_topic")
#: Every key accepted in an ``imu_errors`` section.
IMU_ERROR_KEYS: tuple[str, ...] = _OTHER_KEYS + tuple(_SENSOR_KEYS)

# Presets, in the units of the keys. Typical values of each grade, not a particular product:
# see PRESET_SOURCES and docs/theory/imu_errors.md. Random-per-unit terms (turn-on bias, scale
# factor, misalignment) are given as 1σ; fixed terms are zero except g-sensitivity.
_COMMON_ZERO = {
    "gyro_bias_dph": 0.0,
    "gyro_rrw_dphpsh": 0.0,
    "gyro_scale_factor_ppm": 0.0,
    "gyro_misalignment_mrad": [0.0] * 6,
    "accel_bias_mg": 0.0,
    "accel_rrw_mgpsh": 0.0,
    "accel_scale_factor_ppm": 0.0,
    "accel_misalignment_mrad": [0.0] * 6,
}
#: Error presets by grade (values in the units of the keys).
PRESETS: dict[str, dict[str, Any]] = {
    "consumer_mems": {
        **_COMMON_ZERO,
        "gyro_turn_on_bias_sigma_dph": 1800.0,  # 0.5 deg/s zero-rate offset
        "gyro_bias_instability_dph": 10.0,
        "gyro_correlation_time_s": 100.0,
        "gyro_arw_dpsh": 0.5,  # ~0.008 deg/s/√Hz noise density
        "gyro_scale_factor_sigma_ppm": 5000.0,
        "gyro_misalignment_sigma_mrad": 5.0,
        "gyro_g_sensitivity_dphpg": 200.0,  # ~0.06 deg/s/g linear-acceleration effect
        "gyro_quantum_rad": 1e-5,
        "gyro_range_dps": 2000.0,
        "accel_turn_on_bias_sigma_mg": 30.0,
        "accel_bias_instability_mg": 0.1,
        "accel_correlation_time_s": 100.0,
        "accel_vrw_mpsph": 0.1,  # ~170 µg/√Hz
        "accel_scale_factor_sigma_ppm": 10000.0,
        "accel_misalignment_sigma_mrad": 5.0,
        "accel_quantum_mps": 5e-5,
        "accel_range_g": 16.0,
    },
    "industrial": {
        **_COMMON_ZERO,
        "gyro_turn_on_bias_sigma_dph": 20.0,
        "gyro_bias_instability_dph": 5.0,
        "gyro_correlation_time_s": 100.0,
        "gyro_arw_dpsh": 0.2,
        "gyro_scale_factor_sigma_ppm": 1000.0,
        "gyro_misalignment_sigma_mrad": 1.0,
        "gyro_g_sensitivity_dphpg": 36.0,  # 0.01 deg/s/g
        "gyro_quantum_rad": 1e-6,
        "gyro_range_dps": 500.0,
        "accel_turn_on_bias_sigma_mg": 2.0,
        "accel_bias_instability_mg": 0.02,
        "accel_correlation_time_s": 100.0,
        "accel_vrw_mpsph": 0.04,
        "accel_scale_factor_sigma_ppm": 1000.0,
        "accel_misalignment_sigma_mrad": 1.0,
        "accel_quantum_mps": 1e-5,
        "accel_range_g": 8.0,
    },
    "tactical": {
        **_COMMON_ZERO,
        "gyro_turn_on_bias_sigma_dph": 1.0,
        "gyro_bias_instability_dph": 0.5,
        "gyro_correlation_time_s": 300.0,
        "gyro_arw_dpsh": 0.1,
        "gyro_scale_factor_sigma_ppm": 150.0,
        "gyro_misalignment_sigma_mrad": 0.5,
        "gyro_g_sensitivity_dphpg": 1.0,
        "gyro_quantum_rad": 1e-6,
        "gyro_range_dps": 1000.0,
        "accel_turn_on_bias_sigma_mg": 1.0,
        "accel_bias_instability_mg": 0.05,
        "accel_correlation_time_s": 300.0,
        "accel_vrw_mpsph": 0.03,
        "accel_scale_factor_sigma_ppm": 300.0,
        "accel_misalignment_sigma_mrad": 0.5,
        "accel_quantum_mps": 1e-5,
        "accel_range_g": 40.0,
    },
    "navigation": {
        **_COMMON_ZERO,
        "gyro_turn_on_bias_sigma_dph": 0.005,
        "gyro_bias_instability_dph": 0.002,
        "gyro_correlation_time_s": 3600.0,
        "gyro_arw_dpsh": 0.002,
        "gyro_scale_factor_sigma_ppm": 5.0,
        "gyro_misalignment_sigma_mrad": 0.02,
        "gyro_g_sensitivity_dphpg": 0.0,  # optical gyros
        "gyro_quantum_rad": 1e-6,
        "gyro_range_dps": 400.0,
        "accel_turn_on_bias_sigma_mg": 0.03,
        "accel_bias_instability_mg": 0.005,
        "accel_correlation_time_s": 3600.0,
        "accel_vrw_mpsph": 0.005,
        "accel_scale_factor_sigma_ppm": 50.0,
        "accel_misalignment_sigma_mrad": 0.02,
        "accel_quantum_mps": 1e-6,
        "accel_range_g": 25.0,
    },
}
#: Where the preset figures come from (typical values; no preset describes a particular product).
PRESET_SOURCES = (
    "P. D. Groves, Principles of GNSS, Inertial, and Multisensor Integrated Navigation "
    "Systems, 2nd ed., Artech House, 2013, ch. 4 (IMU grades; typical bias, scale-factor, "
    "cross-coupling and noise ranges by grade); N. El-Sheimy, A. Youssef, 'Inertial sensors "
    "technologies for navigation applications: state of the art and future trends', Satellite "
    "Navigation 1:2, 2020, Table 1 (drift, random walk and accelerometer bias by grade); public "
    "datasheets of representative consumer, industrial, tactical and navigation-grade parts. "
    "Quantization and ranges are representative choices."
)


class ImuErrorsError(ValueError):
    """An ``imu_errors`` setting is invalid; ``key`` is its dotted path."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}")


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

    bias: Array
    turn_on_bias_sigma: Array
    bias_instability: Array
    correlation_time_s: Array
    white: Array
    random_walk: Array
    scale_factor: Array
    scale_factor_sigma: Array
    misalignment: Array
    misalignment_sigma: Array
    quantum: Array
    range: Array
    g_sensitivity: Array

    @classmethod
    def zero(cls) -> SensorErrors:
        """A perfect sensor triad (τ_c = 1 s, unused)."""
        z3, z33 = np.zeros(3), np.zeros((3, 3))
        return cls(z3, z3, z3, np.ones(3), z3, z3, z3, z3, z33, z33, z3, z3, z33)

    @property
    def gauss_markov_sigma(self) -> Array:
        """Steady-state deviation ``σ_GM = 0.664 B / 0.6174`` of the Gauss–Markov bias (rate)."""
        return self.bias_instability * (BIAS_INSTABILITY_FACTOR / GAUSS_MARKOV_PEAK)


@dataclass(frozen=True, eq=False)
class ImuErrorParameters:
    """Validated ``imu_errors`` settings: both triads in SI units, the seed, the topics.

    ``input_topic`` / ``output_topic`` are None when not given (the ROS layer chooses).
    """

    gyro: SensorErrors
    accel: SensorErrors
    seed: int = 0
    preset: str | None = None
    input_topic: str | None = None
    output_topic: str | None = None


# ---------------------------------------------------------------------------------------------
# Configuration parsing.


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ImuErrorsError(key, f"must be a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ImuErrorsError(key, f"must be finite, got {value}")
    return value


def _numbers(value: Any, key: str) -> Array:
    """A scalar, a list or a nested list of finite numbers as an array (shape kept)."""
    if isinstance(value, list | tuple):
        items = [
            _numbers(v, f"{key}[{i}]") if isinstance(v, list | tuple) else _number(v, f"{key}[{i}]")
            for i, v in enumerate(value)
        ]
        try:
            return np.array(items, dtype=np.float64)
        except ValueError:
            raise ImuErrorsError(key, f"ragged nested list {value!r}") from None
    return np.array(_number(value, key))


def misalignment_matrix(values: ArrayLike) -> Array:
    """3×3 misalignment matrix of the 6 values ``[xy, xz, yx, yz, zx, zy]`` (zero diagonal)."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (6,):
        raise ValueError(f"expected 6 values, got shape {v.shape}")
    m = np.zeros((3, 3))
    for k, (i, j) in enumerate(_OFF_DIAG):
        m[i, j] = v[k]
    return m


def _shape(value: Any, key: str, kind: str, sign: str) -> Array:
    a = _numbers(value, key)
    if sign == "nonneg" and np.any(a < 0):
        raise ImuErrorsError(key, f"must be >= 0, got {value!r}")
    if sign == "positive" and np.any(a <= 0):
        raise ImuErrorsError(key, f"must be > 0, got {value!r}")
    if kind == "axes":
        if a.shape == ():
            return np.full(3, float(a))
        if a.shape == (3,):
            return a
        raise ImuErrorsError(key, f"must be a number or a list of 3 numbers, got {value!r}")
    if kind in ("misalignment", "sigma6"):
        if a.shape == () and kind == "sigma6":
            return misalignment_matrix(np.full(6, float(a)))
        if a.shape == (6,):
            return misalignment_matrix(a)
        if a.shape == (3, 3):
            if np.any(np.diag(a) != 0):
                raise ImuErrorsError(
                    key, "the diagonal of a 3x3 misalignment must be 0 (it is the scale factor)"
                )
            return a
        scalar = "a number, " if kind == "sigma6" else ""
        raise ImuErrorsError(
            key,
            f"must be {scalar}6 values [xy, xz, yx, yz, zx, zy] or a 3x3 matrix with zero "
            f"diagonal, got {value!r}",
        )
    # "matrix": scalar or 3 values on the diagonal, or a full 3x3
    if a.shape == ():
        return np.diag(np.full(3, float(a)))
    if a.shape == (3,):
        return np.diag(a)
    if a.shape == (3, 3):
        return a
    raise ImuErrorsError(key, f"must be a number, a list of 3 or a 3x3 matrix, got {value!r}")


def parse_imu_errors(
    section: Mapping[str, Any] | None, path: str = "imu_errors"
) -> ImuErrorParameters:
    """Validate an ``imu_errors`` section and convert it to SI units.

    Parameters
    ----------
    section : mapping or None
        The section (keys :data:`IMU_ERROR_KEYS`); None or empty: a perfect IMU.
    path : str
        Dotted path of the section, used in error messages.

    Returns
    -------
    ImuErrorParameters
        Both triads in SI units (rad/s, m/s², rad, s) in FRD sensor axes.

    Raises
    ------
    ImuErrorsError
        Naming the dotted key: unknown key or preset, wrong shape, negative sigma, NaN, ...
    """
    section = {} if section is None else section
    if not isinstance(section, Mapping):
        raise ImuErrorsError(path, f"must be a mapping, got {type(section).__name__}")
    for key in section:
        if key not in IMU_ERROR_KEYS:
            raise ImuErrorsError(
                f"{path}.{key}", f"unknown key; expected one of: {', '.join(IMU_ERROR_KEYS)}"
            )
    preset = section.get("preset")
    if preset is not None and preset not in PRESETS:
        raise ImuErrorsError(
            f"{path}.preset", f"must be one of: {', '.join(PRESETS)}; got {preset!r}"
        )
    seed = section.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ImuErrorsError(f"{path}.seed", f"must be an integer >= 0, got {seed!r}")
    topics = {}
    for key in ("input_topic", "output_topic"):
        value = section.get(key)
        if value is not None and (
            not isinstance(value, str) or not value.startswith("/") or " " in value
        ):
            raise ImuErrorsError(f"{path}.{key}", f"must be an absolute topic name, got {value!r}")
        topics[key] = value
    values = dict(PRESETS[preset]) if preset is not None else {}
    values.update({k: v for k, v in section.items() if k in _SENSOR_KEYS and v is not None})
    fields: dict[str, dict[str, Array]] = {"gyro": {}, "accel": {}}
    for key, value in values.items():
        sensor, name, factor, kind, sign = _SENSOR_KEYS[key]
        full = f"{path}.{key}"
        fields[sensor][name] = _shape(value, full, kind, sign) * factor
    for sensor in ("gyro", "accel"):
        f = fields[sensor]
        if np.any(f.get("bias_instability", np.zeros(3)) > 0) and "correlation_time_s" not in f:
            raise ImuErrorsError(
                f"{path}.{sensor}_correlation_time_s",
                f"is required when {sensor}_bias_instability is > 0",
            )
    return ImuErrorParameters(
        gyro=_triad(fields["gyro"]),
        accel=_triad(fields["accel"]),
        seed=int(seed),
        preset=preset,
        input_topic=topics["input_topic"],
        output_topic=topics["output_topic"],
    )


def _triad(values: dict[str, Array]) -> SensorErrors:
    zero = SensorErrors.zero()
    return SensorErrors(**{k: values.get(k, getattr(zero, k)) for k in zero.__dataclass_fields__})


# ---------------------------------------------------------------------------------------------
# The stateful model.


def _gm_integral_factor(x: Array) -> Array:
    """``h(x) = x - 2(1 - e^{-x}) + (1 - e^{-2x})/2`` (→ x³/3 for small x), x = T/τ_c."""
    e1 = -np.expm1(-x)
    e2 = -np.expm1(-2.0 * x)
    direct = x - 2.0 * e1 + 0.5 * e2
    series = x**3 * (1.0 / 3.0 - x / 4.0 + 7.0 * x**2 / 60.0)
    return np.where(x < 1e-3, series, direct)


class _Triad:
    """One sensor triad's realized constants, discretized noise and carried state."""

    def __init__(self, p: SensorErrors, period_s: float, unit: Array) -> None:
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

    def noise(self, z: Array) -> Array:
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

    def apply(self, ideal: Array, z: Array, dv: Array | None) -> Array:
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
        Validated parameters (:func:`parse_imu_errors`).
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
    def gyro_bias(self) -> Array:
        """Constant gyro bias of this run, fixed plus turn-on (rad/s, FRD)."""
        return self._gyro.bias_T / self.period_s

    @property
    def accel_bias(self) -> Array:
        """Constant accelerometer bias of this run, fixed plus turn-on (m/s², FRD)."""
        return self._accel.bias_T / self.period_s

    @property
    def gyro_error_matrix(self) -> Array:
        """``S + M`` of the gyros in this run (3×3, dimensionless)."""
        return self._gyro.error_matrix.copy()

    @property
    def accel_error_matrix(self) -> Array:
        """``S + M`` of the accelerometers in this run (3×3, dimensionless)."""
        return self._accel.error_matrix.copy()

    def apply(self, dalpha: ArrayLike, dv: ArrayLike) -> tuple[Array, Array]:
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

    def rate_noise_variance(self) -> tuple[Array, Array]:
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
