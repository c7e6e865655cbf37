"""The ``transfer_alignment`` section: the variation IMU's INS aided by the reference's state.

:class:`TransferAlignmentSpec` holds the keys with their limits; :func:`check_transfer` the
rules that need the rest of the scenario (a fixed mount or a sweeping platform, the slave IMU
the variation IMU or its ``imu_errors`` output, periods on the IMU grid). The filter and its
equations: docs/transfer_alignment.md.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator

from strapdown_ros.config.base import (
    Model,
    NonNegative,
    Positive,
    ScenarioError,
    StrictBool,
    StrictInt,
    Vector3,
    check_topic_name,
    enabled_section,
    require_period_multiple,
)

__all__ = [
    "TRANSFER_OUTPUTS",
    "MasterErrorSpec",
    "ResolverSpec",
    "TransferAlignmentSpec",
    "TransferTuningSpec",
    "check_transfer",
    "transfer_spec",
]

#: Output key -> topic name below ``topic_prefix``.
TRANSFER_OUTPUTS = {
    "odom": "odom",
    "vel": "vel",
    "error_position": "error/position",
    "error_velocity": "error/velocity",
    "error_attitude": "error/attitude",
    "nees": "nees",
    "mounting": "mounting/estimate",
    "mounting_error": "mounting/error",
    "mounting_sigma": "mounting/sigma",
    "mounting_nees": "mounting/nees",
    "lever_arm_error": "lever_arm/error",
    "nis": "nis",
}


class MasterErrorSpec(Model):
    """Errors of the master (the reference navigation state as the slave receives it).

    Per axis σ: ``velocity_noise_mps`` white noise and ``velocity_bias_mps`` a random-constant
    bias (drawn once per run, NED axes); ``attitude_noise_deg`` and ``attitude_bias_deg`` the
    same on the attitude (rotation about the master's body FRD axes); ``latency_s`` the age of
    the master's output when it is used (a whole number of IMU periods; not compensated by the
    filter). ``seed`` draws the noise and the biases.
    """

    velocity_noise_mps: NonNegative = 0.0
    velocity_bias_mps: NonNegative = 0.0
    attitude_noise_deg: NonNegative = 0.0
    attitude_bias_deg: NonNegative = 0.0
    latency_s: NonNegative = 0.0
    seed: Annotated[StrictInt, Field(ge=0)] = 1


class ResolverSpec(Model):
    """The scan-angle resolver of a scanning platform (simulated inside the stage).

    The slave reads the platform's angle θ (the Appendix-D-smoothed sweep angle the generator
    used) as ``θ̃ = θ + bias_deg + n``: ``bias_deg`` a constant error (a value, not a σ; about
    the scan axis it is indistinguishable from a mounting error, docs/transfer_alignment.md §5),
    ``noise_deg`` the σ of ``n``, white, one independent draw per IMU cycle from ``seed``.
    """

    bias_deg: Annotated[float, Field(strict=True, allow_inf_nan=False, ge=-30.0, le=30.0)] = 0.0
    noise_deg: Annotated[NonNegative, Field(le=10.0)] = 0.0
    seed: Annotated[StrictInt, Field(ge=0)] = 3


class TransferTuningSpec(Model):
    """What the filter is told beyond the master's white noise.

    ``velocity_sigma_mps`` and ``attitude_sigma_deg`` are added (in quadrature) to the
    measurement σ (e.g. for the unmodelled bending motion); ``mounting_random_walk`` is the
    random walk of the mounting states (rad/√s; 0: random constants).
    """

    velocity_sigma_mps: NonNegative = 0.0
    attitude_sigma_deg: NonNegative = 0.0
    mounting_random_walk: NonNegative = 0.0


class TransferAlignmentSpec(Model):
    """The ``transfer_alignment`` section (docs/transfer_alignment.md).

    The slave INS integrates ``imu_topic`` (the variation IMU, normally the ``imu_errors``
    output of it); the master is ``master_topic`` (the reference truth) with the errors of
    ``master``; ``truth_topic`` (the variation truth) is used only for the published errors.
    The slave's nominal mounting is the scenario's ``variation.mounting_rph_deg`` rotated by
    ``mounting_error_deg`` (or, when that is null, by a draw of ``mounting_sigma_deg`` from
    ``seed``); its nominal lever arm is ``variation.lever_arm_m`` plus ``lever_arm_error_m``.
    On a scanning platform (a ``sweep``) the slave reads the scan angle from a ``resolver``.
    """

    enabled: StrictBool = True
    imu_topic: str = "/variation/imu_measured"
    master_topic: str = "/reference/odom"
    truth_topic: str = "/variation/odom"
    rate_hz: Annotated[Positive, Field(le=1e6)] = 10.0
    measurements: list[Literal["velocity", "attitude"]] = Field(
        default_factory=lambda: ["velocity", "attitude"]
    )
    velocity_transport: Literal["central_difference", "rate"] = "central_difference"
    mounting_error_deg: Vector3 | None = (0.5, -0.3, 1.0)
    mounting_sigma_deg: Annotated[Positive, Field(le=30.0)] = 1.0
    lever_arm_state: StrictBool = False
    lever_arm_error_m: Vector3 = (0.0, 0.0, 0.0)
    lever_arm_sigma_m: Positive = 0.1
    initial_sigma_position_m: NonNegative = 0.0
    initial_sigma_velocity_mps: NonNegative = 0.0
    seed: Annotated[StrictInt, Field(ge=0)] = 0
    gate_probability: Annotated[float, Field(gt=0.0, le=1.0, strict=True)] = 1.0
    attitude_jacobian: Literal["measurement", "estimate"] = "measurement"
    master: MasterErrorSpec = Field(default_factory=MasterErrorSpec)
    resolver: ResolverSpec = Field(default_factory=ResolverSpec)
    tuning: TransferTuningSpec = Field(default_factory=TransferTuningSpec)
    frame_id: str = "transfer"
    topic_prefix: str = "/transfer"

    @field_validator("measurements")
    @classmethod
    def _measurements(cls, value: list[str]) -> list[str]:
        if "velocity" not in value:
            raise ValueError(f"must contain velocity (the matching measurement), got {value!r}")
        if len(set(value)) != len(value):
            raise ValueError(f"a measurement is listed twice: {value!r}")
        return value

    @field_validator("imu_topic", "master_topic", "truth_topic", "topic_prefix")
    @classmethod
    def _topic(cls, value: str) -> str:
        topic = check_topic_name(value)
        return topic.rstrip("/") or topic

    @property
    def period_ns(self) -> int:
        """Measurement, covariance and output period (ns)."""
        return int(round(1e9 / self.rate_hz))

    def output_topics(self) -> dict[str, str]:
        """Output key -> topic (the lever-arm error only with the lever-arm states)."""
        keys = dict(TRANSFER_OUTPUTS)
        if not self.lever_arm_state:
            del keys["lever_arm_error"]
        return {k: f"{self.topic_prefix}/{v}" for k, v in keys.items()}


def transfer_spec(scenario: Any) -> TransferAlignmentSpec | None:
    """The scenario's enabled ``transfer_alignment`` section (None without one or disabled)."""
    return enabled_section(scenario, "transfer_alignment")


def _check_platform(key: str, spec: TransferAlignmentSpec, variation: Any) -> None:
    """On a platform (a scan or a displacement) the scan must be a sweep (one angle about a
    fixed axis: what the resolver reads) and the velocity transport the central difference;
    resolver errors need a scan."""
    scan = variation.scan
    if scan is None and (spec.resolver.bias_deg != 0.0 or spec.resolver.noise_deg != 0.0):
        raise ScenarioError(f"{key}.resolver", "resolver errors need a scanning platform "
                            "(variation.scan) to read")  # fmt: skip
    if scan is None and not any(v != 0.0 for v in variation.displacement_m):
        return
    if scan is not None and scan.kind != "sweep":
        raise ScenarioError(
            f"{key}", f"variation.scan kind {scan.kind!r} is not supported: the slave's resolver "
            "reads one angle about a fixed axis (kind: sweep)",
        )  # fmt: skip
    if spec.velocity_transport != "central_difference":
        raise ScenarioError(
            f"{key}.velocity_transport", "a platform (variation.scan or displacement_m) needs "
            "central_difference (the carried offset turns with the scan and the mounting "
            "estimate: eq. (10) on the whole offset)",
        )  # fmt: skip


def check_transfer(scenario: Any) -> None:
    """Cross-field rules of ``transfer_alignment`` (called by the scenario's validation with
    itself).

    They read ``recording.topics``, each ``imu_errors`` model's input and output topics, the
    variation section and the IMU period of ``scenario``.

    Raises
    ------
    ScenarioError
        Naming the key, e.g. ``transfer_alignment.imu_topic``.
    """
    key = "transfer_alignment"
    spec = transfer_spec(scenario)
    if spec is None:
        return
    topics = scenario.recording.topics
    variation = scenario.variation
    period_ns = scenario.period_ns
    if variation is None:
        raise ScenarioError(key, "needs a variation section (the slave IMU is the variation IMU)")
    _check_platform(key, spec, variation)
    if variation.method != 2:
        raise ScenarioError(f"{key}", "needs variation.method: 2 (velocity constraint (10))")
    slave = topics["variation_imu"]
    allowed = {slave}
    allowed |= {out for source, out in scenario.measured_imu_topics() if source == slave}
    if spec.imu_topic not in allowed:
        raise ScenarioError(
            f"{key}.imu_topic", f"{spec.imu_topic} is neither the variation IMU {slave} nor "
            f"its imu_errors output ({' or '.join(sorted(allowed))} here)",
        )  # fmt: skip
    if spec.master_topic != topics["reference_odom"]:
        raise ScenarioError(f"{key}.master_topic",
                            f"must be the reference truth {topics['reference_odom']}")  # fmt: skip
    if spec.truth_topic != topics["variation_odom"]:
        raise ScenarioError(f"{key}.truth_topic",
                            f"must be the variation truth {topics['variation_odom']}")  # fmt: skip
    period = require_period_multiple(f"{key}.rate_hz", spec.rate_hz, period_ns)
    if spec.velocity_transport == "central_difference" and (period // period_ns) % 2:
        raise ScenarioError(
            f"{key}.rate_hz", "central_difference needs an even number of IMU cycles per "
            "measurement (Method 2 meets the velocity constraint at even cycles)",
        )  # fmt: skip
    lat = spec.master.latency_s * 1e9
    if abs(lat - round(lat / period_ns) * period_ns) > 1e-3:
        raise ScenarioError(f"{key}.master.latency_s",
                            f"must be a whole number of IMU periods ({period_ns} ns)")
    used = set(topics.values())
    for k, topic in spec.output_topics().items():
        if topic in used:
            raise ScenarioError(f"{key}.topic_prefix", f"{topic} ({k}) is another stream's topic")
