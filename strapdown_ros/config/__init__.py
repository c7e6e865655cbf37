"""The scenario model: one typed tree, parsed and validated once, at the edge.

:func:`load_scenario` reads a YAML file, applies ``--set`` overrides and ``--duration`` and
returns a validated :class:`Scenario`; everything downstream takes typed objects. The keys are
documented in docs/scenarios.md.
"""

from strapdown_ros.config import scenario
from strapdown_ros.config.scenario import *  # noqa: F403

__all__ = list(scenario.__all__)
