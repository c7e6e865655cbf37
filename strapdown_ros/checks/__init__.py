"""What ``strapdown-sim check`` and ``report`` verify on a bag read back from disk.

* :mod:`strapdown_ros.checks.settings`: the gravitation model a bag's streams were generated
  with (its ``custom_data``, or an explicit override);
* :mod:`strapdown_ros.checks.streams`: the docs/interface.md §3 verdict of every Imu/Odometry
  pair, and why a pair cannot be verified (a bag from another tool);
* :mod:`strapdown_ros.checks.foreign`: what the commands can and cannot do with a bag that was
  not written by strapdown_ros.
"""

from __future__ import annotations

from strapdown_ros.checks.settings import GRAVITY_MODELS, CheckSettings, check_settings
from strapdown_ros.checks.streams import PairVerdict, check_pair, check_streams, is_ecef

__all__ = [
    "GRAVITY_MODELS",
    "CheckSettings",
    "PairVerdict",
    "check_pair",
    "check_settings",
    "check_streams",
    "is_ecef",
]
