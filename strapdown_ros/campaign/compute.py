"""The computation of a campaign: what all runs share, computed once, and one run.

A run is ``generate``'s chain (the same stage objects, fed the same pieces in the same order)
restricted to what a campaign needs: the links its results (the navigator's errors) depend on
(:func:`strapdown_ros.plan.chain.links_for`). What does not change between runs is
computed once in the client and sent to every worker (:attr:`Campaign.shared_level`):

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
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.campaign.results import RunResult, run_dir
from strapdown_ros.campaign.runs import Campaign
from strapdown_ros.plan import Plan, resolve_plan
from strapdown_ros.plan.chain import feed_stages, link, links_for, offline_stages
from strapdown_ros.stages.trajectory import reference_batch_chunks

__all__ = ["Shared", "run_links", "run_one", "shared_inputs"]

#: Navigator error topics (recording.topics keys), in the column order of ERROR_COLUMNS.
ERROR_KEYS = ("navigator_error_position", "navigator_error_velocity", "navigator_error_attitude")


@dataclass
class Shared:
    """What every run of a campaign takes as given: ``pieces`` of serialized batches (only the
    topics the runs read) at the level ``level``; ``cycles``: the scenario's reference cycles."""

    level: str
    cycles: int
    pieces: list[list[Batch]] | None


#: Chain links computed once for all runs at each shared level (Campaign.shared_level).
SHARED_LINKS: dict[str, tuple[str, ...]] = {
    "variation": ("trajectory", "variation"),
    "reference": ("trajectory",),
    "none": (),
}
#: The links whose outputs a run's results are made of.
RESULT_LINKS = ("navigator",)


def run_links(plan: Plan, level: str) -> list[str]:
    """The chain links each run computes itself: those the results need that are not shared."""
    shared = SHARED_LINKS[level]
    have = {t for t, p in plan.topics.items() if p.link in shared}
    return [n for n in links_for(plan, RESULT_LINKS, have) if n not in shared]


def shared_inputs(campaign: Campaign) -> Shared:
    """Compute the part of the streams that all runs share (in this process, once)."""
    level = campaign.shared_level
    shared = SHARED_LINKS[level]
    if not shared:
        return Shared(level, 0, None)
    plan = resolve_plan(campaign.base)
    produced = {t for t, p in plan.topics.items() if p.link in shared}
    keep = {t for n in run_links(plan, level) for t in link(n).inputs(plan)} & produced
    stages = offline_stages(plan, shared)
    pieces = [
        [b for b in feed_stages(stages, batches) if b.topic in keep]
        for _, batches in reference_batch_chunks(plan)
    ]
    return Shared(level, plan.cycles, pieces)


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


def run_one(shared: Shared, index: int, campaign: Campaign, bags_out: str | None
            ) -> RunResult:  # fmt: skip
    """Compute run ``index`` (in a worker): its navigator errors at the navigation rate.

    With ``bags_out`` (the campaign's ``--out``), the run's full dataset is also written by
    ``generate`` to ``runs/NNNN/bag``.
    """
    start = time.perf_counter()
    spec = campaign.run(index)
    plan = resolve_plan(campaign.scenario(spec))
    if shared.pieces is None:
        pieces: Iterable[list[Batch]] = (b for _, b in reference_batch_chunks(plan))
    else:
        pieces = shared.pieces
    stages = offline_stages(plan, run_links(plan, shared.level))
    topics = plan.scenario.recording.topics
    error_topics = [topics[k] for k in ERROR_KEYS]
    out: list[Batch] = []
    for batches in pieces:  # generate's order (the chain's)
        out += [b for b in feed_stages(stages, batches) if b.topic in error_topics]
    stamps, errors = _errors(out, error_topics)
    bag = None
    if bags_out is not None:
        from strapdown_ros.generate import generate_dataset

        path = run_dir(Path(bags_out), index) / "bag"
        generate_dataset(plan, path, force=True)
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
