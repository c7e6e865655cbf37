"""Typed node parameters: declare one, check its value, name it in the error.

Parameter problems raise :class:`ParameterError`; a node's ``main`` turns it (and
:class:`~strapdown_ros.config.ScenarioError`) into exit status 2, as ``strapdown-sim`` does
(:func:`~strapdown_ros.nodes.lifecycle.run_node`).
"""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

__all__ = [
    "ParameterError",
    "declare_bool",
    "declare_int",
    "declare_number",
    "declare_scenario",
    "declare_string",
    "declare_string_array",
]


class ParameterError(ValueError):
    """A node parameter is missing or invalid; ``name`` is the parameter."""

    def __init__(self, name: str, problem: str) -> None:
        self.name = name
        self.problem = problem
        super().__init__(f"parameter '{name}': {problem}")


def _declare(node: Node, name: str, default: Any, description: str, dynamic: bool = False) -> Any:
    descriptor = ParameterDescriptor(description=description, dynamic_typing=dynamic)
    try:
        return node.declare_parameter(name, default, descriptor).value
    except Exception as exc:  # rclpy's InvalidParameterTypeException and the like
        raise ParameterError(name, str(exc)) from exc


def declare_string(node: Node, name: str, default: str, description: str = "") -> str:
    """Declare a string parameter and return its value."""
    value = _declare(node, name, default, description, dynamic=True)
    if not isinstance(value, str):
        raise ParameterError(name, f"must be a string, got {value!r}")
    return value


def declare_bool(node: Node, name: str, default: bool, description: str = "") -> bool:
    """Declare a boolean parameter and return its value."""
    value = _declare(node, name, default, description, dynamic=True)
    if not isinstance(value, bool):
        raise ParameterError(name, f"must be true or false, got {value!r}")
    return value


def declare_number(node: Node, name: str, default: float, description: str = "") -> float:
    """Declare a floating-point parameter (``3`` is accepted as well as ``3.0``)."""
    value = _declare(node, name, float(default), description, dynamic=True)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(name, f"must be a number, got {value!r}")
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ParameterError(name, f"must be finite, got {value}")
    return value


def declare_int(
    node: Node, name: str, default: int, description: str = "", minimum: int | None = None
) -> int:
    """Declare an integer parameter and return its value."""
    value = _declare(node, name, int(default), description, dynamic=True)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ParameterError(name, f"must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise ParameterError(name, f"must be >= {minimum}, got {value}")
    return value


def declare_string_array(node: Node, name: str, description: str = "") -> list[str]:
    """Declare a string-array parameter (default empty) and return its value.

    A single string is accepted as a one-element list (``-p overrides:=rate_hz=100``).
    """
    value = _declare(node, name, [""], description, dynamic=True)
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise ParameterError(name, f"must be a list of strings, got {value!r}")
    return [v for v in value if v]


def declare_scenario(node: Node, required: bool = True, what: str = "") -> Any:
    """Declare ``scenario`` (a YAML path), ``overrides`` and ``duration_s``; load the scenario.

    Returns the :class:`~strapdown_ros.config.Scenario` (None when ``required`` is False and
    no path is given). ``what`` says what the node takes from it, for the description. Raises
    :class:`ParameterError` for a missing path or a negative duration and
    :class:`~strapdown_ros.config.ScenarioError` for an invalid file.
    """
    from strapdown_ros.config import load_scenario

    path = declare_string(
        node, "scenario", "", f"scenario YAML file{f' ({what})' if what else ''}"
        + (" (required)" if required else "")
    )
    overrides = declare_string_array(node, "overrides", "scenario overrides dotted.key=value")
    duration_s = declare_number(node, "duration_s", 0.0, "duration (s); 0 = the scenario's")
    if not path:
        if required:
            raise ParameterError("scenario", "is required (the path of a scenario YAML file)")
        return None
    if duration_s < 0:
        raise ParameterError("duration_s", f"must be >= 0, got {duration_s}")
    return load_scenario(path, overrides, duration_s if duration_s > 0 else None)
