"""The computation of a campaign: what all runs share, computed once, and one run.

A run is ``generate``'s pipeline (the same stage objects, fed the same pieces in the same
order) restricted to what a campaign needs: the variation when it differs per run, the IMU
error model, the navigator, and the navigator's errors. What does not change between runs is
computed once in the client and sent to every worker (:attr:`CampaignPlan.shared_level`):

* ``variation``: the pieces of the navigator's inputs (the ideal IMU that the error model reads
  and the truth Odometry) — only the IMU errors (and navigator/aiding keys) vary;
* ``reference``: the pieces of the reference Imu/Odometry — the variation has a seed (random
  bending) or varied keys and is recomputed per run;
* ``none``: nothing (a varied key changes the reference itself).

Because every stage gives the same bits for any chunking and the pieces are those of
``generate``, run k's navigator errors equal those of ``strapdown-sim generate`` with run k's
overrides, bit for bit (``test/test_campaign.py``).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.campaign.plan import CampaignPlan
from strapdown_ros.campaign.results import RunResult, run_dir
from strapdown_ros.config import Scenario

__all__ = ["Shared", "run_one", "shared_inputs"]

#: Navigator error topics (recording.topics keys), in the column order of ERROR_COLUMNS.
ERROR_KEYS = ("navigator_error_position", "navigator_error_velocity", "navigator_error_attitude")


@dataclass
class Shared:
    """What every run of a campaign takes as given: ``pieces`` of serialized batches (only the
    topics the runs read) at the level ``level``; ``cycles``: the scenario's reference cycles."""

    level: str
    cycles: int
    pieces: list[list[Batch]] | None


def _keep(batches: Iterable[Batch], topics: set[str]) -> list[Batch]:
    return [b for b in batches if b.topic in topics]


def _reference_pieces(scenario: Scenario) -> tuple[int, Iterator[list[Batch]]]:
    from strapdown_ros.stages.reference import (
        build_trajectory,
        output_cycles,
        reference_batch_chunks,
    )

    trajectory = build_trajectory(scenario)
    cycles = output_cycles(scenario, trajectory)
    return cycles, (b for _, b in reference_batch_chunks(scenario, trajectory))


def _variation_stage(scenario: Scenario, cycles: int):  # noqa: ANN202
    from strapdown_ros.stages.variation import VariationStage

    return None if scenario.variation is None else VariationStage.offline(scenario, cycles)


def shared_inputs(plan: CampaignPlan) -> Shared:
    """Compute the part of the streams that all runs share (in this process, once)."""
    scenario = plan.base
    level = plan.shared_level
    if level == "none":
        return Shared(level, 0, None)
    cycles, pieces = _reference_pieces(scenario)
    topics = scenario.recording.topics
    if level == "reference":
        keep = {topics["reference_imu"], topics["reference_odom"]}
        return Shared(level, cycles, [_keep(p, keep) for p in pieces])
    from strapdown_ros.config.navigator import navigator_spec
    from strapdown_ros.stages.measurement import imu_model_topics

    nav = navigator_spec(scenario)
    keep = {imu_model_topics(scenario)[0]}
    if nav is not None and nav.truth_topic:
        keep.add(nav.truth_topic)
    variation = _variation_stage(scenario, cycles)
    out = []
    for batches in pieces:
        if variation is not None:
            batches = batches + variation.feed_batches(batches)
        out.append(_keep(batches, keep))
    return Shared(level, cycles, out)


def _errors(batches: list[Batch], topics: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Stamps and the (K, 9) error array from the navigator's error batches."""
    by_topic: dict[str, list[Batch]] = {}
    for b in batches:
        by_topic.setdefault(b.topic, []).append(b)
    columns, stamps = [], None
    for topic in topics:
        parts = by_topic.get(topic, [])
        if not parts:
            raise RuntimeError(f"the navigator produced no {topic} (no truth topic?)")
        payloads = [p for b in parts for p in b.payloads]
        fields = cdr.deserialize(cdr.VECTOR3_STAMPED, payloads)
        columns.append(np.asarray(fields.vector, dtype=np.float64))  # type: ignore[attr-defined]
        s = np.asarray(fields.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
        if stamps is not None and not np.array_equal(stamps, s):
            raise RuntimeError("the navigator error topics have different stamps")
        stamps = s
    assert stamps is not None
    return stamps, np.hstack(columns)


def run_one(shared: Shared, index: int, plan: CampaignPlan, bags_out: str | None) -> RunResult:
    """Compute run ``index`` (in a worker): its navigator errors at the navigation rate.

    With ``bags_out`` (the campaign's ``--out``), the run's full dataset is also written by
    ``generate`` to ``runs/NNNN/bag``.
    """
    from strapdown_ros.stages.measurement import generate_measured_stream
    from strapdown_ros.stages.navigation import NavigationStage

    start = time.perf_counter()
    spec = plan.run(index)
    scenario = plan.scenario(spec)
    if shared.pieces is None:
        cycles, pieces = _reference_pieces(scenario)
    else:
        cycles, pieces = shared.cycles, iter(shared.pieces)
    variation = _variation_stage(scenario, cycles) if shared.level != "variation" else None
    measured = generate_measured_stream(scenario)
    navigator = NavigationStage.for_scenario(scenario, period_ns=scenario.period_ns)
    topics = scenario.recording.topics
    error_topics = [topics[k] for k in ERROR_KEYS]
    out: list[Batch] = []
    for batches in pieces:  # generate's order: variation, measured IMU, navigator
        if variation is not None:
            batches = batches + variation.feed_batches(batches)
        if measured is not None:
            batches = batches + measured.feed_batches(batches)
        out += [b for b in navigator.feed_batches(batches) if b.topic in error_topics]
    stamps, errors = _errors(out, error_topics)
    bag = None
    if bags_out is not None:
        from strapdown_ros.generate import generate_dataset

        path = run_dir(Path(bags_out), index) / "bag"
        generate_dataset(scenario, path, force=True)
        bag = str(path)
    return RunResult(
        index=index,
        stamps_ns=stamps,
        errors=errors,
        seeds=spec.seeds,
        draws=spec.draws,
        overrides=spec.overrides,
        elapsed_s=time.perf_counter() - start,
        bag=bag,
    )
