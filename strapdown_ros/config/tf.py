"""The ``tf`` section: TF tree, ``map`` datum and map-frame odometry (docs/interface.md).

Keys (all optional; the section may be absent):

``enabled`` (default true)
    ``/tf_static`` and ``/tf`` in the bag and from the nodes.
``datum`` (default: the scenario's initial position)
    ``{latitude_deg, longitude_deg, altitude_m}`` of the ``map`` origin (ENU tangent plane).
``body_rate_hz`` (default: the truth rate)
    rate of ``map → base_link`` and ``base_link → variation_imu``; must divide ``rate_hz``.
``navigator_rate_hz`` (default: the navigation rate)
    rate of ``map → <navigator frame>``; must divide the navigation rate ``rate_hz / n``.
``map_odometry`` (default true)
    ``nav_msgs/Odometry`` in ``map`` beside each ECEF Odometry topic.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from strapdown_ros.config.base import Finite, Model, Positive, ScenarioError, StrictBool

__all__ = ["DatumSpec", "TFSpec", "check_tf"]


class DatumSpec(Model):
    """Geodetic origin of ``map`` (WGS-84, ellipsoidal altitude); axes east, north, up."""

    latitude_deg: Annotated[Finite, Field(ge=-90.0, le=90.0)]
    longitude_deg: Annotated[Finite, Field(ge=-180.0, le=360.0)]
    altitude_m: Annotated[Finite, Field(ge=-10_000.0, le=1_000_000.0)] = 0.0


class TFSpec(Model):
    """The ``tf`` section (defaults: TF and map odometry on, datum at the initial position)."""

    enabled: StrictBool = True
    datum: DatumSpec | None = None
    body_rate_hz: Positive | None = None
    navigator_rate_hz: Positive | None = None
    map_odometry: StrictBool = True


def _decimation(rate_hz: float, base_period_ns: int, key: str, what: str) -> None:
    period = 1e9 / rate_hz
    ratio = period / base_period_ns
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        raise ScenarioError(
            key,
            f"must divide the {what} ({1e9 / base_period_ns:g} Hz) by a whole number, "
            f"got {rate_hz:g} Hz",
        )


def check_tf(spec: TFSpec, period_ns: int, navigation_period_ns: int | None) -> None:
    """Cross-field rules of ``tf`` (the section or its defaults): the rates divide the truth
    rate (period ``period_ns``) and the navigation rate (period ``navigation_period_ns``, None
    without a navigator)."""
    if spec.body_rate_hz is not None:
        _decimation(spec.body_rate_hz, period_ns, "tf.body_rate_hz", "truth rate")
    if spec.navigator_rate_hz is not None:
        if navigation_period_ns is None:
            raise ScenarioError("tf.navigator_rate_hz", "the scenario has no navigator")
        _decimation(
            spec.navigator_rate_hz,
            navigation_period_ns,
            "tf.navigator_rate_hz",
            "navigation rate",
        )
