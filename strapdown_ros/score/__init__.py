"""``strapdown-sim score``: a navigation estimate in a bag against the bag's exact truth.

One module per step: :mod:`~strapdown_ros.score.truth` (the truth at any stamp: the trajectory
model tied to the published samples), :mod:`~strapdown_ros.score.estimate` (the estimate's
messages and static frames to ECEF), :mod:`~strapdown_ros.score.metrics` (errors, outage drift,
NEES, time offset), :mod:`~strapdown_ros.score.scorer` (the steps in order),
:mod:`~strapdown_ros.score.page` (JSON, markdown, plots), :mod:`~strapdown_ros.score.cli`.
Definitions: docs/score.md.
"""

from __future__ import annotations

from strapdown_ros.score.estimate import ScoreError
from strapdown_ros.score.scorer import Score, score_bag, score_estimate

__all__ = ["Score", "ScoreError", "score_bag", "score_estimate"]
