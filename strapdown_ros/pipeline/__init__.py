"""``strapdown-sim run``: the live pipeline as separate ROS 2 processes (interface.md §6).

Starts ``bag_recorder``, ``aided_node``, ``aiding_node``, ``navigator_node``,
``imu_model_node``, ``variation_node`` and ``trajectory_node`` (those the scenario needs) as
child processes in a private ROS domain (LOCALHOST discovery), downstream first: each node waits
until every one of its output topics has as many matched subscriptions as the pipeline will have
on it (``subscribers_per_topic``: the recorder plus the downstream nodes), and only then
subscribes to its inputs, so no message is published before everyone who should record or
process it is listening. The trajectory node then publishes the scenario paced at
``rate_factor`` x real time; every node exits after its last message, the recorder
(``stop_when_done``) when all its publishers are gone, and the recorded message counts are
checked against what the scenario produces.

Runs not tied to the wall clock (``rate_factor`` > 1, or <= 0: unpaced, as fast as the slowest
node allows) are flow-controlled (:mod:`strapdown_ros.nodes.flow`): the recorder and the nodes
report their progress and the trajectory node never gets more than a window ahead of any
consumer, so they are lossless by construction; the throughput reached is reported. Real-time
and slower runs (0 < ``rate_factor`` <= 1, hardware in the loop) keep the wall-clock pace and
any loss shows as a count mismatch.

Modules: :mod:`~strapdown_ros.pipeline.processes` (the children: start, watch, stop, reap;
environment and domain), :mod:`~strapdown_ros.pipeline.run` (:func:`run_pipeline`),
:mod:`~strapdown_ros.pipeline.replay` (:func:`replay_into_navigator`),
:mod:`~strapdown_ros.pipeline.result` (what both report).
"""

from __future__ import annotations

from strapdown_ros.pipeline.processes import PROFILE_ENV, STOP_GRACE_S, PipelineError
from strapdown_ros.pipeline.replay import replay_into_navigator
from strapdown_ros.pipeline.result import PipelineResult, ReplayResult
from strapdown_ros.pipeline.run import RECORDER_GRACE_S, STARTUP_TIMEOUT_S, run_pipeline

__all__ = [
    "PROFILE_ENV",
    "RECORDER_GRACE_S",
    "STARTUP_TIMEOUT_S",
    "STOP_GRACE_S",
    "PipelineError",
    "PipelineResult",
    "ReplayResult",
    "replay_into_navigator",
    "run_pipeline",
]
