"""Building blocks of the scenario model: the strict base model, field types, error messages.

Every section of a scenario file is a :class:`Model` (pydantic v2): unknown keys are rejected
(``extra="forbid"``), numbers are strict (no strings, no booleans, no NaN or infinity; an
integer is accepted where a real number is expected) and a validated model is frozen. A
:class:`pydantic.ValidationError` is turned into one :class:`ScenarioError` whose key reads
like the file, e.g. ``trajectory.segments[2].accel_mps2: must be a finite number, got nan``.
A value echoed in a message is shortened (:func:`shorten`), so that a huge value (or one whose
YAML aliases make it huge) gives a message of a line, not of megabytes.
"""

from __future__ import annotations

import difflib
import math
import types
import typing
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal, Union

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    model_validator,
)

__all__ = [
    "Core",
    "Finite",
    "Model",
    "NonNegative",
    "NullIsDefault",
    "Positive",
    "PresetModel",
    "ScenarioError",
    "StrictBool",
    "StrictInt",
    "Vector3",
    "check_frame_id",
    "check_topic_name",
    "core_keys",
    "core_values",
    "enabled_section",
    "error_from_validation",
    "finite_number",
    "is_frame_id",
    "is_topic_name",
    "join_key",
    "require_correlation_times",
    "required_section",
    "shorten",
    "with_preset",
]

#: Longest echo of a value (or of a key) in an error message, in characters; cut with "…".
ECHO_LIMIT = 200
#: Longest problem text of a :class:`ScenarioError` (a backstop; echoes are shortened first).
PROBLEM_LIMIT = 4000


class _FullError(Exception):
    """The budget of :func:`shorten` is spent."""


def shorten(value: Any, limit: int = ECHO_LIMIT) -> str:
    """``repr(value)``, cut after ``limit`` characters with "…".

    Only as much of ``value`` is formatted as is shown: lists, tuples and dicts are written
    element by element (as ``repr`` writes them) until the budget is spent, so a value whose
    parts are shared many times (YAML aliases) or that contains itself costs ``limit``
    characters, not its expanded size. Other values are ``repr``'d (strings cut first).
    """
    parts: list[str] = []
    left = [limit + 1]

    def emit(text: str) -> None:
        parts.append(text)
        left[0] -= len(text)
        if left[0] <= 0:
            raise _FullError

    def walk(v: Any) -> None:
        kind = type(v)
        if kind is list or kind is tuple:
            emit("[" if kind is list else "(")
            for i, item in enumerate(v):
                if i:
                    emit(", ")
                walk(item)
            emit("]" if kind is list else ",)" if len(v) == 1 else ")")
        elif kind is dict:
            emit("{")
            for i, (k, item) in enumerate(v.items()):
                if i:
                    emit(", ")
                walk(k)
                emit(": ")
                walk(item)
            emit("}")
        elif kind is str and len(v) > limit:
            emit(repr(v[: limit + 1]))
        else:
            emit(repr(v))

    try:
        walk(value)
    except _FullError:
        return "".join(parts)[:limit] + "…"
    return "".join(parts)


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[:limit] + "…"


class ScenarioError(ValueError):
    """A scenario file or override is invalid; ``key`` is the dotted path of the culprit.

    The message is ``"<key>: <problem>"`` (the key alone names the value in the file, e.g.
    ``trajectory.segments[2].accel_mps2``); ``key`` is empty for problems of the whole file.
    """

    def __init__(self, key: str, problem: str) -> None:
        key, problem = _cut(key, ECHO_LIMIT), _cut(problem, PROBLEM_LIMIT)
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}" if key else problem)

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # picklable across processes
        return (type(self), (self.key, self.problem))


#: A finite real number (an integer is accepted; strings, booleans, NaN and ±inf are not).
Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]
#: A finite number > 0.
Positive = Annotated[float, Strict(), Field(allow_inf_nan=False, gt=0.0)]
#: A finite number >= 0.
NonNegative = Annotated[float, Strict(), Field(allow_inf_nan=False, ge=0.0)]
#: An integer (not a float, not a boolean).
StrictInt = Annotated[int, Strict()]
#: ``true`` or ``false``.
StrictBool = Annotated[bool, Strict()]


def is_topic_name(value: Any) -> bool:
    """An absolute ROS topic name: a string that starts with ``/`` and has no space."""
    return isinstance(value, str) and value.startswith("/") and " " not in value


def is_frame_id(value: Any) -> bool:
    """A frame id: a non-empty string without spaces."""
    return isinstance(value, str) and bool(value) and " " not in value


def check_topic_name(value: Any) -> Any:
    """``value`` when :func:`is_topic_name`, else ValueError (a pydantic before-validator)."""
    if not is_topic_name(value):
        raise ValueError(f"must be an absolute topic name, got {shorten(value)}")
    return value


def check_frame_id(value: Any) -> Any:
    """``value`` when :func:`is_frame_id`, else ValueError (a pydantic before-validator)."""
    if not is_frame_id(value):
        raise ValueError(f"must be a frame id, got {shorten(value)}")
    return value


def enabled_section(scenario: Any, key: str) -> Any:
    """The scenario's section ``key`` if it has one with ``enabled: true``, else None."""
    spec = getattr(scenario, key, None)
    return spec if spec is not None and spec.enabled else None


def require_period_multiple(key: str, rate_hz: float, period_ns: int, what: str = "") -> int:
    """The period 1e9/``rate_hz`` (ns) of ``key`` (``what`` names it in the message), which must
    be a whole multiple of the IMU period T = ``period_ns``; :class:`ScenarioError` if not."""
    period = 1e9 / rate_hz
    if abs(period - round(period)) > 1e-6 or round(period) % period_ns:
        raise ScenarioError(
            key, f"the {what + ' ' if what else ''}period 1e9/{rate_hz:g} = {period:g} ns is not "
            f"a whole multiple of the IMU period T = {period_ns} ns",
        )  # fmt: skip
    return int(round(period))


def required_section(scenario: Any, key: str) -> Any:
    """:func:`enabled_section`, or :class:`ScenarioError` under ``key`` when there is none."""
    spec = enabled_section(scenario, key)
    if spec is None:
        raise ScenarioError(key, f"missing or disabled: this needs an enabled '{key}' section")
    return spec


def finite_number(value: Any) -> float:
    """``value`` as a float: an int or float, not a boolean, not NaN or ±inf (a plain-function
    check for values inside lists, where the field types above do not reach)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"must be a number, got {type(value).__name__} {shorten(value)}")
    if not math.isfinite(value):
        raise ValueError(f"must be finite, got {shorten(value)}")
    return float(value)


def _length(n: int) -> Any:
    def check(value: Any) -> Any:
        if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence):
            raise ValueError(f"must be a list of {n} numbers, got {shorten(value)}")
        if len(value) != n:
            raise ValueError(f"must be a list of {n} numbers, got {len(value)}: {shorten(value)}")
        return tuple(value)

    return BeforeValidator(check)


#: Three finite numbers, e.g. ``[1.0, 0.0, -0.5]`` (a vector in the axes its key names).
Vector3 = Annotated[tuple[Finite, Finite, Finite], _length(3)]


def vector(n: int) -> Any:
    """The type of a list of ``n`` finite numbers."""
    return Annotated[tuple[(Finite,) * n], _length(n)]  # type: ignore[misc]


def with_preset(presets: Mapping[str, Mapping[str, Any]], data: Any) -> Any:
    """``data`` with the values of its ``preset`` for the keys not given (or given as null).

    For a ``mode="before"`` model validator of a section with presets; a missing or unknown
    preset leaves ``data`` as it is (the ``preset`` field reports an unknown one).
    """
    if not isinstance(data, Mapping):
        return data
    preset = data.get("preset")
    if not isinstance(preset, str) or preset not in presets:
        return data
    merged: dict[str, Any] = dict(presets[preset])
    merged.update({k: v for k, v in data.items() if v is not None or k not in merged})
    return merged


class Model(BaseModel):
    """Base of every scenario section: unknown keys rejected, frozen once validated."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=False)


class NullIsDefault(Model):
    """A section whose ``null`` values mean "the default" (the key as if left out)."""

    @model_validator(mode="before")
    @classmethod
    def _null_is_default(cls, data: Any) -> Any:
        if isinstance(data, Mapping):
            return {k: v for k, v in data.items() if v is not None}
        return data


def require_correlation_times(spec: Model, pairs: tuple[tuple[str, str], ...]) -> None:
    """A Gauss-Markov term needs its correlation time: for each ``(sigma_key, tau_key)``, the
    ``tau_key`` is required when any axis of ``sigma_key`` is > 0."""
    for sigma_key, tau_key in pairs:
        sigma = getattr(spec, sigma_key)
        if sigma is not None and max(np.atleast_1d(sigma)) > 0 and getattr(spec, tau_key) is None:
            raise ScenarioError(tau_key, f"is required when {sigma_key} is > 0")


@dataclass(frozen=True)
class Core:
    """What a scenario key is to the core object its section builds (``Annotated`` metadata of
    the key): the core parameter ``name`` it sets, to the key's value times ``factor`` (from the
    unit the key's name says to SI; a vector or matrix element by element)."""

    name: str
    factor: float = 1.0

    def convert(self, value: Any) -> Any:
        """``value`` in SI units (``factor`` 1: ``value`` itself)."""
        if self.factor == 1.0:
            return value
        if isinstance(value, tuple):
            return tuple(self.convert(v) for v in value)
        return value * self.factor


def _core_fields(spec: type[BaseModel]) -> Iterator[tuple[str, Core]]:
    for key, info in spec.model_fields.items():
        for meta in info.metadata:
            if isinstance(meta, Core):
                yield key, meta


def core_values(spec: BaseModel) -> dict[str, Any]:
    """The core parameters the keys of ``spec`` set (:class:`Core`), by name, in SI units: the
    keys that are not None (the others leave the core object's defaults)."""
    values = {}
    for key, core in _core_fields(type(spec)):
        value = getattr(spec, key)
        if value is not None:
            values[core.name] = core.convert(value)
    return values


def core_keys(spec: type[BaseModel]) -> dict[str, str]:
    """The scenario key of each core parameter the keys of model ``spec`` set (:class:`Core`)."""
    return {core.name: key for key, core in _core_fields(spec)}


class PresetModel(Model):
    """A section with a ``preset`` key: the preset's values fill the keys not given
    (:func:`with_preset`); a subclass names its table in ``PRESETS``."""

    PRESETS: ClassVar[Mapping[str, Mapping[str, Any]]] = {}

    @model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        return with_preset(cls.PRESETS, data)


# ---------------------------------------------------------------------------------------------
# ValidationError -> ScenarioError


def join_key(path: str, key: str | int) -> str:
    """``path`` extended by a mapping key (``a.b``) or a list index (``a[2]``)."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _unwrap(annotation: Any) -> list[Any]:
    """The model classes / containers an annotation may hold (Annotated, Optional, unions)."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (Union, types.UnionType):
        out: list[Any] = []
        for arg in typing.get_args(annotation):
            out += _unwrap(arg)
        return out
    return [annotation]


def _model_kind(model: type[BaseModel]) -> str | None:
    field = model.model_fields.get("kind")
    if field is None:
        return None
    args = typing.get_args(field.annotation)
    return args[0] if typing.get_origin(field.annotation) is Literal and len(args) == 1 else None


def _list_items(t: Any) -> list[Any]:
    """The item types of a list or tuple type ``t`` (none for another type)."""
    if typing.get_origin(t) not in (list, tuple):
        return []
    return [u for a in typing.get_args(t) if a is not Ellipsis for u in _unwrap(a)]


def _keys_at(root: type[BaseModel], loc: Sequence[str | int], document: Any) -> tuple[str, Any]:
    """Dotted key of ``loc`` (tagged-union tags removed) and the model type found there."""
    key = ""
    types_here: list[Any] = [root]
    node = document
    i = 0
    while i < len(loc):
        part = loc[i]
        models = [t for t in types_here if isinstance(t, type) and issubclass(t, BaseModel)]
        # A tagged union puts the tag in the location right after the union's field.
        if isinstance(part, str) and isinstance(node, Mapping) and node.get("kind") == part:
            tagged = [m for m in models if _model_kind(m) == part]
            if tagged and (len(models) > 1 or part not in tagged[0].model_fields):
                types_here, i = tagged, i + 1
                continue
        if isinstance(part, int) and isinstance(node, Mapping):
            # a one-or-list section written as one mapping: its keys without an index
            types_here = [a for t in types_here for a in _list_items(t)]
            i += 1
            continue
        key = join_key(key, part)
        nxt: list[Any] = []
        if isinstance(part, int):
            for t in types_here:
                origin = typing.get_origin(t)
                if origin in (list, tuple):
                    args = [a for a in typing.get_args(t) if a is not Ellipsis]
                    if args:
                        nxt += _unwrap(args[min(part, len(args) - 1)])
        else:
            for m in models:
                if part in m.model_fields:
                    nxt += _unwrap(m.model_fields[part].annotation)
        types_here = nxt
        try:
            node = node[part]  # type: ignore[index]
        except (KeyError, IndexError, TypeError):
            node = None
        i += 1
    return key, types_here


def _format(error: Mapping[str, Any], allowed: Sequence[str]) -> str:
    kind = error["type"]
    value = error.get("input")
    if kind == "extra_forbidden":
        return "unknown key; expected one of: " + ", ".join(allowed) if allowed else "unknown key"
    if kind == "missing":
        return "is required"
    if kind == "union_tag_invalid":
        ctx = error.get("ctx", {})
        return f"kind must be one of: {ctx.get('expected_tags', '')}; got {shorten(ctx.get('tag'))}"
    if kind == "union_tag_not_found":
        return "is missing its 'kind'"
    if kind == "literal_error":
        expected = error.get("ctx", {}).get("expected", "")
        return f"must be one of: {expected}; got {shorten(value)}"
    if kind in ("float_type", "int_type", "float_parsing", "int_from_float"):
        want = "an integer" if kind.startswith("int") else "a number"
        return f"must be {want}, got {type(value).__name__} {shorten(value)}"
    if kind == "finite_number":
        return f"must be finite, got {shorten(value)}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        ctx = error.get("ctx", {})
        op, bound = {
            "greater_than": (">", ctx.get("gt")),
            "greater_than_equal": (">=", ctx.get("ge")),
            "less_than": ("<", ctx.get("lt")),
            "less_than_equal": ("<=", ctx.get("le")),
        }[kind]
        return f"must be {op} {bound}, got {shorten(value)}"
    if kind == "bool_type":
        return f"must be true or false, got {shorten(value)}"
    if kind in ("string_type",):
        return f"must be a string, got {shorten(value)}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"must be a mapping, got {type(value).__name__}"
    if kind in ("list_type", "tuple_type"):
        return f"must be a list, got {shorten(value)}"
    if kind == "value_error":
        return str(error.get("ctx", {}).get("error", error["msg"]))
    return f"{error['msg'][0].lower()}{error['msg'][1:]}, got {shorten(value)}"


def error_from_validation(
    exc: ValidationError, root: type[BaseModel], document: Any, prefix: str = ""
) -> ScenarioError:
    """The first error of a pydantic validation as a :class:`ScenarioError` naming the key."""
    error = exc.errors(include_url=False)[0]
    loc = list(error["loc"])
    key, _ = _keys_at(root, loc, document)
    allowed: list[str] = []
    if error["type"] == "extra_forbidden":
        _, parents = _keys_at(root, loc[:-1], document)
        for t in parents:
            if isinstance(t, type) and issubclass(t, BaseModel):
                allowed += [n for n in t.model_fields if n not in allowed]
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        problem = _format(error, allowed)
        if close:
            problem = f"unknown key (did you mean {close[0]!r}?); expected one of: " + ", ".join(
                allowed
            )
    else:
        problem = _format(error, allowed)
        inner = error.get("ctx", {}).get("error") if error["type"] == "value_error" else None
        if isinstance(inner, ScenarioError):  # a validator naming a key below its model
            key = ".".join(k for k in (key, inner.key) if k).replace(".[", "[")
            problem = inner.problem
    if prefix:
        key = join_key(prefix, key) if key else prefix
    return ScenarioError(key, problem)


def validate_section(model: type[Model], data: Any, key: str = "") -> Model:
    """``model.model_validate(data)``, errors as a :class:`ScenarioError` under ``key``."""
    try:
        return model.model_validate({} if data is None else data)
    except ValidationError as exc:
        raise error_from_validation(exc, model, data, key) from None
