"""TEMPORARY: the old dict readers, used only by stages/navigation.py until the navigator
section has its typed model (config/navigator.py). Delete with that change."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from strapdown_ros.config.base import ScenarioError


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


