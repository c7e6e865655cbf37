"""The ``initial`` section: the initial state every trajectory kind but ``samples`` starts from.

Its own module so that the section modules that need it (``trajectory``) take it as an argument
without knowing the scenario model. Keys: docs/scenarios.md.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, field_validator

from strapdown_ros.config.base import Finite, Model, ScenarioError, Vector3

__all__ = ["Initial"]


class Initial(Model):
    """Initial state: geodetic position (WGS-84, ellipsoidal altitude), NED velocity (m/s),
    roll/pitch/heading of the body FRD axes w.r.t. NED (deg)."""

    # ±90° here; the segments and coning kinds need ±89.9° (their latitude integrates
    # 1/cos φ): config.trajectory.check_trajectory.
    latitude_deg: Annotated[Finite, Field(ge=-90.0, le=90.0)]
    longitude_deg: Annotated[Finite, Field(ge=-180.0, le=360.0)]
    altitude_m: Annotated[Finite, Field(ge=-10_000.0, le=1_000_000.0)] = 0.0
    velocity_ned_mps: Vector3 = (0.0, 0.0, 0.0)
    attitude_rph_deg: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("attitude_rph_deg")
    @classmethod
    def _pitch(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if abs(value[1]) >= 90.0:
            raise ScenarioError("[1]", f"pitch must be within ±90°, got {value[1]}")
        return value
