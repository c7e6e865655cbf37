"""How the reference moves: continuous truth models sampled at the generation instants.

Every kind but ``increments`` is a :class:`~strapdown_ros.core.trajectory.base.Trajectory`: a
continuous truth that can be sampled at any time. The published increments and truth then come
from Savage's Method 2 with zero offsets (:mod:`strapdown_ros.core.method2`), which makes them
exact (docs/interface.md §3) whatever the model.
"""

from strapdown_ros.core.trajectory.base import (
    LocalTruth,
    Trajectory,
    TrajectoryError,
    TruthE0,
    local_to_e0,
)

__all__ = ["LocalTruth", "Trajectory", "TrajectoryError", "TruthE0", "local_to_e0"]
