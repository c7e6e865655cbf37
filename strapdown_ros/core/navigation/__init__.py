"""Strapdown navigators (numpy core, no ROS).

* :mod:`.state` — navigation state (geodetic position, NED velocity, ``q_b^n``) and its
  initialization from a stream's E0 truth.
* :mod:`.multirate` — Waldmann's multirate modified b–l split scheme (seeds/004, Table 1) and
  the simultaneous l-frame scheme (Table 2) for comparison.
"""

from strapdown_ros.core.navigation.multirate import (
    MODES,
    MultirateNavigator,
    NavSolution,
    SimultaneousNavigator,
    VerticalDamping,
    fast_cycle,
    navigate_multirate,
    navigate_simultaneous,
)
from strapdown_ros.core.navigation.state import NavState, state_from_stream, truth_navigation

__all__ = [
    "MODES",
    "MultirateNavigator",
    "NavSolution",
    "SimultaneousNavigator",
    "VerticalDamping",
    "NavState",
    "fast_cycle",
    "navigate_multirate",
    "navigate_simultaneous",
    "state_from_stream",
    "truth_navigation",
]
