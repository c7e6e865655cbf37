"""The ``trajectory`` section: one typed model per ``kind`` (segments, increments, coning, samples).

:data:`TrajectorySpec` is a union tagged by ``kind``. Each spec holds its keys in the units the
file uses (deg, deg/s, ...) and converts them to the SI arguments of its core model
(:mod:`strapdown_ros.core.trajectory`): ``build`` for segments and coning, ``core_segments``
for increments, ``fit_options`` for samples (whose samples are read by
:mod:`strapdown_ros.stages.trajectory`). :func:`check_trajectory` holds the rules that need the
rest of the scenario (``initial``, the generation period). Problems only found while building
(a segment decelerating past standstill, knots the samples cannot support) come back from the
core as :class:`~strapdown_ros.core.trajectory.base.TrajectoryError`; :meth:`key_of` of each
spec names the scenario key for them. Keys: docs/scenarios.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import BeforeValidator, Field, PlainValidator, field_validator, model_validator

from strapdown_ros.config.base import (
    Core,
    Finite,
    Model,
    NonNegative,
    Positive,
    ScenarioError,
    Vector3,
    core_keys,
    core_values,
    finite_number,
    join_key,
    shorten,
)
from strapdown_ros.config.initial import Initial
from strapdown_ros.core.trajectory.base import TrajectoryError
from strapdown_ros.core.trajectory.coning import (
    AMPLITUDE_DEFAULT,
    DURATION_DEFAULT,
    PERIOD_DEFAULT,
    PRECESSION_RATE_DEFAULT,
    THETA_DEFAULT,
    ConingTrajectory,
    lowest_altitude,
)
from strapdown_ros.core.trajectory.increments import IncrementSegment, whole_cycles
from strapdown_ros.core.trajectory.segments import (
    ALTITUDE_MIN,
    LATITUDE_LIMIT,
    PITCH_LIMIT,
    Segment,
    SegmentsTrajectory,
)

if TYPE_CHECKING:  # imported by fit_options(): the spline fit loads numba
    from strapdown_ros.core.trajectory.samples import FitOptions

__all__ = [
    "KINDS",
    "ConingSpec",
    "ConingTrajectorySpec",
    "IncrementSegmentSpec",
    "IncrementsTrajectorySpec",
    "PerFit",
    "SamplesTrajectorySpec",
    "SegmentSpec",
    "SegmentsTrajectorySpec",
    "TrajectorySpec",
    "WeightsSpec",
    "MAX_DURATION_S",
    "check_trajectory",
    "core_initial",
]

KINDS = ("segments", "samples", "increments", "coning")
#: Longest trajectory (s, about 116 days) of the kinds whose section gives its length
#: (segments, increments, coning). The segments and coning models solve latitude and longitude
#: over the whole path at once, in memory and time proportional to its length (1e7 s of
#: straight flight: about 2 GB and half a minute); a longer path is refused before any of it.
MAX_DURATION_S = 1.0e7
FITS = ("position", "attitude")
#: rad per degree: ``math.radians(x)`` is ``x * _DEG`` (CPython multiplies by pi/180).
_DEG = math.pi / 180.0


def _not_null(value: Any) -> Any:
    """Optional keys may be left out, not set to null (the old readers' rule)."""
    if value is None:
        raise ValueError("must be a number, got None (leave the key out for the default)")
    return value


class _SegmentList(Model):
    """A trajectory of consecutive segments (a subclass types ``segments`` and names the
    scenario key of each core segment field in ``CORE_KEYS``)."""

    CORE_KEYS: ClassVar[Mapping[str, str]] = {}

    @field_validator("segments", check_fields=False)
    @classmethod
    def _non_empty(cls, value: list[Any]) -> list[Any]:
        if not value:
            raise ValueError("must be a non-empty list of segments")
        return value

    @property
    def natural_duration(self) -> float:
        """Sum of the segment durations (s)."""
        return float(sum(s.duration_s for s in self.segments))  # type: ignore[attr-defined]

    def key_of(self, where: tuple[str | int, ...]) -> str:
        """Scenario key of a core :class:`TrajectoryError` location."""
        initial = _initial_key(where)
        if initial is not None:
            return initial
        key = "trajectory"
        for part in where:
            key = join_key(key, self.CORE_KEYS.get(part, part) if isinstance(part, str) else part)
        return key


def core_initial(initial: Initial) -> tuple[float, float, float, np.ndarray, np.ndarray]:
    """``initial`` as the core models take it: ``lat, lon`` (rad), ``alt`` (m), ``v_ned``
    (NED, m/s), ``rph`` (roll, pitch, heading of FRD w.r.t. NED, rad)."""
    return (
        math.radians(initial.latitude_deg),
        math.radians(initial.longitude_deg),
        float(initial.altitude_m),
        np.array(initial.velocity_ned_mps, dtype=np.float64),
        np.radians(np.array(initial.attitude_rph_deg, dtype=np.float64)),
    )


def _initial_key(where: tuple[str | int, ...]) -> str | None:
    """Scenario key of a core error about the initial-state arguments, if it is one."""
    head = where[0] if where else None
    if head == "lat":
        return "initial.latitude_deg"
    if head == "lon":
        return "initial.longitude_deg"
    if head == "alt":
        return "initial.altitude_m"
    if head == "v_ned":
        return "initial.velocity_ned_mps" + "".join(f"[{i}]" for i in where[1:])
    if head == "rph":
        return "initial.attitude_rph_deg" + "".join(f"[{i}]" for i in where[1:])
    return None


# ---------------------------------------------------------------------------------------------
# segments


class SegmentSpec(Model):
    """One maneuver segment (``trajectory.segments[i]`` of kind ``segments``).

    Euler-angle rates of FRD w.r.t. NED (deg/s), along-track acceleration (m/s²), target climb
    rate up (m/s) or a NED acceleration (m/s²) instead of the two, blend length (s).
    """

    duration_s: Annotated[Positive, Core("duration")]
    roll_rate_dps: Annotated[Finite, Core("roll_rate", _DEG)] = 0.0
    pitch_rate_dps: Annotated[Finite, Core("pitch_rate", _DEG)] = 0.0
    heading_rate_dps: Annotated[Finite, Core("heading_rate", _DEG)] = 0.0
    accel_mps2: Annotated[Finite | None, Core("accel")] = None
    climb_rate_mps: Annotated[Finite | None, Core("climb_rate")] = None
    accel_ned_mps2: Annotated[Vector3 | None, Core("accel_ned")] = None
    # default min(1, duration_s / 2)
    transition_s: Annotated[NonNegative | None, Core("transition")] = None

    _null = field_validator(
        "accel_mps2", "climb_rate_mps", "accel_ned_mps2", "transition_s", mode="before"
    )(_not_null)

    @model_validator(mode="after")
    def _combinations(self) -> SegmentSpec:
        if self.accel_ned_mps2 is not None:
            for other in ("accel_mps2", "climb_rate_mps"):
                if getattr(self, other) is not None:
                    raise ScenarioError(
                        "accel_ned_mps2", f"cannot be combined with {other} in one segment"
                    )
        if self.transition_s is not None and self.transition_s > self.duration_s:
            raise ScenarioError(
                "transition_s",
                f"must be in [0, duration_s = {self.duration_s}], got {self.transition_s}",
            )
        return self

    def core_segment(self) -> Segment:
        """The segment in SI units (rad/s)."""
        return Segment(**core_values(self))


class SegmentsTrajectorySpec(_SegmentList):
    """``kind: segments``: maneuver segments in navigation terms from ``initial``."""

    CORE_KEYS = core_keys(SegmentSpec)

    kind: Literal["segments"]
    segments: list[SegmentSpec]

    def build(self, initial: Initial) -> SegmentsTrajectory:
        """The core model from ``initial``.

        Raises
        ------
        ScenarioError
            For an impossible trajectory, naming the segment's key (e.g.
            ``trajectory.segments[2].accel_mps2``).
        """
        segments = [s.core_segment() for s in self.segments]
        try:
            return SegmentsTrajectory(*core_initial(initial), segments)
        except TrajectoryError as exc:
            raise ScenarioError(self.key_of(exc.where), exc.problem) from None


# ---------------------------------------------------------------------------------------------
# increments


class IncrementSegmentSpec(Model):
    """One constant-rate segment (``kind: increments``): ``ω_ib^B`` (deg/s), ``f^B`` (m/s²)."""

    duration_s: Positive
    omega_dps: Vector3 = (0.0, 0.0, 0.0)
    specific_force_mps2: Vector3 = (0.0, 0.0, 0.0)

    def core_segment(self) -> IncrementSegment:
        """The segment in SI units (rad/s)."""
        omega = np.radians(np.array(self.omega_dps, dtype=np.float64))
        return IncrementSegment(
            duration=self.duration_s,
            omega=(float(omega[0]), float(omega[1]), float(omega[2])),
            specific_force=self.specific_force_mps2,
        )


class IncrementsTrajectorySpec(_SegmentList):
    """``kind: increments``: Savage's constant body rate / specific force segments."""

    CORE_KEYS = {"duration": "duration_s"}

    kind: Literal["increments"]
    segments: list[IncrementSegmentSpec]

    def core_segments(self) -> list[IncrementSegment]:
        """The segments in SI units."""
        return [s.core_segment() for s in self.segments]


# ---------------------------------------------------------------------------------------------
# coning


class ConingSpec(Model):
    """``trajectory.coning``: Waldmann §6 cone half-angle, precession rate, CM motion."""

    theta_rad: Finite | None = None
    theta_deg: Finite | None = None
    precession_rate_radps: Finite | None = None
    precession_rate_dps: Finite | None = None
    cm_motion: Literal["rest", "sinusoids"] = "rest"
    velocity_amplitude_ned_mps: Vector3 = AMPLITUDE_DEFAULT
    velocity_period_ned_s: Vector3 = PERIOD_DEFAULT
    duration_s: Positive = DURATION_DEFAULT

    _null = field_validator(
        "theta_rad", "theta_deg", "precession_rate_radps", "precession_rate_dps", mode="before"
    )(_not_null)

    @field_validator("velocity_period_ned_s")
    @classmethod
    def _periods(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        for i, p in enumerate(value):
            if p <= 0.0:
                raise ScenarioError(f"[{i}]", f"must be > 0, got {p}")
        return value

    @model_validator(mode="after")
    def _choices(self) -> ConingSpec:
        for a, b in (("theta_rad", "theta_deg"), ("precession_rate_radps", "precession_rate_dps")):
            if getattr(self, a) is not None and getattr(self, b) is not None:
                raise ScenarioError(b, f"give either {a} or {b}, not both")
        if not 0.0 <= self.theta <= math.pi:
            key = "theta_rad" if self.theta_rad is not None else "theta_deg"
            raise ScenarioError(key, f"the cone half-angle must be in [0, π] rad, got {self.theta}")
        return self

    @property
    def theta(self) -> float:
        """Cone half-angle θ (rad)."""
        return _in_radians(self.theta_rad, self.theta_deg, THETA_DEFAULT)

    @property
    def precession_rate(self) -> float:
        """Precession rate Ω_p (rad/s)."""
        return _in_radians(
            self.precession_rate_radps, self.precession_rate_dps, PRECESSION_RATE_DEFAULT
        )


def _in_radians(radians: float | None, degrees: float | None, default: float) -> float:
    """An angle (or a rate) given in radians or in degrees (one of them; neither: the default)."""
    if radians is not None:
        return radians
    if degrees is not None:
        return math.radians(degrees)
    return default


def _null_is_empty(value: Any) -> Any:
    return {} if value is None else value


class ConingTrajectorySpec(Model):
    """``kind: coning``: Waldmann §6 coning about the local vertical, CM at rest or moving."""

    kind: Literal["coning"]
    coning: Annotated[ConingSpec, BeforeValidator(_null_is_empty)] = Field(
        default_factory=ConingSpec
    )

    @property
    def natural_duration(self) -> float:
        """``coning.duration_s`` (s)."""
        return float(self.coning.duration_s)

    def key_of(self, where: tuple[str | int, ...]) -> str:
        """Scenario key of a core error location (core argument names map to keys)."""
        initial = _initial_key(where)
        if initial is not None:
            return initial
        return "trajectory.coning"

    def build(self, initial: Initial) -> ConingTrajectory:
        """The core model from ``initial`` (position, ``C_0`` from ``attitude_rph_deg``)."""
        c = self.coning
        lat, lon, alt, _, rph = core_initial(initial)
        try:
            return ConingTrajectory(
                lat,
                lon,
                alt,
                c.theta,
                c.precession_rate,
                c.duration_s,
                c.cm_motion,
                np.array(c.velocity_amplitude_ned_mps, dtype=np.float64),
                np.array(c.velocity_period_ned_s, dtype=np.float64),
                rph,
            )
        except TrajectoryError as exc:
            raise ScenarioError(self.key_of(exc.where), exc.problem) from None


# ---------------------------------------------------------------------------------------------
# samples


class PerFit(Model):
    """A fitting option of ``samples``: one value for both splines or one per spline.

    ``per_fit`` tells whether the file gave a mapping ``{position: …, attitude: …}`` (then
    errors name ``trajectory.<option>.<fit>``) or one common value.
    """

    position: Any = None
    attitude: Any = None
    per_fit: bool = False

    def of(self, fit: str) -> Any:
        """The value for the ``position`` or ``attitude`` spline."""
        return self.position if fit == "position" else self.attitude


def _integer(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"must be an integer, got {type(value).__name__} {shorten(value)}")
    return int(value)


def _sub(prefix: str, key: str) -> str:
    """``key`` (relative: ``name``, ``[i]``, ``name[i].x`` or empty) below ``prefix``."""
    if not key:
        return prefix
    return prefix + key if key.startswith("[") else f"{prefix}.{key}"


def _checked(prefix: str, check: Callable[[Any], Any], value: Any) -> Any:
    """``check(value)``, its errors named below the relative key ``prefix``."""
    try:
        return check(value)
    except ScenarioError as exc:
        raise ScenarioError(_sub(prefix, exc.key), exc.problem) from None
    except ValueError as exc:
        raise ScenarioError(prefix, str(exc)) from None


def _list(value: Any, item: Callable[[Any], Any]) -> tuple[Any, ...]:
    return tuple(_checked(f"[{i}]", item, v) for i, v in enumerate(value))


def _is_list(value: Any) -> bool:
    return isinstance(value, Sequence) and not isinstance(value, str | bytes)


def _knots(value: Any) -> float | tuple[float, ...] | None:
    """A spacing (s, > 0) or a list of breakpoints (s since the first sample)."""
    if value is None:
        return None
    if _is_list(value):
        return _list(value, finite_number)
    spacing = finite_number(value)
    if spacing <= 0.0:
        raise ValueError(
            f"must be > 0 (a spacing in s) or a list of breakpoints, got {shorten(value)}"
        )
    return spacing


def _degree(value: Any) -> int:
    degree = _integer(value)
    if degree < 1:
        raise ValueError(f"must be >= 1, got {degree}")
    return degree


def _continuity(value: Any) -> int | tuple[int, ...] | None:
    if value is None:
        return None
    if _is_list(value):
        return _list(value, _integer)
    return _integer(value)


def _break(value: Any) -> tuple[float, int]:
    if not isinstance(value, Mapping):
        raise ValueError(f"must be a mapping {{t_s: <s>, continuity: <int>}}, got {shorten(value)}")
    for key in value:
        if key not in ("t_s", "continuity"):
            raise ScenarioError(str(key), "unknown key; expected one of: t_s, continuity")
    for key in ("t_s", "continuity"):
        if key not in value:
            raise ScenarioError(key, "is required")
    return (
        _checked("t_s", finite_number, value["t_s"]),
        _checked("continuity", _integer, value["continuity"]),
    )


def _breaks(value: Any) -> tuple[tuple[float, int], ...]:
    if not _is_list(value):
        raise ValueError(f"must be a list of {{t_s, continuity}}, got {shorten(value)}")
    return _list(value, _break)


def _per_fit(check: Callable[[Any], Any], default: Any) -> Any:
    """Validator of a :class:`PerFit` option whose single value ``check`` validates."""

    def validate(value: Any) -> PerFit:
        if isinstance(value, PerFit):
            return value
        if isinstance(value, Mapping):
            for key in value:
                if key not in FITS:
                    raise ScenarioError(
                        str(key), "unknown key; expected one of: " + ", ".join(FITS)
                    )
            out = {}
            for fit in FITS:
                if fit not in value:
                    out[fit] = default
                    continue
                out[fit] = _checked(fit, check, value[fit])
            return PerFit(**out, per_fit=True)
        one = check(value)
        return PerFit(position=one, attitude=one)

    return PlainValidator(validate)


class WeightsSpec(Model):
    """Least-squares weights ``w = 1/σ²`` (0 ignores that data)."""

    position: NonNegative = 1.0  # 1/m²
    velocity: NonNegative = 100.0  # s²/m²
    acceleration: NonNegative = 0.0  # s⁴/m²
    attitude: NonNegative = 1.0e4  # 1/rad²
    rate: NonNegative = 1.0e4  # s²/rad²


class SamplesTrajectorySpec(Model):
    """``kind: samples``: a continuous truth fitted to samples from a CSV file or a bag."""

    kind: Literal["samples"]
    file: str | None = None
    bag: str | None = None
    topic: str | None = None  # default /reference/odom (with bag)
    columns: dict[str, str] | None = None
    knots: Annotated[PerFit, _per_fit(_knots, None)] = PerFit()
    degree: Annotated[PerFit, _per_fit(_degree, 3)] = PerFit(position=3, attitude=3)
    continuity: Annotated[PerFit, _per_fit(_continuity, None)] = PerFit()
    breaks: Annotated[PerFit, _per_fit(_breaks, ())] = PerFit(position=(), attitude=())
    weights: WeightsSpec = Field(default_factory=WeightsSpec)
    attitude_method: Literal["auto", "fit", "integrate"] = "auto"
    rate_frame: Literal["inertial", "earth"] = "inertial"
    q_step: Positive | None = None

    @field_validator("file", "bag", "topic")
    @classmethod
    def _path(cls, value: str | None) -> str | None:
        if value is not None and not value.strip():
            raise ValueError("must not be empty")
        return value

    @field_validator("columns")
    @classmethod
    def _columns(cls, value: dict[str, str] | None) -> dict[str, str] | None:
        from strapdown_ros.inputs.samples import CSV_NAMES

        for name in value or {}:
            if name not in CSV_NAMES:
                raise ScenarioError(
                    name, "unknown canonical column name; expected one of: " + ", ".join(CSV_NAMES)
                )
        return value

    @model_validator(mode="after")
    def _rules(self) -> SamplesTrajectorySpec:
        if self.file is None and self.bag is None:
            raise ScenarioError(
                "file",
                "is required (a CSV path relative to the scenario file), or `bag` (and "
                "`topic`) for an Odometry topic of a bag",
            )
        if self.file is not None and self.bag is not None:
            raise ScenarioError("bag", "give either file or bag, not both")
        if self.topic is not None and self.bag is None:
            raise ScenarioError("topic", "is only used with bag")
        # Continuity limits (Giribet 2007 eq. (5)): C^c with -1 <= c <= degree - 1; the
        # position spline needs c >= 1 (a continuous velocity), the attitude one c >= 0.
        for fit, low in (("position", 1), ("attitude", 0)):
            degree = self.degree.of(fit)
            high = degree - 1
            cont = self.continuity.of(fit)
            if cont is None and high < low:
                raise ScenarioError(
                    self.option_key("degree", fit),
                    f"must be >= {low + 1} for the {fit} spline (its default continuity "
                    f"degree - 1 must be >= {low}), got {degree}",
                )
            given = [] if cont is None else list(cont) if isinstance(cont, tuple) else [cont]
            breaks = [c for _, c in self.breaks.of(fit)]
            for option, values in (("continuity", given), ("breaks", breaks)):
                for c in values:
                    if not low <= c <= high:
                        raise ScenarioError(
                            self.option_key(option, fit),
                            f"continuity orders of the {fit} spline must be in "
                            f"[{low}, degree - 1] = [{low}, {high}], got {c}",
                        )
        if self.attitude_method == "integrate" and self.degree.attitude < 2:
            raise ScenarioError(
                self.option_key("degree", "attitude"),
                "must be >= 2 with attitude_method 'integrate'",
            )
        return self

    @property
    def source_key(self) -> str:
        """The key of the samples' source: ``trajectory.file`` or ``trajectory.bag``."""
        return "trajectory.file" if self.file is not None else "trajectory.bag"

    @property
    def odometry_topic(self) -> str:
        """The Odometry topic read from ``bag``."""
        return self.topic if self.topic is not None else "/reference/odom"

    def option_key(self, option: str, fit: str) -> str:
        """Key of a fitting option for one spline, relative: ``knots`` or ``knots.position``."""
        return f"{option}.{fit}" if getattr(self, option).per_fit else option

    def key_of(self, where: tuple[str | int, ...]) -> tuple[str, str]:
        """Scenario key and a problem prefix for a core :class:`TrajectoryError` location."""
        if (
            len(where) >= 2
            and where[0] in FITS
            and where[1] in ("knots", "degree", "continuity", "breaks")
        ):
            fit, option = str(where[0]), str(where[1])
            key = "trajectory." + self.option_key(option, fit)
            for part in where[2:]:
                key = join_key(key, part)
            common = not getattr(self, option).per_fit
            return key, f"{fit} spline: " if common else ""
        if where and where[0] in FITS:
            return "trajectory", f"{where[0]} spline: "
        if len(where) == 2 and where[0] == "weights":
            return f"trajectory.weights.{where[1]}", ""
        if where and where[0] == "attitude_method":
            return "trajectory.attitude_method", ""
        return "trajectory", ""

    def fit_options(self) -> FitOptions:
        """The core fitting options."""
        from strapdown_ros.core.trajectory.samples import FitOptions, SplineOptions, Weights

        def spline(fit: str) -> SplineOptions:
            return SplineOptions(
                degree=self.degree.of(fit),
                knots=self.knots.of(fit),
                continuity=self.continuity.of(fit),
                breaks=self.breaks.of(fit),
            )

        w = self.weights
        return FitOptions(
            position=spline("position"),
            attitude=spline("attitude"),
            weights=Weights(
                position=w.position,
                velocity=w.velocity,
                acceleration=w.acceleration,
                attitude=w.attitude,
                rate=w.rate,
            ),
            attitude_method=self.attitude_method,
            q_step=self.q_step,
        )


# ---------------------------------------------------------------------------------------------
# The union and the cross-field rules


def _kind(value: Any) -> Any:
    if isinstance(value, Mapping):
        if "kind" not in value:
            raise ScenarioError("kind", "is required; one of: " + ", ".join(KINDS))
        if value["kind"] not in KINDS:
            raise ScenarioError(
                "kind", f"must be one of: {', '.join(KINDS)}; got {shorten(value['kind'])}"
            )
    return value


#: The ``trajectory`` section: one of the four kinds, tagged by ``kind``.
TrajectorySpec = Annotated[
    SegmentsTrajectorySpec
    | IncrementsTrajectorySpec
    | ConingTrajectorySpec
    | SamplesTrajectorySpec,
    Field(discriminator="kind"),
    BeforeValidator(_kind),
]


def check_trajectory(
    spec: TrajectorySpec, initial: Initial | None, generation_period_ns: int
) -> None:
    """Rules of ``trajectory`` that need the rest of the scenario (called by its validation
    with the scenario's ``initial`` and its generation period T / oversample in ns).

    * ``initial`` is required for every kind but ``samples`` (the samples define the start).
    * ``segments`` and ``coning``: ``|initial.latitude_deg| <= 89.9``. Their latitude and
      longitude integrate the geodetic rates ``λ' = v_E / ((R_E + h) cos φ)``, singular at the
      poles; the whole path is held within ±89.9° (docs/interface.md §5), so its start must be too.
      The
      top-level ``initial`` allows ±90° because ``increments`` (integrated in E0) and the
      navigator have no such singularity.
    * ``segments``: ``|pitch| <= 89.9°`` at the start (the Euler-angle model is held within
      ±89.9° of pitch; ``C_B^N = Rz Ry Rx`` is singular at ±90°).
    * ``coning``: the CM starts at rest (``initial.velocity_ned_mps`` zero, Waldmann §6) and its
      sinusoidal descent may not take it below -10 km.
    * ``increments``: every segment is a whole number of generation cycles (T / oversample).
    * ``segments``, ``increments``, ``coning``: at most :data:`MAX_DURATION_S` in total.

    Raises
    ------
    ScenarioError
        Naming the key.
    """
    if isinstance(spec, SamplesTrajectorySpec):
        return
    if initial is None:
        raise ScenarioError("initial", "is required")
    if spec.natural_duration > MAX_DURATION_S:
        key = "trajectory.coning.duration_s" if spec.kind == "coning" else "trajectory.segments"
        what = "lasts {:g} s" if spec.kind == "coning" else "the segments last {:g} s in total"
        raise ScenarioError(
            key,
            what.format(spec.natural_duration) + f", more than the {MAX_DURATION_S:g} s (about "
            f"116 days) a {spec.kind} trajectory may last",
        )
    if isinstance(spec, SegmentsTrajectorySpec | ConingTrajectorySpec):
        limit = math.degrees(LATITUDE_LIMIT)
        if abs(initial.latitude_deg) > limit:
            raise ScenarioError(
                "initial.latitude_deg",
                f"must be within ±{limit:.1f}° for a {spec.kind} trajectory (its latitude and "
                f"longitude integrate the geodetic rates, singular at the poles), got "
                f"{initial.latitude_deg}",
            )
    if isinstance(spec, SegmentsTrajectorySpec):
        limit = math.degrees(PITCH_LIMIT)
        pitch = initial.attitude_rph_deg[1]
        if abs(pitch) > limit:
            raise ScenarioError(
                "initial.attitude_rph_deg[1]",
                f"pitch must be within ±{limit:.1f}° for a segments trajectory, got {pitch}",
            )
    if isinstance(spec, ConingTrajectorySpec):
        if any(v != 0.0 for v in initial.velocity_ned_mps):
            raise ScenarioError(
                "initial.velocity_ned_mps",
                "the coning trajectory starts at rest (Waldmann §6), got "
                f"{list(initial.velocity_ned_mps)}",
            )
        c = spec.coning
        if c.cm_motion == "sinusoids":
            low = lowest_altitude(
                initial.altitude_m,
                c.velocity_amplitude_ned_mps[2],
                c.velocity_period_ned_s[2],
                c.duration_s,
            )
            if low < ALTITUDE_MIN:
                raise ScenarioError(
                    "trajectory.coning.velocity_amplitude_ned_mps",
                    f"altitude would fall to {low:.1f} m, below -10 km",
                )
    if isinstance(spec, IncrementsTrajectorySpec):
        period_ns = generation_period_ns
        for i, seg in enumerate(spec.segments):
            if whole_cycles(seg.duration_s, period_ns) is None:
                raise ScenarioError(
                    f"trajectory.segments[{i}].duration_s",
                    f"{seg.duration_s} s is not a whole number of cycles of {period_ns * 1e-9} s "
                    "(T / oversample; segment boundaries must fall on cycle boundaries)",
                )
