"""The topics a scenario produces (docs/interface.md §4), with their message types.

:func:`produced_topics` is what the recorder records by default and what ``strapdown-sim
generate`` writes for the same scenario: the reference Imu/Odometry/NavSatFix (and ``/clock``
when ``recording.clock`` is true), the variation topics when the scenario has a ``variation``,
``/variation/imu_measured`` (or ``imu_errors.output_topic``) when it has ``imu_errors``, and
the navigator's solution and errors when it has a ``navigator`` (the error topics only when
the navigator has a truth topic to compare with). Names come from the scenario's
``recording.topics``. No rclpy here.
"""

from __future__ import annotations

from strapdown_ros.config import DEFAULT_TOPICS, Scenario

__all__ = ["MSGTYPES", "produced_keys", "produced_topics", "spec_topics"]

IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
CLOCK = "rosgraph_msgs/msg/Clock"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"

#: Message type of every ``recording.topics`` key (docs/interface.md §4).
MSGTYPES: dict[str, str] = {
    "clock": CLOCK,
    "reference_odom": ODOMETRY,
    "reference_fix": NAVSATFIX,
    "reference_imu": IMU,
    "variation_odom": ODOMETRY,
    "variation_fix": NAVSATFIX,
    "variation_imu": IMU,
    "variation_reference_odom": ODOMETRY,
    "variation_reference_imu": IMU,
    "variation_imu_measured": IMU,
    "navigator_odom": ODOMETRY,
    "navigator_fix": NAVSATFIX,
    "navigator_error_position": VECTOR3_STAMPED,
    "navigator_error_velocity": VECTOR3_STAMPED,
    "navigator_error_attitude": VECTOR3_STAMPED,
}

_REFERENCE = ("reference_odom", "reference_fix", "reference_imu")
_VARIATION = (
    "variation_odom",
    "variation_fix",
    "variation_imu",
    "variation_reference_odom",
    "variation_reference_imu",
)
_NAVIGATOR = (
    "navigator_odom",
    "navigator_fix",
    "navigator_error_position",
    "navigator_error_velocity",
    "navigator_error_attitude",
)


def produced_keys(scenario: Scenario) -> list[str]:
    """``recording.topics`` keys of the topics ``scenario`` produces, in ``generate``'s order."""
    keys = ["clock"] if scenario.recording.clock else []
    keys += _REFERENCE
    if scenario.variation is not None:
        keys += _VARIATION
    if scenario.imu_errors is not None:
        keys.append("variation_imu_measured")
    if scenario.navigator is not None:
        keys += _NAVIGATOR if _navigator_has_truth(scenario) else _NAVIGATOR[:2]
    return keys


def _navigator_has_truth(scenario: Scenario) -> bool:
    """Whether the navigator compares with a truth topic (and so publishes its errors)."""
    from strapdown_ros.config.navigator import navigator_spec

    spec = navigator_spec(scenario)
    return spec is not None and bool(spec.truth_topic)


def produced_topics(scenario: Scenario) -> dict[str, str]:
    """Topic name -> message type (``pkg/msg/Name``) of every topic ``scenario`` produces."""
    names = dict(scenario.recording.topics)
    if scenario.imu_errors is not None:  # imu_errors.output_topic may rename the measured IMU
        from strapdown_ros.stages.measurement import imu_model_topics

        names["variation_imu_measured"] = imu_model_topics(scenario)[1]
    out = {names[key]: MSGTYPES[key] for key in produced_keys(scenario)}
    from strapdown_ros.stages.aiding import aiding_topic_types

    out.update(aiding_topic_types(scenario))  # issue 16
    # TF, map-frame odometry and increments derived from them (docs/interface.md)
    from strapdown_ros.stages.frames import derived_topics

    return {**out, **derived_topics(scenario, out)}


def spec_topics() -> dict[str, str]:
    """Every default topic of docs/interface.md §4 -> its message type (``/clock`` first)."""
    return {DEFAULT_TOPICS[key]: msgtype for key, msgtype in MSGTYPES.items()}
