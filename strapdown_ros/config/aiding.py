"""The ``aiding`` section: GNSS, barometer, magnetometer and wheel odometer, typed.

Each sensor is a sub-mapping with ``enabled``, ``rate_hz``, a ``seed``, an error ``preset`` and
keys (in the units their names say) that override the preset's; the lever arms are body FRD
from the reference IMU (m). ``*.errors()`` converts a sensor to the SI parameters of its core
model (:mod:`strapdown_ros.core.aiding`). Keys, models and presets: docs/aiding.md.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import BeforeValidator, Field, field_validator, model_validator

from strapdown_ros.config.base import (
    Core,
    Finite,
    Model,
    NonNegative,
    Positive,
    PresetModel,
    ScenarioError,
    StrictBool,
    StrictInt,
    Vector3,
    check_frame_id,
    core_values,
    finite_number,
    require_correlation_times,
    shorten,
)

__all__ = [
    "AIDING_TOPICS",
    "GNSS_PRESETS",
    "BAROMETER_PRESETS",
    "IGRF_YEARS",
    "MAGNETOMETER_PRESETS",
    "WHEEL_ODOMETER_PRESETS",
    "AidingSpec",
    "BarometerSpec",
    "GnssSpec",
    "MagnetometerSpec",
    "WheelOdometerSpec",
    "check_aiding",
    "decimal_year",
]

#: Fixed topic names of the aiding messages, by stream key.
AIDING_TOPICS: dict[str, str] = {
    "gnss_fix": "/gnss/fix",
    "gnss_vel": "/gnss/vel",
    "baro": "/baro/pressure",
    "mag": "/mag",
    "wheel": "/wheel/twist",
}

#: Years covered by the IGRF-14 main-field model (definitive to 2020, predictive to 2030).
IGRF_YEARS = (1900.0, 2030.0)

Axes = tuple[float, float, float]
Matrix3 = tuple[Axes, Axes, Axes]

# ---------------------------------------------------------------------------------------------
# Value shapes


def _axes(sign: str) -> Any:
    """A number (all three axes) or a list of 3; ``sign`` "any", "nonneg" or "positive"."""

    def convert(value: Any) -> Axes | None:
        if value is None:
            return None
        if isinstance(value, list | tuple):
            if len(value) != 3:
                raise ValueError(f"must be a number or a list of 3 numbers, got {shorten(value)}")
            out = tuple(finite_number(v) for v in value)
        else:
            out = (finite_number(value),) * 3
        if sign == "nonneg" and min(out) < 0:
            raise ValueError(f"must be >= 0, got {shorten(value)}")
        if sign == "positive" and min(out) <= 0:
            raise ValueError(f"must be > 0, got {shorten(value)}")
        return out  # type: ignore[return-value]

    return BeforeValidator(convert)


def _matrix(value: Any) -> Matrix3 | None:
    if value is None:
        return None
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise ValueError(f"must be a 3x3 matrix (3 lists of 3 numbers), got {shorten(value)}")
    rows = []
    for row in value:
        if not isinstance(row, list | tuple) or len(row) != 3:
            raise ValueError(f"must be a 3x3 matrix (3 lists of 3 numbers), got {shorten(value)}")
        rows.append(tuple(finite_number(v) for v in row))
    return tuple(rows)  # type: ignore[return-value]


AxesAny = Annotated[Axes | None, _axes("any")]
AxesNonNeg = Annotated[Axes | None, _axes("nonneg")]
AxesPositive = Annotated[Axes | None, _axes("positive")]
Matrix = Annotated[Matrix3 | None, BeforeValidator(_matrix)]
Rate = Annotated[Positive, Field(le=1000.0)]
Seed = Annotated[StrictInt, Field(ge=0)]


def _frame(value: Any) -> Any:
    return value if value is None else check_frame_id(value)


FrameId = Annotated[str | None, BeforeValidator(_frame)]


class _Sensor(PresetModel):
    """Keys every sensor has; ``GM_TERMS``: the ``(sigma_key, tau_key)`` of its Gauss-Markov
    error terms (a σ > 0 needs its correlation time); ``ERROR_MODEL``: ``(module, class)`` of
    its core error model in :mod:`strapdown_ros.core.aiding`, whose parameters the keys
    annotated with :class:`~strapdown_ros.config.base.Core` set."""

    GM_TERMS: ClassVar[tuple[tuple[str, str], ...]] = ()
    ERROR_MODEL: ClassVar[tuple[str, str]]

    enabled: StrictBool = True
    rate_hz: Rate
    seed: Seed = 0

    @field_validator("rate_hz")
    @classmethod
    def _integer_period(cls, rate: float) -> float:
        period = 1e9 / rate
        if abs(period - round(period)) > 1e-6:
            raise ValueError(
                f"the period 1e9/rate_hz = {period!r} ns is not an integer number of ns"
            )
        return rate

    @model_validator(mode="after")
    def _correlation_times(self) -> _Sensor:
        require_correlation_times(self, self.GM_TERMS)
        return self

    @property
    def period_ns(self) -> int:
        """Epoch period P (ns)."""
        return int(round(1e9 / self.rate_hz))

    def errors(self) -> Any:
        """The core model's parameters (SI units; vectors and matrices as arrays): the keys
        annotated with :class:`Core` that are set (by the preset or the sensor's mapping); the
        model's defaults (no error; correlation times 1 s; identity soft iron) for the others."""
        module, name = self.ERROR_MODEL
        # Imported here: the core models load scipy.signal.
        model = getattr(importlib.import_module(f"strapdown_ros.core.aiding.{module}"), name)
        values = core_values(self)
        return model(**{k: np.array(v, dtype=np.float64) if isinstance(v, tuple) else v
                        for k, v in values.items()})  # fmt: skip


# ---------------------------------------------------------------------------------------------
# GNSS

#: ``sensor_msgs/NavSatStatus`` status by name.
GNSS_STATUS = {"fix": 0, "sbas_fix": 1, "gbas_fix": 2}
#: ``sensor_msgs/NavSatStatus`` service bits by constellation.
GNSS_SERVICE = {"gps": 1, "glonass": 2, "beidou": 4, "galileo": 8}

#: GNSS error presets (per NED axis; m, m/s, s). Typical 1σ figures, see docs/aiding.md.
GNSS_PRESETS: dict[str, dict[str, Any]] = {
    "spp": {  # single-point positioning, code only, open sky
        "status": "fix",
        "position_white_m": [0.3, 0.3, 0.6],
        "position_gm_sigma_m": [1.5, 1.5, 3.0],
        "position_gm_tau_s": 300.0,
        "velocity_white_mps": [0.05, 0.05, 0.1],
        "velocity_gm_sigma_mps": [0.01, 0.01, 0.02],
        "velocity_gm_tau_s": 30.0,
    },
    "sbas": {  # SBAS-corrected (WAAS/EGNOS) code positioning
        "status": "sbas_fix",
        "position_white_m": [0.2, 0.2, 0.4],
        "position_gm_sigma_m": [0.6, 0.6, 1.2],
        "position_gm_tau_s": 300.0,
        "velocity_white_mps": [0.05, 0.05, 0.1],
        "velocity_gm_sigma_mps": [0.01, 0.01, 0.02],
        "velocity_gm_tau_s": 30.0,
    },
    "rtk": {  # carrier-phase RTK, fixed ambiguities, short baseline
        "status": "gbas_fix",
        "position_white_m": [0.005, 0.005, 0.01],
        "position_gm_sigma_m": [0.008, 0.008, 0.015],
        "position_gm_tau_s": 60.0,
        "velocity_white_mps": [0.01, 0.01, 0.02],
        "velocity_gm_sigma_mps": [0.0, 0.0, 0.0],
        "velocity_gm_tau_s": 30.0,
    },
}


def _outage(value: Any) -> Any:
    if isinstance(value, list | tuple) and len(value) == 2:
        start, end = (finite_number(v) for v in value)
        if start < 0:
            raise ValueError(f"the start must be >= 0 s, got {shorten(start)}")
        if not end > start:
            raise ValueError(f"[start_s, end_s] needs end_s > start_s, got {shorten(list(value))}")
        return (start, end)
    raise ValueError(f"must be a window [start_s, end_s] (s since the start), got {shorten(value)}")


Outage = Annotated[tuple[float, float], BeforeValidator(_outage)]


class GnssSpec(_Sensor):
    """``aiding.gnss``: antenna position and velocity (NavSatFix, TwistWithCovarianceStamped).

    Errors per local-level NED axis (a number: all three). ``outages``: windows
    ``[start_s, end_s)`` of measurement time (s since the scenario start) without messages.
    ``latency_s``: publication (and bag log) time after the measurement time (the stamp).
    """

    PRESETS = GNSS_PRESETS
    ERROR_MODEL = ("gnss", "GnssErrors")
    GM_TERMS = (
        ("position_gm_sigma_m", "position_gm_tau_s"),
        ("velocity_gm_sigma_mps", "velocity_gm_tau_s"),
    )

    rate_hz: Rate = 1.0
    lever_arm_m: Vector3 = (0.0, 0.0, 0.0)
    preset: Literal["spp", "sbas", "rtk"] | None = None
    latency_s: Annotated[NonNegative, Field(le=10.0)] = 0.0
    outages: list[Outage] = Field(default_factory=list)
    status: Literal["fix", "sbas_fix", "gbas_fix"] | None = None
    constellations: list[Literal["gps", "glonass", "beidou", "galileo"]] = Field(
        default_factory=lambda: ["gps"], min_length=1
    )
    frame_id: FrameId = "gnss"
    position_white_m: Annotated[AxesNonNeg, Core("position_white")] = None
    position_gm_sigma_m: Annotated[AxesNonNeg, Core("position_gm_sigma")] = None
    position_gm_tau_s: Annotated[AxesPositive, Core("position_gm_tau_s")] = None
    position_offset_m: Annotated[AxesAny, Core("position_offset")] = None
    velocity_white_mps: Annotated[AxesNonNeg, Core("velocity_white")] = None
    velocity_gm_sigma_mps: Annotated[AxesNonNeg, Core("velocity_gm_sigma")] = None
    velocity_gm_tau_s: Annotated[AxesPositive, Core("velocity_gm_tau_s")] = None
    velocity_offset_mps: Annotated[AxesAny, Core("velocity_offset")] = None

    @property
    def status_code(self) -> int:
        """``NavSatStatus.status`` (the preset's, else ``fix``)."""
        return GNSS_STATUS[self.status or "fix"]

    @property
    def service_code(self) -> int:
        """``NavSatStatus.service`` bit mask of the constellations."""
        return int(sum(GNSS_SERVICE[c] for c in set(self.constellations)))

    @property
    def latency_ns(self) -> int:
        """``latency_s`` in ns."""
        return int(round(self.latency_s * 1e9))

    def outage_windows_ns(self, start_time_ns: int) -> list[tuple[int, int]]:
        """Outages as absolute ``[start, end)`` stamp windows (ns)."""
        return [
            (start_time_ns + int(round(a * 1e9)), start_time_ns + int(round(b * 1e9)))
            for a, b in self.outages
        ]


# ---------------------------------------------------------------------------------------------
# Barometer

#: Barometer presets (Pa, s). Typical figures, see docs/aiding.md.
BAROMETER_PRESETS: dict[str, dict[str, Any]] = {
    "mems": {  # consumer MEMS pressure sensor (BMP388 / LPS22-class)
        "turn_on_bias_sigma_pa": 50.0,
        "drift_sigma_pa": 20.0,
        "drift_correlation_time_s": 1800.0,
        "noise_sigma_pa": 3.0,
        "quantum_pa": 0.1,
    },
    "precision": {  # resonant / precision digital barometer (air-data grade)
        "turn_on_bias_sigma_pa": 5.0,
        "drift_sigma_pa": 20.0,
        "drift_correlation_time_s": 1800.0,
        "noise_sigma_pa": 0.3,
        "quantum_pa": 0.01,
    },
}


class BarometerSpec(_Sensor):
    """``aiding.barometer``: static pressure (FluidPressure) at the sensor's altitude."""

    PRESETS = BAROMETER_PRESETS
    ERROR_MODEL = ("baro", "BaroErrors")
    GM_TERMS = (("drift_sigma_pa", "drift_correlation_time_s"),)

    rate_hz: Rate = 25.0
    lever_arm_m: Vector3 = (0.0, 0.0, 0.0)
    preset: Literal["mems", "precision"] | None = None
    frame_id: FrameId = "baro"
    bias_pa: Annotated[Finite | None, Core("bias")] = None
    turn_on_bias_sigma_pa: Annotated[NonNegative | None, Core("turn_on_bias_sigma")] = None
    drift_sigma_pa: Annotated[NonNegative | None, Core("drift_sigma")] = None
    drift_correlation_time_s: Annotated[Positive | None, Core("drift_tau_s")] = None
    noise_sigma_pa: Annotated[NonNegative | None, Core("white")] = None
    quantum_pa: Annotated[NonNegative | None, Core("quantum")] = None


# ---------------------------------------------------------------------------------------------
# Magnetometer

#: Magnetometer presets (µT, body FRD). Typical figures, see docs/aiding.md.
MAGNETOMETER_PRESETS: dict[str, dict[str, Any]] = {
    "mems": {  # consumer 3-axis MEMS / AMR magnetometer, after factory calibration
        "hard_iron_sigma_ut": 1.0,
        "noise_sigma_ut": 0.3,
    },
    "fluxgate": {  # navigation fluxgate magnetometer
        "hard_iron_sigma_ut": 0.05,
        "noise_sigma_ut": 0.005,
    },
}


class MagnetometerSpec(_Sensor):
    """``aiding.magnetometer``: body-frame field (MagneticField) from IGRF-14, with errors.

    ``frame_id`` None: the reference IMU's frame (the field is in the IMU body axes).
    ``decimal_year`` None: the year of ``start_time_s`` (held over the run).
    """

    PRESETS = MAGNETOMETER_PRESETS
    ERROR_MODEL = ("magnetometer", "MagnetometerErrors")

    rate_hz: Rate = 50.0
    preset: Literal["mems", "fluxgate"] | None = None
    model: Literal["igrf14"] = "igrf14"
    decimal_year: Annotated[float, Field(ge=IGRF_YEARS[0], le=IGRF_YEARS[1])] | None = None
    frame_id: FrameId = None
    hard_iron_ut: Annotated[AxesAny, Core("hard_iron", 1e-6)] = None
    hard_iron_sigma_ut: Annotated[AxesNonNeg, Core("hard_iron_sigma", 1e-6)] = None
    soft_iron: Annotated[Matrix, Core("soft_iron")] = None
    noise_sigma_ut: Annotated[AxesNonNeg, Core("white", 1e-6)] = None

    @field_validator("decimal_year", mode="before")
    @classmethod
    def _year(cls, value: Any) -> Any:
        return None if value is None else finite_number(value)

    def year(self, start_time_ns: int) -> float:
        """Decimal year the field model is evaluated at."""
        return self.decimal_year if self.decimal_year is not None else decimal_year(start_time_ns)


def decimal_year(stamp_ns: int) -> float:
    """Decimal year (UTC) of a stamp in ns since the Unix epoch, e.g. 2026.0 for 2026-01-01."""
    t = datetime.fromtimestamp(stamp_ns // 1_000_000_000, tz=UTC)
    start = datetime(t.year, 1, 1, tzinfo=UTC)
    end = datetime(t.year + 1, 1, 1, tzinfo=UTC)
    seconds = (t - start).total_seconds() + (stamp_ns % 1_000_000_000) * 1e-9
    return t.year + seconds / (end - start).total_seconds()


# ---------------------------------------------------------------------------------------------
# Wheel odometer

#: Wheel odometer presets. Typical figures, see docs/aiding.md.
WHEEL_ODOMETER_PRESETS: dict[str, dict[str, Any]] = {
    "abs_sensor": {  # ABS wheel-speed sensor: 48-tooth tone ring, both edges, 0.63 m tyre
        "scale_factor_sigma_ppm": 5000.0,
        "noise_sigma_mps": 0.02,
        "pulses_per_m": 48.0,
    },
    "encoder": {  # high-resolution wheel encoder (survey vehicle / robot)
        "scale_factor_sigma_ppm": 1000.0,
        "noise_sigma_mps": 0.005,
        "pulses_per_m": 1000.0,
    },
}


class WheelOdometerSpec(_Sensor):
    """``aiding.wheel_odometer``: contact-point speed along body x (TwistWithCovarianceStamped).

    ``lever_arm_m``: the wheel contact point from the reference IMU (body FRD, m).
    ``nhc_sigma_mps``: the σ the message's covariance gives the lateral and vertical velocity,
    which it reports as 0 (the non-holonomic constraint).
    """

    PRESETS = WHEEL_ODOMETER_PRESETS
    ERROR_MODEL = ("odometer", "OdometerErrors")

    rate_hz: Rate = 50.0
    lever_arm_m: Vector3 = (0.0, 0.0, 0.0)
    preset: Literal["abs_sensor", "encoder"] | None = None
    frame_id: FrameId = "wheel"
    nhc_sigma_mps: Positive = 0.05
    scale_factor_ppm: Annotated[Finite | None, Core("scale_factor", 1e-6)] = None
    scale_factor_sigma_ppm: Annotated[NonNegative | None, Core("scale_factor_sigma", 1e-6)] = None
    noise_sigma_mps: Annotated[NonNegative | None, Core("white")] = None
    pulses_per_m: Annotated[NonNegative | None, Core("pulses_per_m")] = None


# ---------------------------------------------------------------------------------------------
# The section


class AidingSpec(Model):
    """The ``aiding`` section: any of the four sensors (absent or ``enabled: false``: none)."""

    gnss: GnssSpec | None = None
    barometer: BarometerSpec | None = None
    magnetometer: MagnetometerSpec | None = None
    wheel_odometer: WheelOdometerSpec | None = None

    def sensors(self) -> dict[str, _Sensor]:
        """The enabled sensors by key (``gnss``, ``barometer``, ``magnetometer``,
        ``wheel_odometer``)."""
        out: dict[str, _Sensor] = {}
        for key in ("gnss", "barometer", "magnetometer", "wheel_odometer"):
            spec = getattr(self, key)
            if spec is not None and spec.enabled:
                out[key] = spec
        return out

    def topics(self) -> list[str]:
        """The topics the enabled sensors publish, in output order."""
        keys = {
            "gnss": ("gnss_fix", "gnss_vel"),
            "barometer": ("baro",),
            "magnetometer": ("mag",),
            "wheel_odometer": ("wheel",),
        }
        return [AIDING_TOPICS[k] for s in self.sensors() for k in keys[s]]


def check_aiding(
    spec: AidingSpec | None,
    *,
    period_ns: int,
    start_time_s: float,
    start_time_ns: int,
    topics: Mapping[str, str],
) -> None:
    """Cross-field rules of ``aiding`` (called by the scenario's validation with its period T
    ``period_ns``, its start ``start_time_s`` (and in ns) and its ``recording.topics``).

    Every epoch of a sensor (the multiples of its period P on the absolute time grid) must be
    a truth cycle: P a multiple of the scenario's period T and ``start_time_s`` on the grid of
    T; GNSS epochs are whole-second aligned (P divides 1 s); the magnetic model's year within
    IGRF-14's; aiding topics not used by another stream.

    Raises
    ------
    ScenarioError
        Naming the key, e.g. ``aiding.gnss.rate_hz``.
    """
    if spec is None:
        return
    t_ns = period_ns
    t0 = start_time_ns
    for key, sensor in spec.sensors().items():
        p_ns = sensor.period_ns
        if p_ns % t_ns:
            raise ScenarioError(
                f"aiding.{key}.rate_hz",
                f"the epoch period {p_ns} ns is not a multiple of the scenario's period "
                f"T = {t_ns} ns (epochs must be truth cycles)",
            )
        if t0 % t_ns:
            raise ScenarioError(
                f"aiding.{key}.rate_hz",
                f"start_time_s = {start_time_s!r} is not a multiple of T = {t_ns} ns, "
                "so no epoch (a multiple of 1/rate_hz since the Unix epoch) is a truth cycle",
            )
        if key == "gnss" and 1_000_000_000 % p_ns:
            raise ScenarioError(
                "aiding.gnss.rate_hz",
                f"GNSS epochs are whole-second aligned: 1/rate_hz = {p_ns} ns must divide 1 s",
            )
    mag = spec.magnetometer
    if mag is not None and mag.enabled and mag.decimal_year is None:
        year = decimal_year(t0)
        if not IGRF_YEARS[0] <= year <= IGRF_YEARS[1]:
            raise ScenarioError(
                "aiding.magnetometer.decimal_year",
                f"start_time_s gives the year {year:.3f}, outside IGRF-14 "
                f"({IGRF_YEARS[0]:g}-{IGRF_YEARS[1]:g}); set decimal_year",
            )
    used = set(topics.values())
    for topic in spec.topics():
        if topic in used:
            raise ScenarioError("aiding", f"{topic} is also another stream's topic")
