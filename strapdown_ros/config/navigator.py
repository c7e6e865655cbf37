"""The ``navigator`` section: which IMU stream the navigator runs on, and how.

:class:`NavigatorSpec` holds every key with its limits; keys whose default depends on the rest
of the scenario (``mode`` on ``algorithm``; ``imu_topic``, ``truth_topic`` on the recording
topics; ``gravity_model`` on the scenario's) are ``None`` until :func:`resolve_navigator` fills
them in. Keys: docs/scenarios.md; the navigator: docs/navigator.md.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Annotated, Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BeforeValidator, Field, field_validator, model_validator

from strapdown_ros.config.base import (
    Model,
    NonNegative,
    NullIsDefault,
    ScenarioError,
    StrictBool,
    StrictInt,
    Vector3,
    check_frame_id,
    check_topic_name,
    is_topic_name,
    shorten,
)

__all__ = [
    "INPUT_STREAMS",
    "OUTPUT_TOPICS",
    "InitialErrors",
    "NavigatorSpec",
    "VerticalDampingSpec",
    "check_navigator",
    "resolve_navigator",
]

#: Input IMU stream key (``recording.topics``) → (its truth Odometry key, section it needs).
INPUT_STREAMS: dict[str, tuple[str, str | None]] = {
    "reference_imu": ("reference_odom", None),
    "variation_imu": ("variation_odom", "variation"),
    "variation_reference_imu": ("variation_reference_odom", "variation"),
    "variation_imu_measured": ("variation_odom", "imu_errors"),
}

#: Navigator output key → ``recording.topics`` key of its topic.
OUTPUT_TOPICS: dict[str, str] = {
    "odom": "navigator_odom",
    "fix": "navigator_fix",
    "error_position": "navigator_error_position",
    "error_velocity": "navigator_error_velocity",
    "error_attitude": "navigator_error_attitude",
}


class InitialErrors(NullIsDefault):
    """Errors added to the initial state: position NED (m) and velocity NED (m/s) in the true
    local level, attitude offsets of roll, pitch and heading (deg)."""

    position_ned_m: Vector3 = (0.0, 0.0, 0.0)
    velocity_ned_mps: Vector3 = (0.0, 0.0, 0.0)
    attitude_rph_deg: Vector3 = (0.0, 0.0, 0.0)


class VerticalDampingSpec(NullIsDefault):
    """Vertical-channel damping gains (paper mode): ``k1`` (1/s), ``k2`` (1/s²), and Table 1's
    printed signs (docs/navigator.md)."""

    k1: NonNegative = 1.0
    k2: NonNegative = 1.0
    paper_signs: StrictBool = False


def _default_mode(algorithm: str) -> str:
    return "exact" if algorithm == "multirate" else "paper"


class NavigatorSpec(Model):
    """The ``navigator`` section (docs/scenarios.md).

    ``mode``, ``imu_topic``, ``truth_topic`` and ``gravity_model`` are None for "the default"
    as written in the file; :func:`resolve_navigator` returns a copy with all four set
    (``truth_topic`` ``""``: no truth topic, hence no error topics).
    """

    algorithm: Literal["multirate", "simultaneous"] = "multirate"
    mode: Literal["paper", "exact"] | None = None
    n: Annotated[StrictInt, Field(ge=1)] = 10
    p: Annotated[StrictInt, Field(ge=1)] = 2
    imu_topic: Annotated[str | None, BeforeValidator(check_topic_name)] = None  # null refused
    truth_topic: str | None = None
    initialization: Literal["truth", "scenario"] = "truth"
    initial_errors: InitialErrors = Field(default_factory=InitialErrors)
    vertical_damping: VerticalDampingSpec | None = None
    gravity_model: Literal["j2", "spherical"] | None = None
    table1_radii: StrictBool = False
    normalize_quaternion: StrictBool = True
    frame_id: Annotated[str, BeforeValidator(check_frame_id)] = "navigator"

    @model_validator(mode="before")
    @classmethod
    def _nulls(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            return data
        keep = ("imu_topic", "frame_id")  # null is no topic / frame id: rejected below
        out = {k: v for k, v in data.items() if v is not None or k in keep}
        if "truth_topic" in data and data["truth_topic"] is None:
            out["truth_topic"] = ""  # null: no truth topic
        return out

    @field_validator("truth_topic", mode="before")
    @classmethod
    def _truth_topic(cls, value: Any) -> Any:
        if value == "" or is_topic_name(value):
            return value
        raise ValueError(f"must be an absolute topic name or empty, got {shorten(value)}")

    @field_validator("vertical_damping", mode="before")
    @classmethod
    def _damping(cls, value: Any) -> Any:
        if value is True:
            return {}
        if value is False:
            return None
        if not isinstance(value, Mapping):
            raise ValueError(f"must be true, false or a mapping, got {shorten(value)}")
        return value

    @model_validator(mode="after")
    def _combinations(self) -> NavigatorSpec:
        mode = self.mode or _default_mode(self.algorithm)
        if self.algorithm == "simultaneous" and mode != "paper":
            raise ScenarioError("mode", "the simultaneous scheme (Table 2) has only 'paper'")
        if self.vertical_damping is not None and mode == "exact":
            raise ScenarioError("vertical_damping", "vertical damping is a 'paper' mode option")
        return self

    # -- derived values (SI) ------------------------------------------------------------------

    @property
    def resolved(self) -> bool:
        """Whether the scenario-dependent defaults are filled in (:func:`resolve_navigator`)."""
        return None not in (self.mode, self.imu_topic, self.truth_topic, self.gravity_model)

    @property
    def position_error_ned(self) -> NDArray[np.float64]:
        """Initial position error, NED of the true position (m)."""
        return np.array(self.initial_errors.position_ned_m)

    @property
    def velocity_error_ned(self) -> NDArray[np.float64]:
        """Initial velocity error, NED (m/s)."""
        return np.array(self.initial_errors.velocity_ned_mps)

    @property
    def attitude_error_rph(self) -> NDArray[np.float64]:
        """Initial roll, pitch, heading offsets (rad)."""
        return np.radians(np.array(self.initial_errors.attitude_rph_deg))

    def _resolve(
        self, topics: Mapping[str, str], gravity_model: str,
        measured: Sequence[tuple[str, str]] = (),
    ) -> NavigatorSpec:  # fmt: skip
        imu = self.imu_topic or topics.get("variation_imu", "/variation/imu")
        key = stream_key(topics, imu, measured)
        default_truth = topics.get(INPUT_STREAMS[key][0], "") if key in INPUT_STREAMS else ""
        truth = default_truth if self.truth_topic is None else self.truth_topic
        if self.initialization == "truth" and not truth:
            raise ScenarioError("navigator.initialization", "'truth' needs a truth_topic")
        if self.initialization == "scenario" and key not in (None, "reference_imu"):
            raise ScenarioError(
                "navigator.initialization",
                "'scenario' initializes from the reference IMU's initial state; use it with "
                f"imu_topic {topics.get('reference_imu', '/reference/imu')!r} or use 'truth'",
            )
        if self.vertical_damping is not None and not truth:
            raise ScenarioError(
                "navigator.vertical_damping",
                "needs a truth_topic (its altitude is the auxiliary altitude)",
            )
        return self.model_copy(
            update={
                "mode": self.mode or _default_mode(self.algorithm),
                "imu_topic": imu,
                "truth_topic": truth,
                "gravity_model": self.gravity_model or gravity_model,
            }
        )


def topic_key(topics: Mapping[str, str], name: str) -> str | None:
    """The ``recording.topics`` key of topic ``name`` (None if it is none of them)."""
    for key, value in topics.items():
        if value == name:
            return key
    return None


def stream_key(
    topics: Mapping[str, str], imu: str, measured: Sequence[tuple[str, str]] = ()
) -> str | None:
    """The :data:`INPUT_STREAMS` key of the IMU topic ``imu``: its ``recording.topics`` key, or,
    for an IMU error model's output (``measured`` = each model's input and output topics,
    whatever their names), ``variation_imu_measured`` when it measures the variation IMU and
    else the key of the ideal IMU it measures. None: not an IMU stream (the error models'
    default output name when no model writes it included)."""
    for source_topic, output in measured:
        if imu == output:
            source = topic_key(topics, source_topic)
            return "variation_imu_measured" if source == "variation_imu" else source
    key = topic_key(topics, imu)
    if measured and key == "variation_imu_measured":
        return None  # the models write other topics: nothing produces this one
    return key


def resolve_navigator(
    spec: NavigatorSpec,
    topics: Mapping[str, str],
    gravity_model: str,
    sections: Collection[str] | None = None,
    measured: Sequence[tuple[str, str]] = (),
) -> NavigatorSpec:
    """``spec`` with its scenario-dependent defaults filled in, checked against the scenario.

    Parameters
    ----------
    spec : NavigatorSpec
        The section as written (or built from node parameters).
    topics : mapping
        ``recording.topics`` (stream key → topic name).
    gravity_model : str
        The default gravitation model (the scenario's).
    sections : collection of str, optional
        The optional parts the scenario has (``Scenario.sections()``: ``initial``,
        ``variation``, ``imu_errors``, ...). Given, the input must be one of the scenario's IMU
        streams (with the section that stream needs) and ``initialization: scenario`` needs
        ``initial``. None: not checked (``navigator_node`` without a scenario).
    measured : sequence of (str, str), optional
        Each IMU error model's input and output topics (``Scenario.measured_imu_topics``): an
        output is an IMU stream whatever its name (truth: that of its input) and the default
        name is none when no model writes it.

    Raises
    ------
    ScenarioError
        Naming the key (``navigator.imu_topic: ...``).
    """
    if sections is not None:
        imu = spec.imu_topic or topics["variation_imu"]
        key = stream_key(topics, imu, measured)
        if key not in INPUT_STREAMS:
            streams = [topics[k] for k in INPUT_STREAMS if k in topics]
            if measured:
                streams = [t for t in streams if stream_key(topics, t, measured)]
                streams += [out for _, out in measured if out not in streams]
            names = ", ".join(streams)
            raise ScenarioError(
                "navigator.imu_topic", f"{shorten(imu)} is not an IMU stream; one of: {names}"
            )
        needs = INPUT_STREAMS[key][1]
        if needs is not None and needs not in sections:
            raise ScenarioError(
                "navigator.imu_topic", f"{shorten(imu)} needs a '{needs}' section in the scenario"
            )
    resolved = spec._resolve(topics, gravity_model, measured)
    if sections is not None and resolved.initialization == "scenario" and "initial" not in sections:
        raise ScenarioError(
            "navigator.initialization", "'scenario' needs the scenario's 'initial' state"
        )
    return resolved


#: Truth Odometry stream key → the section it needs.
TRUTH_STREAMS: dict[str, str | None] = {
    "reference_odom": None,
    "variation_odom": "variation",
    "variation_reference_odom": "variation",
}


def check_navigator(
    spec: NavigatorSpec | None, topics: Mapping[str, str], sections: Collection[str]
) -> None:
    """Cross-field rules of ``navigator`` beyond those of :func:`resolve_navigator` (called by
    the scenario's validation with the resolved section, the recording topics and the
    scenario's sections): the truth topic must be an Odometry stream the scenario produces
    (``generate`` has no other)."""
    if spec is None or not spec.truth_topic:
        return
    key = topic_key(topics, spec.truth_topic)
    if key not in TRUTH_STREAMS:
        names = ", ".join(topics[k] for k in TRUTH_STREAMS)
        raise ScenarioError(
            "navigator.truth_topic",
            f"{shorten(spec.truth_topic)} is not an Odometry stream of the scenario; one of: "
            f"{names} (or empty: none)",
        )
    needs = TRUTH_STREAMS[key]
    if needs is not None and needs not in sections:
        raise ScenarioError(
            "navigator.truth_topic",
            f"{shorten(spec.truth_topic)} needs a '{needs}' section in the scenario",
        )
