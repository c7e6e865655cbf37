"""``strapdown-sim score``: a navigation estimate in a bag against the bag's exact truth.

One module per step: :mod:`~strapdown_ros.score.truth` (the truth at any stamp: the trajectory
model tied to the published samples), :mod:`~strapdown_ros.score.estimate` (the estimate's
messages and static frames to ECEF), :mod:`~strapdown_ros.score.metrics` (errors, outage drift,
NEES, time offset), :mod:`~strapdown_ros.score.scorer` (the steps in order),
:mod:`~strapdown_ros.score.page` (JSON, markdown, plots), :mod:`~strapdown_ros.score.cli`.
Definitions: docs/score.md.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Score", "ScoreError", "score_bag", "score_estimate"]


def __getattr__(name: str) -> Any:
    """The public names, imported on first use (``strapdown-sim``'s parser imports
    :mod:`strapdown_ros.score.cli` and must not load numpy, scipy or the bag reader)."""
    if name == "ScoreError":
        from strapdown_ros.score.estimate import ScoreError

        return ScoreError
    if name in __all__:
        from strapdown_ros.score import scorer

        return getattr(scorer, name)
    raise AttributeError(f"module 'strapdown_ros.score' has no attribute {name!r}")
