"""The ``imu_errors`` section: typed settings of the IMU error model, presets, topic rules.

:class:`ImuErrorsSpec` holds the section in the units of its keys (deg/h, mg, ppm, mrad, ...),
with a preset's values filled in for the keys not given; :meth:`ImuErrorsSpec.parameters`
converts it to the SI :class:`~strapdown_ros.core.imu_errors.ImuErrorParameters` the model
takes. Keys: docs/scenarios.md; the model and the preset figures: docs/theory/imu_errors.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator, field_validator, model_validator

from strapdown_ros.config.base import (
    PresetModel,
    ScenarioError,
    StrictInt,
    check_topic_name,
    finite_number,
    require_correlation_times,
    shorten,
)

if TYPE_CHECKING:  # imported by parameters(): the core model loads scipy.signal
    from strapdown_ros.core.imu_errors import ImuErrorParameters

__all__ = [
    "IMU_ERROR_KEYS",
    "PRESETS",
    "PRESET_SOURCES",
    "SENSOR_KEYS",
    "ImuErrorsSpec",
    "check_imu_errors",
    "imu_errors_key",
    "one_or_list",
]

#: Standard gravity (m/s², the conventional value of CGPM 1901), the ``g`` of the ``mg`` and
#: ``_g`` units; the same constant as :data:`strapdown_ros.core.imu_errors.G0`.
G0 = 9.80665
#: (row, column) of the 6 misalignment values ``[xy, xz, yx, yz, zx, zy]`` in the 3x3 matrix
#: (:func:`strapdown_ros.core.imu_errors.misalignment_matrix` has the same order).
MISALIGNMENT_ORDER = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))

_DEG = math.pi / 180.0
_DPH = _DEG / 3600.0  # deg/h -> rad/s
_DPSH = _DEG / 60.0  # deg/√h -> rad/√s
_MG = G0 * 1e-3  # mg -> m/s²
_SQRT_H = 60.0  # √(3600 s)

#: :class:`~strapdown_ros.core.imu_errors.SensorErrors` field -> the gyro's key and SI factor,
#: the accelerometer's key and SI factor (None: the gyro's only); keys without their triad prefix.
_TRIAD_KEYS: tuple[tuple[str, str, float, str | None, float], ...] = (
    ("bias", "bias_dph", _DPH, "bias_mg", _MG),
    ("turn_on_bias_sigma", "turn_on_bias_sigma_dph", _DPH, "turn_on_bias_sigma_mg", _MG),
    ("bias_instability", "bias_instability_dph", _DPH, "bias_instability_mg", _MG),
    ("correlation_time_s", "correlation_time_s", 1.0, "correlation_time_s", 1.0),
    ("white", "arw_dpsh", _DPSH, "vrw_mpsph", 1.0 / _SQRT_H),
    ("random_walk", "rrw_dphpsh", _DPH / _SQRT_H, "rrw_mgpsh", _MG / _SQRT_H),
    ("scale_factor", "scale_factor_ppm", 1e-6, "scale_factor_ppm", 1e-6),
    ("scale_factor_sigma", "scale_factor_sigma_ppm", 1e-6, "scale_factor_sigma_ppm", 1e-6),
    ("misalignment", "misalignment_mrad", 1e-3, "misalignment_mrad", 1e-3),
    ("misalignment_sigma", "misalignment_sigma_mrad", 1e-3, "misalignment_sigma_mrad", 1e-3),
    ("quantum", "quantum_rad", 1.0, "quantum_mps", 1.0),
    ("range", "range_dps", _DEG, "range_g", G0),
    ("g_sensitivity", "g_sensitivity_dphpg", _DPH / G0, None, 0.0),
)
#: Sensor key -> (triad, :class:`~strapdown_ros.core.imu_errors.SensorErrors` field, SI factor):
#: every gyro key, then every accelerometer key, in the order of ``_TRIAD_KEYS``.
SENSOR_KEYS: dict[str, tuple[str, str, float]] = {
    **{f"gyro_{key}": ("gyro", name, factor) for name, key, factor, _, _ in _TRIAD_KEYS},
    **{
        f"accel_{key}": ("accel", name, factor)
        for name, _, _, key, factor in _TRIAD_KEYS
        if key is not None
    },
}
#: Every key accepted in an ``imu_errors`` section.
IMU_ERROR_KEYS: tuple[str, ...] = ("preset", "seed", "input_topic", "output_topic", *SENSOR_KEYS)

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

# ---------------------------------------------------------------------------------------------
# Value shapes: a number or nested lists of numbers, normalized to 3 values or a 3x3 matrix.

Axes = tuple[float, float, float]
Matrix3 = tuple[Axes, Axes, Axes]
Sign = Literal["any", "nonneg", "positive"]


def _number(value: Any, key: str) -> float:
    try:
        return finite_number(value)
    except ValueError as exc:
        raise ScenarioError(key, str(exc)) from None


def _numbers(value: Any, key: str = "") -> Any:
    """A number or (nested) lists of finite numbers as floats; the key of a bad element."""
    if isinstance(value, list | tuple):
        return [_numbers(v, f"{key}[{i}]") for i, v in enumerate(value)]
    return _number(value, key)


def _array(value: Any, sign: Sign) -> np.ndarray:
    """``value`` checked (numbers, sign) as an array of its shape."""
    numbers = _numbers(value)
    try:
        a = np.array(numbers, dtype=np.float64)
    except ValueError:
        raise ValueError(f"ragged nested list {shorten(value)}") from None
    if sign == "nonneg" and np.any(a < 0):
        raise ValueError(f"must be >= 0, got {shorten(value)}")
    if sign == "positive" and np.any(a <= 0):
        raise ValueError(f"must be > 0, got {shorten(value)}")
    return a


def _misalignment_matrix(values: np.ndarray) -> np.ndarray:
    """The 3x3 misalignment (zero diagonal) of the 6 values ``[xy, xz, yx, yz, zx, zy]``."""
    m = np.zeros((3, 3))
    for k, (i, j) in enumerate(MISALIGNMENT_ORDER):
        m[i, j] = values[k]
    return m


def _matrix(a: np.ndarray) -> Matrix3:
    return tuple(tuple(float(x) for x in row) for row in a)  # type: ignore[return-value]


def _axes(sign: Sign) -> Callable[[Any], Axes | None]:
    """A number (all axes) or a list of 3 (FRD x, y, z)."""

    def convert(value: Any) -> Axes | None:
        if value is None:
            return None
        a = _array(value, sign)
        if a.shape == ():
            return (float(a),) * 3  # type: ignore[return-value]
        if a.shape == (3,):
            return tuple(float(x) for x in a)  # type: ignore[return-value]
        raise ValueError(f"must be a number or a list of 3 numbers, got {shorten(value)}")

    return convert


def _misalignment(scalar: bool, sign: Sign) -> Callable[[Any], Matrix3 | None]:
    """6 values ``[xy, xz, yx, yz, zx, zy]`` or a 3x3 matrix with zero diagonal (or a number
    for all six when ``scalar``)."""

    def convert(value: Any) -> Matrix3 | None:
        if value is None:
            return None
        a = _array(value, sign)
        if a.shape == () and scalar:
            a = np.full(6, float(a))
        if a.shape == (6,):
            return _matrix(_misalignment_matrix(a))
        if a.shape == (3, 3):
            if np.any(np.diag(a) != 0):
                raise ValueError(
                    "the diagonal of a 3x3 misalignment must be 0 (it is the scale factor)"
                )
            return _matrix(a)
        number = "a number, " if scalar else ""
        raise ValueError(
            f"must be {number}6 values [xy, xz, yx, yz, zx, zy] or a 3x3 matrix with zero "
            f"diagonal, got {shorten(value)}"
        )

    return convert


def _full_matrix(value: Any) -> Matrix3 | None:
    """A number or 3 values (the diagonal), or a full 3x3 matrix."""
    if value is None:
        return None
    a = _array(value, "any")
    if a.shape == ():
        return _matrix(np.diag(np.full(3, float(a))))
    if a.shape == (3,):
        return _matrix(np.diag(a))
    if a.shape == (3, 3):
        return _matrix(a)
    raise ValueError(f"must be a number, a list of 3 or a 3x3 matrix, got {shorten(value)}")


#: Per-axis value of any sign, of a value >= 0, of a value > 0.
AxesAny = Annotated[Axes | None, BeforeValidator(_axes("any"))]
AxesNonNeg = Annotated[Axes | None, BeforeValidator(_axes("nonneg"))]
AxesPositive = Annotated[Axes | None, BeforeValidator(_axes("positive"))]
#: Misalignment (6 values or 3x3, zero diagonal) and its 1σ (also a number for all six).
Misalignment = Annotated[Matrix3 | None, BeforeValidator(_misalignment(False, "any"))]
MisalignmentSigma = Annotated[Matrix3 | None, BeforeValidator(_misalignment(True, "nonneg"))]
#: A number or 3 values (diagonal) or a 3x3 matrix.
FullMatrix = Annotated[Matrix3 | None, BeforeValidator(_full_matrix)]


def _topic(value: Any) -> Any:
    return value if value is None else check_topic_name(value)


class ImuErrorsSpec(PresetModel):
    """The ``imu_errors`` section, in the units of its keys, body FRD sensor axes.

    A ``preset`` supplies every sensor key not given (a key given as ``null`` counts as not
    given); the fields hold the resulting values. Per-axis fields are 3 values (x, y, z);
    misalignments and g-sensitivity 3x3 matrices (row: sensor axis, column: body axis). None:
    not set (zero; for a correlation time: unused). ``input_topic`` / ``output_topic`` None:
    the ``recording.topics`` defaults (:meth:`topics`).
    """

    PRESETS = PRESETS  # the module's table, by grade

    preset: Literal["consumer_mems", "industrial", "tactical", "navigation"] | None = None
    seed: StrictInt = 0
    input_topic: Annotated[str | None, BeforeValidator(_topic)] = None
    output_topic: Annotated[str | None, BeforeValidator(_topic)] = None
    # -- gyros (deg/h, deg/√h, ppm, mrad, rad, deg/s) --
    gyro_bias_dph: AxesAny = None
    gyro_turn_on_bias_sigma_dph: AxesNonNeg = None
    gyro_bias_instability_dph: AxesNonNeg = None
    gyro_correlation_time_s: AxesPositive = None
    gyro_arw_dpsh: AxesNonNeg = None
    gyro_rrw_dphpsh: AxesNonNeg = None
    gyro_scale_factor_ppm: AxesAny = None
    gyro_scale_factor_sigma_ppm: AxesNonNeg = None
    gyro_misalignment_mrad: Misalignment = None
    gyro_misalignment_sigma_mrad: MisalignmentSigma = None
    gyro_quantum_rad: AxesNonNeg = None
    gyro_range_dps: AxesNonNeg = None
    gyro_g_sensitivity_dphpg: FullMatrix = None
    # -- accelerometers (mg, m/s/√h, mg/√h, ppm, mrad, m/s, g) --
    accel_bias_mg: AxesAny = None
    accel_turn_on_bias_sigma_mg: AxesNonNeg = None
    accel_bias_instability_mg: AxesNonNeg = None
    accel_correlation_time_s: AxesPositive = None
    accel_vrw_mpsph: AxesNonNeg = None
    accel_rrw_mgpsh: AxesNonNeg = None
    accel_scale_factor_ppm: AxesAny = None
    accel_scale_factor_sigma_ppm: AxesNonNeg = None
    accel_misalignment_mrad: Misalignment = None
    accel_misalignment_sigma_mrad: MisalignmentSigma = None
    accel_quantum_mps: AxesNonNeg = None
    accel_range_g: AxesNonNeg = None

    @field_validator("seed", mode="before")
    @classmethod
    def _seed(cls, value: Any) -> Any:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"must be an integer >= 0, got {shorten(value)}")
        return value

    @model_validator(mode="after")
    def _correlation_times(self) -> ImuErrorsSpec:
        require_correlation_times(
            self,
            (
                ("gyro_bias_instability_dph", "gyro_correlation_time_s"),
                ("accel_bias_instability_mg", "accel_correlation_time_s"),
            ),
        )
        return self

    # -- derived -----------------------------------------------------------------------------

    def parameters(self) -> ImuErrorParameters:
        """The model's parameters: both triads in SI units (rad/s, m/s², rad, s), FRD axes."""
        from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors

        zero = SensorErrors.zero()
        fields: dict[str, dict[str, np.ndarray]] = {"gyro": {}, "accel": {}}
        for key, (sensor, name, factor) in SENSOR_KEYS.items():
            value = getattr(self, key)
            if value is not None:
                fields[sensor][name] = np.array(value, dtype=np.float64) * factor
        gyro, accel = (
            SensorErrors(
                **{k: fields[s].get(k, getattr(zero, k)) for k in zero.__dataclass_fields__}
            )
            for s in ("gyro", "accel")
        )
        return ImuErrorParameters(gyro=gyro, accel=accel, seed=self.seed)

    def topics(self, recording_topics: Mapping[str, str]) -> tuple[str, str]:
        """``(input, output)`` topics: the section's, else ``recording.topics``'
        ``variation_imu`` and ``variation_imu_measured``."""
        return (
            self.input_topic or recording_topics["variation_imu"],
            self.output_topic or recording_topics["variation_imu_measured"],
        )


def generated_imu_topics(topics: Mapping[str, str], variation: bool) -> list[str]:
    """The ideal IMU topics a scenario generates (``topics``: its ``recording.topics``): the
    reference IMU, and the variation ones when it has a ``variation`` section."""
    keys = ["reference_imu"]
    if variation:
        keys += ["variation_imu", "variation_reference_imu"]
    return [topics[k] for k in keys]


def one_or_list(value: Any) -> Any:
    """The ``imu_errors`` value as a list of models: one mapping (one model), a list of them,
    or None / an empty list (none)."""
    if value is None:
        return []
    if isinstance(value, Mapping):
        return [value]
    if not isinstance(value, list | tuple):
        raise ValueError(f"must be a mapping (one model) or a list of them, got {shorten(value)}")
    return value


def imu_errors_key(index: int, count: int) -> str:
    """The key of model ``index`` of ``count``: ``imu_errors`` for a single model (written as
    one mapping or a list of one), ``imu_errors[index]`` in a list of several."""
    return "imu_errors" if count == 1 else f"imu_errors[{index}]"


def check_imu_errors(
    specs: Sequence[ImuErrorsSpec], topics: Mapping[str, str], *, variation: bool
) -> None:
    """Cross-field rules of ``imu_errors`` (called by the scenario's validation with the
    ``recording.topics`` and whether the scenario has a ``variation`` section).

    Per model: ``input_topic`` must be an ideal IMU topic the scenario generates and
    ``output_topic`` must not be another stream's topic. Across models: no two read the same
    input or write the same output.

    Raises
    ------
    ScenarioError
        Naming ``imu_errors.input_topic`` / ``imu_errors.output_topic`` (``imu_errors[i]...``
        in a list of several models).
    """
    generated = generated_imu_topics(topics, variation)
    inputs: dict[str, int] = {}
    outputs: dict[str, int] = {}
    for i, spec in enumerate(specs):
        key = imu_errors_key(i, len(specs))
        input_topic, output_topic = spec.topics(topics)
        if input_topic not in generated:
            raise ScenarioError(
                f"{key}.input_topic",
                f"{input_topic} is not an ideal IMU topic of this scenario "
                f"(generated: {', '.join(generated)})",
            )
        if output_topic in topics.values() and output_topic != topics["variation_imu_measured"]:
            raise ScenarioError(f"{key}.output_topic", f"{output_topic} is another stream's topic")
        for seen, topic, field in ((inputs, input_topic, "input"), (outputs, output_topic,
                                                                     "output")):  # fmt: skip
            if topic in seen:
                raise ScenarioError(
                    f"{key}.{field}_topic",
                    f"{topic} is also the {field} of imu_errors[{seen[topic]}] (each model "
                    f"has its own {field} topic)",
                )
            seen[topic] = i
