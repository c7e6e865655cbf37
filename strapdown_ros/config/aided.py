"""The ``aided`` section: the reference aided INS (error-state Kalman filter) of a scenario.

:class:`AidedSpec` holds the keys with their limits; :func:`check_aided` the rules that need
the rest of the scenario (the measured IMU of the reference IMU, the aiding sensors enabled,
periods on the IMU grid). The filter: docs/aided.md; its theory: docs/theory/aided_ins.md.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Sequence
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, field_validator

from strapdown_ros.config.base import (
    Model,
    Positive,
    ScenarioError,
    StrictBool,
    StrictInt,
    check_frame_id,
    check_topic_name,
    enabled_section,
    require_period_multiple,
)

__all__ = [
    "AIDED_SENSORS",
    "AidedSpec",
    "InitialSigmaSpec",
    "SENSOR_SOURCE",
    "StatesSpec",
    "TuningSpec",
    "aided_output_keys",
    "aided_spec",
    "check_aided",
]

#: Measurements the filter can use, in canonical order.
AIDED_SENSORS = ("gnss_position", "gnss_velocity", "baro", "mag", "wheel")
#: The ``aiding`` sensor each measurement comes from.
SENSOR_SOURCE = {
    "gnss_position": "gnss",
    "gnss_velocity": "gnss",
    "baro": "barometer",
    "mag": "magnetometer",
    "wheel": "wheel_odometer",
}
#: Output keys other than the per-sensor innovation and NIS topics (topic = prefix + name).
BASE_OUTPUTS = {
    "odom": "odom",
    "fix": "fix",
    "vel": "vel",
    "error_position": "error/position",
    "error_velocity": "error/velocity",
    "error_attitude": "error/attitude",
    "nees": "nees",
    "bias_gyro": "bias/gyro",
    "bias_accel": "bias/accel",
    "bias_gyro_sigma": "bias/gyro_sigma",
    "bias_accel_sigma": "bias/accel_sigma",
}

Axes = tuple[float, float, float]


def _axes(value: Any) -> Any:
    """A number (all three NED axes) or a list of 3, each finite and >= 0."""
    if isinstance(value, list | tuple):
        if len(value) != 3:
            raise ValueError(f"must be a number or a list of 3 numbers, got {value!r}")
        items = list(value)
    else:
        items = [value] * 3
    out = []
    for v in items:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ValueError(f"must be finite numbers, got {value!r}")
        if v < 0:
            raise ValueError(f"must be >= 0, got {value!r}")
        out.append(float(v))
    return tuple(out)


NedSigma = Annotated[Axes, BeforeValidator(_axes)]


def _topic(value: Any) -> Any:
    topic = check_topic_name(value)
    return topic.rstrip("/") or topic


Topic = Annotated[str, BeforeValidator(_topic)]
FrameId = Annotated[str, BeforeValidator(check_frame_id)]


class InitialSigmaSpec(Model):
    """σ of the initial error per NED axis: position (m), velocity (m/s), attitude (deg,
    rotation about north, east, down). 0: start at the truth (the covariance gets a floor)."""

    position_m: NedSigma = (1.0, 1.0, 1.0)
    velocity_mps: NedSigma = (0.1, 0.1, 0.1)
    attitude_deg: NedSigma = (0.05, 0.05, 0.2)


class StatesSpec(Model):
    """Optional states: ``true`` always, ``false`` never, ``null`` (default) when the error model
    has the term."""

    gauss_markov: StrictBool | None = None
    scale_factors: StrictBool | None = None
    sensor_errors: StrictBool | None = None


def _per_sensor(kind: str) -> Any:
    def check(value: Any) -> Any:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise ValueError(f"must be a mapping sensor -> value, got {value!r}")
        out = {}
        for key, v in value.items():
            if key not in AIDED_SENSORS:
                raise ScenarioError(str(key), "unknown sensor; expected one of: "
                                    + ", ".join(AIDED_SENSORS))  # fmt: skip
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ScenarioError(str(key), f"must be a finite number, got {v!r}")
            if kind == "scale" and not v > 0:
                raise ScenarioError(str(key), f"must be > 0, got {v!r}")
            if kind == "sigma" and not v > 0:
                raise ScenarioError(str(key), f"must be > 0, got {v!r}")
            out[key] = float(v)
        return out

    return BeforeValidator(check)


class TuningSpec(Model):
    """Mistuning for tuning studies: ``q_scale`` multiplies every process-noise PSD;
    ``r_scale.<sensor>`` multiplies the measurement covariance taken from the messages;
    ``r_sigma.<sensor>`` replaces it by ``σ² I`` (σ in the measurement's unit: m, m/s, Pa, T,
    m/s)."""

    q_scale: Positive = 1.0
    r_scale: Annotated[dict[str, float], _per_sensor("scale")] = Field(default_factory=dict)
    r_sigma: Annotated[dict[str, float], _per_sensor("sigma")] = Field(default_factory=dict)


class AidedSpec(Model):
    """The ``aided`` section (docs/aided.md).

    ``imu_topic`` None: the output topic of the ``imu_errors`` model measuring
    ``/reference/imu``.
    ``sensors`` None: every measurement of the aiding sensors the scenario enables.
    """

    enabled: StrictBool = True
    imu_topic: Topic | None = None
    truth_topic: Topic = "/reference/odom"
    sensors: list[Literal["gnss_position", "gnss_velocity", "baro", "mag", "wheel"]] | None = None
    wheel_constraints: Literal["both", "lateral", "none"] = "both"
    initial_sigma: InitialSigmaSpec = Field(default_factory=InitialSigmaSpec)
    seed: Annotated[StrictInt, Field(ge=0)] = 0
    output_rate_hz: Annotated[Positive, Field(le=1e6)] = 10.0
    covariance_rate_hz: Annotated[Positive, Field(le=1e6)] = 10.0
    gate_probability: Annotated[float, Field(gt=0.0, le=1.0, strict=True)] = 0.9999
    gravity_steps: Annotated[StrictInt, Field(ge=1, le=100)] = 1
    states: StatesSpec = Field(default_factory=StatesSpec)
    tuning: TuningSpec = Field(default_factory=TuningSpec)
    frame_id: FrameId = "aided"
    topic_prefix: Topic = "/aided"
    topics: dict[str, Topic] = Field(default_factory=dict)

    @field_validator("sensors")
    @classmethod
    def _unique(cls, value: list[str] | None) -> list[str] | None:
        if value is not None and len(set(value)) != len(value):
            raise ValueError(f"a sensor is listed twice: {value!r}")
        return value

    @field_validator("topics", mode="before")
    @classmethod
    def _topic_keys(cls, value: Any) -> Any:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise ValueError(f"must be a mapping output key -> topic, got {value!r}")
        keys = aided_output_keys(AIDED_SENSORS)
        for key in value:
            if key not in keys:
                raise ScenarioError(str(key), "unknown output key; expected one of: "
                                    + ", ".join(keys))  # fmt: skip
        return value

    def period_ns(self, rate_hz: float) -> int:
        """Period (ns) of a rate (Hz)."""
        return int(round(1e9 / rate_hz))

    @property
    def output_period_ns(self) -> int:
        """Output period (ns)."""
        return self.period_ns(self.output_rate_hz)

    @property
    def covariance_period_ns(self) -> int:
        """Covariance propagation period (ns)."""
        return self.period_ns(self.covariance_rate_hz)

    def used_sensors(self, enabled: Collection[str]) -> list[str]:
        """The measurements used, canonical order: ``sensors`` (or every one whose ``aiding``
        sensor is in ``enabled``)."""
        if self.sensors is None:
            return [s for s in AIDED_SENSORS if SENSOR_SOURCE[s] in enabled]
        return [s for s in AIDED_SENSORS if s in self.sensors]

    def output_topics(self, sensors: Iterable[str]) -> dict[str, str]:
        """Output key -> topic name for the measurements ``sensors`` (prefix + name, or
        ``topics``)."""
        keys = aided_output_keys(sensors)
        return {k: self.topics.get(k, f"{self.topic_prefix}/{keys[k]}") for k in keys}

    def resolved_imu_topic(
        self, measured: Sequence[tuple[str, str]], reference: str
    ) -> str | None:
        """``imu_topic``, or the output of the ``imu_errors`` model whose input is ``reference``
        (the reference IMU topic; ``measured``: each model's input and output topics). None:
        no such model."""
        if self.imu_topic is not None:
            return self.imu_topic
        return next((out for source, out in measured if source == reference), None)


def aided_output_keys(sensors: Any) -> dict[str, str]:
    """Output key -> topic name below the prefix, for the measurements ``sensors``."""
    out = dict(BASE_OUTPUTS)
    for s in sensors:
        out[f"innovation_{s}"] = f"innovation/{s}"
        out[f"nis_{s}"] = f"nis/{s}"
    return out


def aided_spec(scenario: Any) -> AidedSpec | None:
    """The scenario's enabled ``aided`` section (None without one or with ``enabled: false``)."""
    return enabled_section(scenario, "aided")


def check_aided(scenario: Any) -> None:
    """Cross-field rules of ``aided`` (called by the scenario's validation with itself).

    They read ``recording.topics``, each ``imu_errors`` model's input and output topics, the
    aiding section and the IMU period of ``scenario``. The IMU topic must be the output of an
    ``imu_errors`` model on the reference IMU (the aiding lever arms are measured from the
    reference IMU); the truth topic the reference Odometry; the sensors used enabled in
    ``aiding``; the output and covariance periods whole multiples of the IMU period; the
    output topics not another stream's.

    Raises
    ------
    ScenarioError
        Naming the key, e.g. ``aided.imu_topic``.
    """
    spec = aided_spec(scenario)
    if spec is None:
        return
    topics = scenario.recording.topics
    measured = scenario.measured_imu_topics()
    aiding = scenario.aiding
    reference = topics["reference_imu"]
    imu = spec.resolved_imu_topic(measured, reference)
    if imu is None:
        raise ScenarioError(
            "aided.imu_topic",
            "no measured IMU: the aided filter runs on the output of an imu_errors model whose "
            f"input is {reference} (add an imu_errors model with input_topic: {reference}, or "
            "remove the aided section: aided=null)",
        )
    source = next((src for src, out in measured if out == imu), None)
    if source != reference:
        what = "" if not measured else " (imu_errors measures " + ", ".join(
            f"{src} into {out}" for src, out in measured) + ")"  # fmt: skip
        raise ScenarioError(
            "aided.imu_topic",
            f"{imu} is not a measured IMU of the reference IMU{what}; the filter runs only on "
            f"the imu_errors output of {reference} for now (the aiding lever arms are measured "
            "from the reference IMU)",
        )
    if spec.truth_topic != topics["reference_odom"]:
        raise ScenarioError(
            "aided.truth_topic",
            f"{spec.truth_topic} is not the reference truth {topics['reference_odom']} (the "
            "filter's errors are those of the reference IMU)",
        )
    enabled = set() if aiding is None else set(aiding.sensors())
    for s in spec.sensors or []:
        if SENSOR_SOURCE[s] not in enabled:
            raise ScenarioError(
                "aided.sensors", f"{s} needs aiding.{SENSOR_SOURCE[s]} (not enabled)"
            )
    for key, rate, what in (
        ("aided.output_rate_hz", spec.output_rate_hz, "output"),
        ("aided.covariance_rate_hz", spec.covariance_rate_hz, "covariance"),
    ):
        require_period_multiple(key, rate, scenario.period_ns, what)
    used = set(topics.values())
    if aiding is not None:
        used |= set(aiding.topics())
    used.add(imu)
    for key, topic in spec.output_topics(spec.used_sensors(enabled)).items():
        if topic in used:
            raise ScenarioError(f"aided.topics.{key}", f"{topic} is another stream's topic")

