"""The ``timing`` section: sensor timing errors, per sensor (docs/timing.md in docs/score.md).

Each sensor key (``imu``, ``gnss``, ``barometer``, ``magnetometer``, ``wheel_odometer``) takes
the same keys (:class:`SensorTiming`); the truth topics are never changed (they stay exact on
their own time base). Stamps: the true measurement time ``t`` (what the stamp would be
without timing errors) becomes

    stamp = t + offset_s + drift_ppm·1e-6 (t − t0) + jitter_s·n,   n ~ N(0, 1) per message,

rounded to the ns; the bag log time (the arrival) is the one without timing errors plus
``latency_s``. ``drops_s`` (measurement times, s since the start) and ``drop_probability``
remove messages; for the IMU ``dropped_increment`` says what becomes of a dropped message's
increment: ``lost`` (the next message is unchanged) or ``accumulated`` (added to the next
message, whose rates are then the means over the longer interval). Draws are seeded per sensor.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from strapdown_ros.config.base import (
    Finite,
    Model,
    NonNegative,
    ScenarioError,
    StrictInt,
)

__all__ = ["SENSORS", "SensorTiming", "TimingSpec", "check_timing"]

#: The sensor keys of ``timing`` and the ``aiding`` sensor each names (None: the IMU).
SENSORS: dict[str, str | None] = {
    "imu": None,
    "gnss": "gnss",
    "barometer": "barometer",
    "magnetometer": "magnetometer",
    "wheel_odometer": "wheel_odometer",
}


class SensorTiming(Model):
    """``timing.<sensor>``: the timing errors of one sensor's messages."""

    offset_s: Annotated[Finite, Field(ge=-10.0, le=10.0)] = 0.0
    drift_ppm: Annotated[Finite, Field(ge=-1e4, le=1e4)] = 0.0
    jitter_s: Annotated[NonNegative, Field(le=1.0)] = 0.0
    latency_s: Annotated[NonNegative, Field(le=10.0)] = 0.0
    drop_probability: Annotated[NonNegative, Field(lt=1.0)] = 0.0
    drops_s: list[Annotated[Finite, Field(ge=0.0)]] = Field(default_factory=list)
    dropped_increment: Literal["lost", "accumulated"] = "lost"
    topic: str | None = None  # imu only: default the IMU error model's output, else reference
    seed: Annotated[StrictInt, Field(ge=0)] = 0

    def ns(self) -> tuple[int, int]:
        """``(offset, latency)`` in ns."""
        return int(round(self.offset_s * 1e9)), int(round(self.latency_s * 1e9))

    @property
    def changes_anything(self) -> bool:
        return bool(self.offset_s or self.drift_ppm or self.jitter_s or self.latency_s
                    or self.drop_probability or self.drops_s)  # fmt: skip


class TimingSpec(Model):
    """The ``timing`` section (absent: no timing errors)."""

    imu: SensorTiming | None = None
    gnss: SensorTiming | None = None
    barometer: SensorTiming | None = None
    magnetometer: SensorTiming | None = None
    wheel_odometer: SensorTiming | None = None

    def sensors(self) -> dict[str, SensorTiming]:
        """The sensors given, by key."""
        return {k: getattr(self, k) for k in SENSORS if getattr(self, k) is not None}


def check_timing(spec: TimingSpec | None, aiding_sensors: set[str]) -> None:
    """Cross-field rule: every aiding sensor timed is one the scenario's ``aiding`` enables.

    Raises ScenarioError ``timing.<sensor>``.
    """
    if spec is None:
        return
    for key, timing in spec.sensors().items():
        sensor = SENSORS[key]
        if sensor is not None and sensor not in aiding_sensors:
            raise ScenarioError(f"timing.{key}", f"the scenario has no aiding.{sensor} sensor")
        if sensor is not None and timing.topic is not None:
            raise ScenarioError(f"timing.{key}.topic", "only timing.imu takes a topic")
