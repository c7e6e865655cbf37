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

The aiding sensors' frames (``base_link → <frame_id>`` at their lever arm, in ``/tf_static``)
come from the ``aiding`` section: :func:`sensor_frames`; docs/frames.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import Field

from strapdown_ros.config.base import Finite, Model, Positive, ScenarioError, StrictBool

__all__ = ["DEFAULT_SENSOR_FRAMES", "DatumSpec", "TFSpec", "check_tf", "sensor_frames"]

#: Frame id of each aiding sensor's messages when its ``frame_id`` is not given (the
#: magnetometer's: the reference IMU's frame, ``recording.frames.reference_imu``).
DEFAULT_SENSOR_FRAMES: dict[str, str | None] = {
    "gnss": "gnss",
    "barometer": "baro",
    "magnetometer": None,
    "wheel_odometer": "wheel",
}


def sensor_frames(
    aiding: Any, imu_frame: str
) -> dict[str, tuple[str, tuple[float, float, float]]]:
    """Frame id and lever arm (body FRD, m, from the reference IMU) of each enabled aiding
    sensor of an ``aiding`` section (None: none), by sensor key; the frame id is the one the
    sensor's messages carry (``frame_id``, else :data:`DEFAULT_SENSOR_FRAMES`, the
    magnetometer's ``imu_frame``). The magnetometer has no lever arm (its field does not
    depend on where it sits): zero."""
    if aiding is None:
        return {}
    out: dict[str, tuple[str, tuple[float, float, float]]] = {}
    for key, spec in aiding.sensors().items():
        frame = getattr(spec, "frame_id", None) or DEFAULT_SENSOR_FRAMES[key] or imu_frame
        lever = tuple(float(x) for x in getattr(spec, "lever_arm_m", (0.0, 0.0, 0.0)))
        out[key] = (frame, lever)  # type: ignore[assignment]
    return out


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


def check_tf(
    spec: TFSpec,
    period_ns: int,
    navigation_period_ns: int | None,
    sensors: Mapping[str, tuple[str, tuple[float, float, float]]] | None = None,
    tree_frames: Mapping[str, str] | None = None,
) -> None:
    """Cross-field rules of ``tf`` (the section or its defaults): the rates divide the truth
    rate (period ``period_ns``) and the navigation rate (period ``navigation_period_ns``, None
    without a navigator); with TF on, each aiding sensor's frame (``sensors``:
    :func:`sensor_frames`) is its own, not another sensor's nor a frame of the tree
    (``tree_frames``: ``recording.frames`` by key) — except a sensor without a lever arm in the
    reference IMU's frame, the magnetometer's default."""
    if spec.enabled and sensors:
        tree = dict(tree_frames or {})
        seen: dict[str, str] = {}
        for key, (frame, lever) in sensors.items():
            if frame == tree.get("reference_imu") and not any(lever):
                continue  # in the IMU's own frame: no transform of its own
            if frame in seen or frame in tree.values():
                other = f"aiding.{seen[frame]}" if frame in seen else "a frame of the TF tree"
                raise ScenarioError(
                    f"aiding.{key}.frame_id",
                    f"{frame!r} is already {other}; each sensor with a lever arm needs its own "
                    "frame in /tf_static (docs/frames.md)",
                )
            seen[frame] = key
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
