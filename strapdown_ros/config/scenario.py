"""The scenario model (top level): rates, times, initial state, sections, recording.

One YAML file describes a whole run; ``generate``, ``validate`` and the ROS nodes read it with
:func:`load_scenario`, which returns a validated, frozen :class:`Scenario`. Every check that can
fail before anything is computed lives in the model (field limits here and in the section
models, cross-field rules in :meth:`Scenario._cross_checks`), so every command accepts and
rejects the same files with the same message ``<dotted key>: <problem>``. Keys:
docs/scenarios.md.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BeforeValidator, Field, PrivateAttr, field_validator, model_validator

from strapdown_ros.config.aided import AidedSpec, check_aided
from strapdown_ros.config.aiding import AidingSpec, check_aiding
from strapdown_ros.config.base import (
    Model,
    NonNegative,
    Positive,
    ScenarioError,
    StrictBool,
    StrictInt,
    is_frame_id,
    is_topic_name,
    shorten,
    validate_section,
)
from strapdown_ros.config.imu_errors import ImuErrorsSpec, check_imu_errors, one_or_list
from strapdown_ros.config.initial import Initial
from strapdown_ros.config.navigator import NavigatorSpec, check_navigator, resolve_navigator
from strapdown_ros.config.tf import TFSpec, check_tf, sensor_frames
from strapdown_ros.config.timing import TimingSpec, check_timing
from strapdown_ros.config.trajectory import TrajectorySpec, check_trajectory
from strapdown_ros.config.transfer import TransferAlignmentSpec, check_transfer
from strapdown_ros.config.variation import VariationSpec, check_variation
from strapdown_ros.config.yaml_limits import (
    MAX_BYTES,
    LimitError,
    check_document,
    load_yaml,
    too_large,
)

__all__ = [
    "DEFAULT_FRAMES",
    "DEFAULT_TOPICS",
    "Initial",
    "Recording",
    "Scenario",
    "ScenarioError",
    "apply_overrides",
    "load_scenario",
    "navigator_spec",
    "parse_scenario",
    "tf_spec",
]

GRAVITY_MODELS = ("j2", "spherical")
STORAGES = ("mcap", "sqlite3")

#: Default topic names (docs/interface.md), by stream key.
DEFAULT_TOPICS: dict[str, str] = {
    "reference_imu": "/reference/imu",
    "reference_odom": "/reference/odom",
    "reference_fix": "/reference/fix",
    "variation_imu": "/variation/imu",
    "variation_odom": "/variation/odom",
    "variation_fix": "/variation/fix",
    "variation_reference_imu": "/variation/reference/imu",
    "variation_reference_odom": "/variation/reference/odom",
    "variation_imu_measured": "/variation/imu_measured",
    "navigator_odom": "/navigator/odom",
    "navigator_fix": "/navigator/fix",
    "navigator_error_position": "/navigator/error/position",
    "navigator_error_velocity": "/navigator/error/velocity",
    "navigator_error_attitude": "/navigator/error/attitude",
    "clock": "/clock",
    # TF (docs/interface.md "Frames and TF"); derived topics are named after their source
    # topic: <odom>_map, <imu>_dv, <imu>_dq
    "tf": "/tf",
    "tf_static": "/tf_static",
}

#: Default frame ids.
DEFAULT_FRAMES: dict[str, str] = {
    "earth": "earth",
    "reference_imu": "reference_imu",
    "variation_imu": "variation_imu",
    "map": "map",
    "base_link": "base_link",
}


def _names(value: Any, defaults: Mapping[str, str], what: str) -> dict[str, str]:
    if value is None:
        value = {}
    if not isinstance(value, Mapping):
        raise ValueError(f"must be a mapping, got {type(value).__name__}")
    out = dict(defaults)
    for key, name in value.items():
        if key not in defaults:
            raise ScenarioError(str(key), "unknown key; expected one of: " + ", ".join(defaults))
        if what == "topic" and not is_topic_name(name):
            raise ScenarioError(str(key), f"must be an absolute topic name, got {shorten(name)}")
        if what == "frame" and not is_frame_id(name):
            raise ScenarioError(str(key), f"must be a frame id, got {shorten(name)}")
        out[str(key)] = name
    return out


def _patterns(value: Any) -> list[str] | None:
    """A list of topic patterns (regular expressions matched against whole topic names)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value:
        raise ValueError(f"must be a non-empty list of topic patterns, got {shorten(value)}")
    for i, pattern in enumerate(value):
        if not isinstance(pattern, str) or not pattern:
            raise ScenarioError(str(i), f"must be a topic name or pattern, got {shorten(pattern)}")
        try:
            re.compile(pattern)
        except re.error as exc:
            raise ScenarioError(str(i), f"{pattern!r} is not a regular expression: {exc}") from None
    return list(value)


class Recording(Model):
    """Bag output: storage plugin, MCAP chunk compression, topic names and frame ids by stream
    key, ``/clock``, and which topics are written (``include``/``exclude``: regular
    expressions each matching whole topic names; docs/recording.md)."""

    storage: Literal["mcap", "sqlite3"] = "mcap"
    #: MCAP chunk compression (rosbag2's mcap storage presets compress chunks the same way)
    compression: Literal["none", "zstd", "lz4"] = "none"
    topics: dict[str, str] = Field(default_factory=lambda: dict(DEFAULT_TOPICS))
    frames: dict[str, str] = Field(default_factory=lambda: dict(DEFAULT_FRAMES))
    clock: StrictBool = False
    #: Δv / Δq topics beside each Imu topic (docs/interface.md §4)
    increments: StrictBool = False
    #: topics written: those matching a pattern of ``include`` (None: all) and none of ``exclude``
    include: list[str] | None = None
    exclude: list[str] | None = None

    @field_validator("include", "exclude", mode="before")
    @classmethod
    def _selection(cls, value: Any) -> list[str] | None:
        return _patterns(value)

    @model_validator(mode="after")
    def _compression_storage(self) -> Recording:
        if self.compression != "none" and self.storage != "mcap":
            raise ScenarioError(
                "compression",
                f"{self.compression} chunk compression needs storage mcap, got {self.storage}",
            )
        return self

    @field_validator("topics", mode="before")
    @classmethod
    def _topics(cls, value: Any) -> dict[str, str]:
        return _names(value, DEFAULT_TOPICS, "topic")

    @field_validator("frames", mode="before")
    @classmethod
    def _frames(cls, value: Any) -> dict[str, str]:
        return _names(value, DEFAULT_FRAMES, "frame")


def _is_integer_ns(value: float) -> bool:
    return abs(value - round(value)) <= 1e-6 * max(1.0, abs(value)) * 1e-3


#: the section fields that name a topic of ``recording.topics`` (followed by renames)
_TOPIC_FIELDS: dict[str, tuple[str, ...]] = {
    "navigator": ("imu_topic", "truth_topic"),
    "imu_errors": ("input_topic", "output_topic"),
}


def _renamed(spec: Any, fields: tuple[str, ...], renamed: Mapping[str, str]) -> Any:
    """``spec`` with its topic ``fields`` renamed (``renamed``: old → new name); ``spec``
    itself when none is (or it is None)."""
    if spec is None:
        return None
    moved = {f: renamed[getattr(spec, f)] for f in fields if getattr(spec, f) in renamed}
    return spec.model_copy(update=moved) if moved else spec


class Scenario(Model):
    """A validated scenario (frozen). ``path`` is the file it was read from (if any)."""

    name: str = "scenario"  # default: the file's stem
    description: str | None = None
    rate_hz: Annotated[Positive, Field(le=1e6)]
    oversample: Annotated[StrictInt, Field(ge=1)] = 1
    duration_s: Positive | None = None
    start_time_s: Annotated[NonNegative, Field(le=4.0e9)] = 0.0
    gravity_model: Literal["j2", "spherical"] = "j2"
    initial: Initial | None = None
    # -- sections (each its own model; see config/<section>.py) --------------------------------
    trajectory: TrajectorySpec  # SECTION trajectory
    variation: VariationSpec | None = None  # SECTION variation
    navigator: NavigatorSpec | None = None  # SECTION navigator
    # SECTION imu_errors: one mapping or a list of them (the models; empty: none)
    imu_errors: Annotated[tuple[ImuErrorsSpec, ...], BeforeValidator(one_or_list)] = ()
    tf: TFSpec | None = None  # SECTION tf (config/tf.py): TF, map datum, map odometry
    aiding: AidingSpec | None = None  # SECTION aiding
    timing: TimingSpec | None = None  # SECTION timing (config/timing.py): sensor timing errors
    aided: AidedSpec | None = None  # SECTION aided (config/aided.py): the aided INS
    # SECTION transfer_alignment (config/transfer.py): the variation IMU aided by the reference
    transfer_alignment: TransferAlignmentSpec | None = None
    recording: Recording = Field(default_factory=Recording)

    _path: Path | None = PrivateAttr(default=None)

    # -- derived quantities --------------------------------------------------------------------

    @property
    def path(self) -> Path | None:
        """The scenario file (resolved), None for a scenario built from a mapping."""
        return self._path

    @property
    def base_dir(self) -> Path:
        """Directory relative paths in the scenario are resolved against."""
        return self._path.parent if self._path is not None else Path.cwd()

    @property
    def period_ns(self) -> int:
        """Output cycle period T (ns)."""
        return int(round(1e9 / self.rate_hz))

    @property
    def generation_period_ns(self) -> int:
        """Generation cycle period T / oversample (ns)."""
        return self.period_ns // self.oversample

    @property
    def start_time_ns(self) -> int:
        """Stamp of cycle 0 (ns since the Unix epoch)."""
        return int(round(self.start_time_s * 1e9))

    def with_path(self, path: Path | None) -> Scenario:
        """A copy that remembers the file it came from."""
        copy_ = self.model_copy()
        copy_._path = path
        return copy_

    def with_recording(self, **changes: Any) -> Scenario:
        """A copy with ``recording`` fields replaced (e.g. topics renamed by node parameters).
        A section that names a renamed topic (``navigator.imu_topic``, ``imu_errors.input_topic``
        ...) follows the rename: it names the same stream under its new name."""
        update: dict[str, Any] = {"recording": self.recording.model_copy(update=changes)}
        if "topics" in changes:
            old, new = self.recording.topics, changes["topics"]
            renamed = {old[k]: new[k] for k in old if k in new and new[k] != old[k]}
            for section, fields in _TOPIC_FIELDS.items():
                value = getattr(self, section)
                specs = value if isinstance(value, tuple) else (value,)
                moved_specs = [_renamed(spec, fields, renamed) for spec in specs]
                if any(m is not s for m, s in zip(moved_specs, specs, strict=True)):
                    update[section] = (
                        tuple(moved_specs) if isinstance(value, tuple) else moved_specs[0]
                    )
        return self.model_copy(update=update)

    # -- cross-field rules ---------------------------------------------------------------------

    @field_validator("name", "description", mode="before")
    @classmethod
    def _text(cls, value: Any) -> Any:
        if value is not None and not isinstance(value, str):
            raise ValueError(f"must be a string, got {shorten(value)}")
        return value

    @field_validator("rate_hz")
    @classmethod
    def _integer_period(cls, rate: float) -> float:
        period = 1e9 / rate
        if not _is_integer_ns(period):
            raise ValueError(
                f"the period 1e9/rate_hz = {period!r} ns is not an integer number of "
                "nanoseconds; choose a rate such as 100, 125, 200, 250, 400, 500 or 1000 Hz"
            )
        return rate

    @model_validator(mode="after")
    def _cross_checks(self) -> Scenario:
        if self.period_ns % self.oversample:
            raise ScenarioError(
                "oversample",
                f"the generation period T/oversample = {self.period_ns}/{self.oversample} ns is "
                "not an integer number of nanoseconds",
            )
        topics = self.recording.topics
        check_trajectory(self.trajectory, self.initial, self.generation_period_ns)
        check_imu_errors(self.imu_errors, topics, variation=self.variation is not None)
        check_aiding(
            self.aiding,
            period_ns=self.period_ns,
            start_time_s=self.start_time_s,
            start_time_ns=self.start_time_ns,
            topics=topics,
        )
        check_aided(self)
        check_transfer(self)
        navigator = navigator_spec(self)
        check_navigator(navigator, topics, self.sections())
        check_variation(self.variation, self.rate_hz)
        frames = self.recording.frames
        check_tf(
            tf_spec(self),
            self.period_ns,
            None if navigator is None else self.period_ns * navigator.n,
            sensor_frames(self.aiding, frames["reference_imu"]),
            frames,
        )
        check_timing(self.timing, set(self.aiding.sensors()) if self.aiding is not None else set())
        return self

    def measured_imu_topics(self) -> tuple[tuple[str, str], ...]:
        """``(input, output)`` topics of each IMU error model, in ``imu_errors`` order (empty
        without ``imu_errors``)."""
        return tuple(spec.topics(self.recording.topics) for spec in self.imu_errors)

    def imu_errors_of(self, output_topic: str) -> ImuErrorsSpec | None:
        """The IMU error model writing ``output_topic`` (None: no model writes it)."""
        for spec, (_, output) in zip(self.imu_errors, self.measured_imu_topics(), strict=True):
            if output == output_topic:
                return spec
        return None

    def sections(self) -> frozenset[str]:
        """Names of the optional parts the scenario has (``initial``, ``variation``,
        ``navigator``, ``imu_errors``, ``tf``, ``aiding``): what the cross-section rules of
        :func:`~strapdown_ros.config.navigator.resolve_navigator` ask about."""
        names = ("initial", "variation", "navigator", "imu_errors", "tf", "aiding")
        return frozenset(n for n in names if getattr(self, n) not in (None, ()))


def navigator_spec(scenario: Scenario) -> NavigatorSpec | None:
    """The scenario's ``navigator`` section, resolved (None without one)."""
    if scenario.navigator is None:
        return None
    return resolve_navigator(
        scenario.navigator, scenario.recording.topics, scenario.gravity_model,
        scenario.sections(), scenario.measured_imu_topics(),
    )  # fmt: skip


def tf_spec(scenario: Scenario) -> TFSpec:
    """The scenario's ``tf`` section, defaults when it has none."""
    spec = getattr(scenario, "tf", None)
    return spec if isinstance(spec, TFSpec) else TFSpec()


# ---------------------------------------------------------------------------------------------
# Parsing, overrides and loading.


def parse_scenario(document: Any, path: Path | None = None) -> Scenario:
    """Validate a scenario document (loaded from YAML, overrides applied).

    Raises
    ------
    ScenarioError
        Naming the first offending key and the problem.
    """
    if not isinstance(document, Mapping):
        raise ScenarioError("", f"the top level must be a mapping, got {type(document).__name__}")
    try:
        check_document(document)
    except LimitError as exc:
        raise ScenarioError("", f"the scenario {exc.problem}") from None
    for key in document:
        if not isinstance(key, str):
            raise ScenarioError("", f"keys must be strings, got {shorten(key)}")
    if "trajectory" in document and not isinstance(document["trajectory"], Mapping):
        value = document["trajectory"]
        raise ScenarioError("trajectory", f"must be a mapping, got {type(value).__name__}")
    document = copy.deepcopy(dict(document))
    if document.get("name") is None and path is not None:
        document["name"] = path.stem
    scenario = validate_section(Scenario, document)
    return scenario.with_path(path)  # type: ignore[attr-defined]


def _parse_path(dotted: str) -> list[str | int]:
    parts: list[str | int] = []
    for part in dotted.split("."):
        if not part:
            raise ScenarioError(dotted, "empty component in the dotted key")
        parts.append(int(part) if part.isdigit() else part)
    return parts


def apply_overrides(document: dict[str, Any], overrides: Iterable[str]) -> dict[str, Any]:
    """Apply ``--set dotted.key=value`` overrides (value parsed as YAML) to a copy of a document.

    Components that are integers index lists (``trajectory.segments.2.duration_s=5``).
    """
    doc = copy.deepcopy(document)
    for item in overrides:
        if "=" not in item:
            raise ScenarioError(item, "an override must look like dotted.key=value")
        dotted, text = item.split("=", 1)
        dotted = dotted.strip()
        try:
            value = load_yaml(text)
        except LimitError as exc:
            raise ScenarioError(dotted, f"the value {exc}") from None
        except yaml.YAMLError as exc:
            raise ScenarioError(dotted, f"value {shorten(text)} is not valid YAML: {exc}") from None
        parts = _parse_path(dotted)
        node: Any = doc
        for i, part in enumerate(parts[:-1]):
            where = ".".join(str(p) for p in parts[: i + 1])
            if isinstance(part, int):
                if not isinstance(node, list) or part >= len(node):
                    raise ScenarioError(dotted, f"{where} is not an existing list element")
                node = node[part]
            else:
                if not isinstance(node, dict):
                    raise ScenarioError(dotted, f"{where} is not a mapping")
                node = node.setdefault(part, {})
        last = parts[-1]
        if isinstance(last, int):
            if not isinstance(node, list) or last >= len(node):
                raise ScenarioError(dotted, "no such list element to override")
            node[last] = value
        else:
            if not isinstance(node, dict):
                raise ScenarioError(dotted, "cannot set a key on a non-mapping")
            node[last] = value
    return doc


def read_document(path: Path) -> dict[str, Any]:
    """The YAML mapping of a scenario file; a :class:`ScenarioError` for anything unreadable."""
    if not path.is_file():
        raise ScenarioError("", f"scenario file not found: {path}")
    try:
        with path.open("rb") as file:  # no further than the limit
            data = file.read(MAX_BYTES + 1)
            size = max(len(data), path.stat().st_size)
        if size > MAX_BYTES:
            raise ScenarioError("", f"{path} {too_large(size)}")
        text = data.decode("utf-8")
    except OSError as exc:
        raise ScenarioError("", f"cannot read {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ScenarioError("", f"{path} is not UTF-8 text (a scenario is a YAML file)") from None
    try:
        document = load_yaml(text)
    except LimitError as exc:
        raise ScenarioError("", f"{path} {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError("", f"{path} is not valid YAML{where}: {problem}") from None
    if document is None:
        raise ScenarioError("", f"{path} is empty")
    if not isinstance(document, dict):
        raise ScenarioError("", f"{path}: the top level must be a mapping")
    return document


def load_scenario(
    path: str | Path, overrides: Iterable[str] = (), duration_s: float | None = None
) -> Scenario:
    """Read, override and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        YAML scenario file.
    overrides : iterable of str
        ``dotted.key=value`` strings (values parsed as YAML), applied before validation.
    duration_s : float, optional
        Shortcut for ``--duration``: overrides ``duration_s``.
    """
    path = Path(path)
    document = apply_overrides(read_document(path), overrides)
    if duration_s is not None:
        if not isinstance(duration_s, int | float) or not math.isfinite(duration_s):
            raise ScenarioError("duration_s", f"must be a finite number, got {shorten(duration_s)}")
        document["duration_s"] = duration_s
    return parse_scenario(document, path.resolve())
