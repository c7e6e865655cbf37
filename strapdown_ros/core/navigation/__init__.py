"""Strapdown navigators (numpy core, no ROS).

* :mod:`.state` — navigation state (geodetic position, NED velocity, ``q_b^n``) and its
  initialization from a stream's E0 truth.
* :mod:`.multirate` — Waldmann's multirate modified b–l split scheme (seeds/004, Table 1) and
  the simultaneous l-frame scheme (Table 2) for comparison.
"""

from strapdown_ros.core.navigation import multirate, state
from strapdown_ros.core.navigation.multirate import *  # noqa: F403
from strapdown_ros.core.navigation.state import *  # noqa: F403

__all__ = [*multirate.__all__, *state.__all__]
