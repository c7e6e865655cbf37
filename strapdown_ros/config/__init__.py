"""The scenario model: one typed tree, parsed and validated once, at the edge.

:func:`load_scenario` reads a YAML file, applies ``--set`` overrides and ``--duration`` and
returns a validated :class:`Scenario`; everything downstream takes typed objects. The keys are
documented in docs/scenarios.md.
"""

from strapdown_ros.config.scenario import (
    DEFAULT_FRAMES,
    DEFAULT_TOPICS,
    Initial,
    Recording,
    Scenario,
    ScenarioError,
    apply_overrides,
    load_scenario,
    navigator_spec,
    parse_scenario,
    tf_spec,
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
