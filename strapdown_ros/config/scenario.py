"""Scenario files (SPEC §5): load, apply overrides, validate before any work starts.

A scenario is one YAML file describing a whole run; the offline command and the ROS nodes read
the same file. Every key is checked here: an unknown key, a wrong type, a NaN, an impossible
value is rejected with a :class:`ScenarioError` whose message starts with the dotted key, e.g.
``trajectory.segments[2].duration_s: must be > 0, got -1``. The schema is documented in
``docs/scenarios.md``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "Initial",
    "Recording",
    "Scenario",
    "ScenarioError",
    "apply_overrides",
    "load_scenario",
    "parse_scenario",
]

GRAVITY_MODELS = ("j2", "spherical")
TRAJECTORY_KINDS = ("segments", "samples", "increments", "coning")
STORAGES = ("mcap", "sqlite3")

TOP_LEVEL_KEYS = (
    "name",
    "description",
    "rate_hz",
    "oversample",
    "duration_s",
    "start_time_s",
    "gravity_model",
    "initial",
    "trajectory",
    "variation",
    "navigator",
    "imu_errors",
    "recording",
)
INITIAL_KEYS = (
    "latitude_deg",
    "longitude_deg",
    "altitude_m",
    "velocity_ned_mps",
    "attitude_rph_deg",
)
RECORDING_KEYS = ("storage", "topics", "clock", "frames")

#: Default topic names of SPEC §4, by stream key.
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
}

#: Default frame ids of SPEC §4.
DEFAULT_FRAMES: dict[str, str] = {
    "earth": "earth",
    "reference_imu": "reference_imu",
    "variation_imu": "variation_imu",
}


class ScenarioError(ValueError):
    """A scenario file or override is invalid; ``key`` is the dotted path of the culprit."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}" if key else problem)


# ---------------------------------------------------------------------------------------------
# Small typed readers: each names the key in its error.


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def check_mapping(value: Any, path: str, allowed: Iterable[str]) -> dict[str, Any]:
    """Return ``value`` as a dict after checking it is a mapping with only ``allowed`` keys."""
    if value is None:
        value = {}
    if not isinstance(value, Mapping):
        raise ScenarioError(path, f"must be a mapping, got {type(value).__name__}")
    allowed = tuple(allowed)
    for key in value:
        if not isinstance(key, str):
            raise ScenarioError(path, f"keys must be strings, got {key!r}")
        if key not in allowed:
            raise ScenarioError(
                _join(path, key), f"unknown key; expected one of: {', '.join(allowed)}"
            )
    return dict(value)


def read_number(
    data: Mapping[str, Any],
    key: str,
    path: str,
    *,
    default: float | None = None,
    required: bool = False,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: float | None = None,
) -> float | None:
    """A finite real number at ``data[key]``, with range checks; errors name the key."""
    full = _join(path, key)
    if key not in data or data[key] is None:
        if required:
            raise ScenarioError(full, "is required")
        return default
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(full, f"must be a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ScenarioError(full, f"must be finite, got {value}")
    if minimum is not None and value < minimum:
        raise ScenarioError(full, f"must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ScenarioError(full, f"must be <= {maximum}, got {value}")
    if exclusive_minimum is not None and value <= exclusive_minimum:
        raise ScenarioError(full, f"must be > {exclusive_minimum}, got {value}")
    return value


def read_int(
    data: Mapping[str, Any],
    key: str,
    path: str,
    *,
    default: int | None = None,
    minimum: int | None = None,
) -> int | None:
    """An integer at ``data[key]`` (a float with an integral value is accepted)."""
    full = _join(path, key)
    if key not in data or data[key] is None:
        return default
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(full, f"must be an integer, got {type(value).__name__} {value!r}")
    if isinstance(value, float) and (not math.isfinite(value) or value != int(value)):
        raise ScenarioError(full, f"must be an integer, got {value}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ScenarioError(full, f"must be >= {minimum}, got {value}")
    return value


def read_vector(
    data: Mapping[str, Any],
    key: str,
    path: str,
    *,
    length: int = 3,
    default: Sequence | None = None,
) -> list[float] | None:
    """A list of ``length`` finite numbers at ``data[key]``."""
    full = _join(path, key)
    if key not in data or data[key] is None:
        return None if default is None else [float(x) for x in default]
    value = data[key]
    if not isinstance(value, list | tuple) or len(value) != length:
        raise ScenarioError(full, f"must be a list of {length} numbers, got {value!r}")
    out = []
    for i, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, int | float):
            raise ScenarioError(f"{full}[{i}]", f"must be a number, got {item!r}")
        if not math.isfinite(float(item)):
            raise ScenarioError(f"{full}[{i}]", f"must be finite, got {item}")
        out.append(float(item))
    return out


def read_choice(
    data: Mapping[str, Any], key: str, path: str, choices: Sequence[str], default: str | None
) -> str | None:
    """One of ``choices`` at ``data[key]``."""
    full = _join(path, key)
    if key not in data or data[key] is None:
        if default is None:
            raise ScenarioError(full, f"is required; one of: {', '.join(choices)}")
        return default
    value = data[key]
    if value not in choices:
        raise ScenarioError(full, f"must be one of: {', '.join(choices)}; got {value!r}")
    return str(value)


def read_bool(data: Mapping[str, Any], key: str, path: str, default: bool) -> bool:
    """A boolean at ``data[key]``."""
    if key not in data or data[key] is None:
        return default
    value = data[key]
    if not isinstance(value, bool):
        raise ScenarioError(_join(path, key), f"must be true or false, got {value!r}")
    return value


def _check_finite_tree(value: Any, path: str) -> None:
    """Reject NaN/inf anywhere in the document, naming the key (YAML accepts .nan)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ScenarioError(path, f"must be finite, got {value}")
    if isinstance(value, Mapping):
        for k, v in value.items():
            _check_finite_tree(v, _join(path, str(k)))
    elif isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _check_finite_tree(v, _join(path, i))


# ---------------------------------------------------------------------------------------------
# The validated scenario.


@dataclass(frozen=True)
class Initial:
    """Initial state (SPEC §5): geodetic position, NED velocity, FRD-w.r.t.-NED attitude."""

    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    velocity_ned_mps: tuple[float, float, float]
    attitude_rph_deg: tuple[float, float, float]

    def as_dict(self) -> dict[str, Any]:
        """The scenario-file form (used by the trajectory builders)."""
        return {
            "latitude_deg": self.latitude_deg,
            "longitude_deg": self.longitude_deg,
            "altitude_m": self.altitude_m,
            "velocity_ned_mps": list(self.velocity_ned_mps),
            "attitude_rph_deg": list(self.attitude_rph_deg),
        }


@dataclass(frozen=True)
class Recording:
    """Bag output settings: storage plugin, topic names, frame ids, whether to write /clock."""

    storage: str = "mcap"
    topics: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_TOPICS))
    frames: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_FRAMES))
    clock: bool = False


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. ``raw`` keeps the (override-applied) document for provenance."""

    path: Path | None
    name: str
    rate_hz: float
    oversample: int
    duration_s: float | None
    start_time_ns: int
    gravity_model: str
    initial: Initial | None
    trajectory: dict[str, Any]
    variation: dict[str, Any] | None
    navigator: dict[str, Any] | None
    imu_errors: dict[str, Any] | None
    recording: Recording
    raw: dict[str, Any]

    @property
    def period_ns(self) -> int:
        """Output cycle period T (ns)."""
        return _integer_ns(1e9 / self.rate_hz)

    @property
    def generation_period_ns(self) -> int:
        """Generation cycle period T / oversample (ns)."""
        return self.period_ns // self.oversample

    @property
    def base_dir(self) -> Path:
        """Directory relative paths in the scenario are resolved against."""
        return self.path.parent if self.path is not None else Path.cwd()


def _integer_ns(value: float) -> int:
    return int(round(value))


def _is_integer_ns(value: float) -> bool:
    return abs(value - round(value)) <= 1e-6 * max(1.0, abs(value)) * 1e-3


def _parse_initial(data: Any) -> Initial:
    d = check_mapping(data, "initial", INITIAL_KEYS)
    lat = read_number(d, "latitude_deg", "initial", required=True, minimum=-90.0, maximum=90.0)
    lon = read_number(d, "longitude_deg", "initial", required=True, minimum=-180.0, maximum=360.0)
    alt = read_number(
        d, "altitude_m", "initial", default=0.0, minimum=-10_000.0, maximum=1_000_000.0
    )
    vel = read_vector(d, "velocity_ned_mps", "initial", default=(0.0, 0.0, 0.0))
    att = read_vector(d, "attitude_rph_deg", "initial", default=(0.0, 0.0, 0.0))
    assert lat is not None and lon is not None and alt is not None
    assert vel is not None and att is not None
    if abs(att[1]) >= 90.0:
        raise ScenarioError(
            "initial.attitude_rph_deg[1]", f"pitch must be within ±90°, got {att[1]}"
        )
    return Initial(lat, lon, alt, (vel[0], vel[1], vel[2]), (att[0], att[1], att[2]))


def _parse_recording(data: Any) -> Recording:
    d = check_mapping(data, "recording", RECORDING_KEYS)
    storage = read_choice(d, "storage", "recording", STORAGES, "mcap")
    topics = dict(DEFAULT_TOPICS)
    for key, value in check_mapping(d.get("topics"), "recording.topics", DEFAULT_TOPICS).items():
        if not isinstance(value, str) or not value.startswith("/") or " " in value:
            raise ScenarioError(
                f"recording.topics.{key}", f"must be an absolute topic name, got {value!r}"
            )
        topics[key] = value
    frames = dict(DEFAULT_FRAMES)
    for key, value in check_mapping(d.get("frames"), "recording.frames", DEFAULT_FRAMES).items():
        if not isinstance(value, str) or not value or " " in value:
            raise ScenarioError(f"recording.frames.{key}", f"must be a frame id, got {value!r}")
        frames[key] = value
    clock = read_bool(d, "clock", "recording", False)
    assert storage is not None
    return Recording(storage=storage, topics=topics, frames=frames, clock=clock)


def parse_scenario(document: Any, path: Path | None = None) -> Scenario:
    """Validate a scenario document (already loaded from YAML, overrides applied).

    Raises
    ------
    ScenarioError
        Naming the first offending key and the problem.
    """
    _check_finite_tree(document, "")
    doc = check_mapping(document, "", TOP_LEVEL_KEYS)
    name = doc.get("name", path.stem if path else "scenario")
    if not isinstance(name, str):
        raise ScenarioError("name", f"must be a string, got {name!r}")
    rate = read_number(doc, "rate_hz", "", required=True, exclusive_minimum=0.0, maximum=1e6)
    assert rate is not None
    period = 1e9 / rate
    if not _is_integer_ns(period):
        raise ScenarioError(
            "rate_hz",
            f"the period 1e9/rate_hz = {period!r} ns is not an integer number of nanoseconds "
            "(SPEC §2); choose a rate such as 100, 125, 200, 250, 400, 500 or 1000 Hz",
        )
    oversample = read_int(doc, "oversample", "", default=1, minimum=1)
    assert oversample is not None
    if _integer_ns(period) % oversample:
        raise ScenarioError(
            "oversample",
            f"the generation period T/oversample = {_integer_ns(period)}/{oversample} ns is not "
            "an integer number of nanoseconds",
        )
    duration = read_number(doc, "duration_s", "", exclusive_minimum=0.0)
    start = read_number(doc, "start_time_s", "", default=0.0, minimum=0.0, maximum=4.0e9)
    assert start is not None
    start_ns = _integer_ns(start * 1e9)
    gravity = read_choice(doc, "gravity_model", "", GRAVITY_MODELS, "j2")
    assert gravity is not None
    if "trajectory" not in doc:
        raise ScenarioError("trajectory", "is required")
    trajectory = _parse_trajectory(doc["trajectory"])
    # The samples define the start of a `samples` trajectory; elsewhere `initial` is required.
    if trajectory["kind"] == "samples" and doc.get("initial") is None:
        initial = None
    else:
        initial = _parse_initial(doc.get("initial"))

    def section(key: str) -> dict[str, Any] | None:
        if key not in doc or doc[key] is None:
            return None
        value = doc[key]
        if not isinstance(value, Mapping):
            raise ScenarioError(key, f"must be a mapping, got {type(value).__name__}")
        return dict(value)

    variation = section("variation")
    if variation is not None:
        from strapdown_ros.core.offsets import validate_offsets

        try:
            validate_offsets(variation)
            if variation.get("method", 2) not in (1, 2) or isinstance(
                variation.get("method"), bool
            ):
                raise ValueError(f"variation.method: must be 1 or 2, got {variation['method']!r}")
            if variation.get("gravity", "full") not in ("full", "first_order"):
                raise ValueError(
                    f"variation.gravity: must be full or first_order, got {variation['gravity']!r}"
                )
        except ValueError as exc:
            head, sep, rest = str(exc).partition(": ")
            raise ScenarioError(head if sep else "variation", rest if sep else str(exc)) from None
    imu_errors = section("imu_errors")
    if imu_errors is not None:
        from strapdown_ros.core.imu_errors import ImuErrorsError, parse_imu_errors

        try:
            parse_imu_errors(imu_errors)
        except ImuErrorsError as exc:
            raise ScenarioError(exc.key, exc.problem) from None
    recording = _parse_recording(doc.get("recording"))
    navigator = section("navigator")
    if navigator is not None:
        from strapdown_ros.stages.navigation import parse_navigator

        parse_navigator(
            navigator,
            recording.topics,
            gravity,
            {"variation": variation, "imu_errors": section("imu_errors")},
        )
    return Scenario(
        path=path,
        name=name,
        rate_hz=rate,
        oversample=oversample,
        duration_s=duration,
        start_time_ns=start_ns,
        gravity_model=gravity,
        initial=initial,
        trajectory=trajectory,
        variation=variation,
        navigator=navigator,
        imu_errors=section("imu_errors"),
        recording=recording,
        raw=copy.deepcopy(dict(doc)),
    )


#: Keys accepted under ``trajectory`` for each kind; ``None``: the kind's builder checks them
#: (``samples`` has many fitting options, validated by
#: :meth:`~strapdown_ros.core.trajectory.samples.SamplesTrajectory.from_config`). Values (and
#: the keys inside segments) are validated by the kind modules, which name the key on error.
TRAJECTORY_KEYS: dict[str, tuple[str, ...] | None] = {
    "segments": ("kind", "segments"),
    "increments": ("kind", "segments"),
    "coning": ("kind", "coning"),
    "samples": None,
}


def _parse_trajectory(data: Any) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise ScenarioError("trajectory", f"must be a mapping, got {type(data).__name__}")
    kind = read_choice(data, "kind", "trajectory", TRAJECTORY_KINDS, None)
    assert kind is not None
    keys = TRAJECTORY_KEYS[kind]
    return dict(data) if keys is None else check_mapping(data, "trajectory", keys)


# ---------------------------------------------------------------------------------------------
# Overrides and loading.


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
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ScenarioError(dotted, f"value {text!r} is not valid YAML: {exc}") from exc
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
    if not path.is_file():
        raise ScenarioError("", f"scenario file not found: {path}")
    try:
        document = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ScenarioError("", f"{path} is not valid YAML: {exc}") from exc
    if document is None:
        raise ScenarioError("", f"{path} is empty")
    if not isinstance(document, dict):
        raise ScenarioError("", f"{path}: the top level must be a mapping")
    document = apply_overrides(document, overrides)
    if duration_s is not None:
        document["duration_s"] = duration_s
    return parse_scenario(document, path.resolve())
