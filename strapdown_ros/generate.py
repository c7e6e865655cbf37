"""``strapdown-sim generate``: every stream of a scenario, offline, into one rosbag2 directory.

This module only orchestrates: it feeds the pieces of the reference stream through the stages
of the chain (:mod:`strapdown_ros.plan.chain`) and writes what they return; the nodes run the
same stage objects, which is why the bag and the live topics carry identical messages.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from strapdown_ros.bag.cdr import TF_MESSAGE
from strapdown_ros.bag.selection import TopicSelection
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import Scenario
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.plan import Plan, resolve_plan
from strapdown_ros.plan.chain import feed_stages, offline_stages
from strapdown_ros.plan.metadata import bag_custom_data
from strapdown_ros.producer import Piece, Producer
from strapdown_ros.stages.tf import STATIC_QOS
from strapdown_ros.stages.trajectory import reference_batch_chunks
from strapdown_ros.topics import topic_lines

__all__ = [
    "DatasetSummary",
    "generate_dataset",
    "merge_residuals",
]

Progress = Callable[[str, int, int], None]


@dataclass
class DatasetSummary:
    """What ``generate`` wrote, for the summary table."""

    path: Path
    storage: str
    rate_hz: float
    cycles: int
    duration_s: float
    topics: dict[str, int] = field(default_factory=dict)
    residuals: dict[str, Residuals] = field(default_factory=dict)
    navigation: dict[str, float] = field(default_factory=dict)
    elapsed_s: float = 0.0

    def format(self) -> str:
        """Human-readable summary (duration, cycles, topics, counts, max one-step residuals)."""
        lines = [
            f"bag:       {self.path} ({self.storage})",
            f"duration:  {self.duration_s:.3f} s, {self.cycles} cycles at {self.rate_hz:g} Hz",
            f"elapsed:   {self.elapsed_s:.2f} s "
            f"({self.duration_s / max(self.elapsed_s, 1e-9):.0f}x real time)",
            "topics:",
        ]
        lines += topic_lines({t: f"{count:>9d} messages" for t, count in self.topics.items()})
        for name, res in self.residuals.items():
            ok = "ok" if res.within_spec() else "DEFECT"
            lines.append(
                f"max one-step residual ({name}): attitude {res.max_attitude:.2e} rad, "
                f"velocity {res.max_velocity:.2e} m/s, position {res.max_position:.2e} m [{ok}]"
            )
        if self.navigation:
            nav = self.navigation
            lines.append(
                f"navigator error at the end: horizontal {nav['horizontal_m']:.3e} m, vertical "
                f"{nav['vertical_m']:.3e} m (max horizontal {nav['max_horizontal_m']:.3e} m)"
            )
        return "\n".join(lines)


def generate_dataset(
    scenario: Scenario | Plan,
    out: str | Path,
    *,
    storage: str | None = None,
    compression: str | None = None,
    force: bool = False,
    progress: Progress | None = None,
) -> DatasetSummary:
    """Compute the scenario's streams and write them to the bag directory ``out``.

    The scenario and its trajectory are fully validated before anything is computed or written;
    the bag is written atomically (nothing is left at ``out`` on error) and an existing ``out``
    is only replaced with ``force``. The stages of the chain (:mod:`strapdown_ros.plan.chain`)
    run piece by piece in a forked producer while the bag writer writes the previous piece.
    ``storage``/``compression`` (None: ``recording.storage``/``recording.compression``): the
    storage plugin and MCAP chunk compression. Only the topics ``recording.include`` /
    ``recording.exclude`` select are written (:mod:`strapdown_ros.bag.selection`); every
    stage still runs.
    """
    start = time.perf_counter()
    plan = scenario if isinstance(scenario, Plan) else resolve_plan(scenario)
    scenario = plan.scenario
    storage = storage or scenario.recording.storage
    compression = compression or scenario.recording.compression
    selection = TopicSelection.of_recording(scenario.recording)
    written = set(selection.check(plan.topics))  # a pattern matching nothing is an error
    out = Path(out)
    # Fail early on the destination (BagWriter checks again when it opens).
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")
    plan.trajectory  # noqa: B018 - built (and validated) before anything is written
    total = plan.cycles
    summary = DatasetSummary(
        path=out,
        storage=storage,
        rate_hz=scenario.rate_hz,
        cycles=total,
        duration_s=plan.duration_s,
    )

    def pieces() -> Iterator[Piece]:
        stages = offline_stages(plan)
        navigator = dict(stages).get("navigator")
        leading = [b for _, s in stages for b in getattr(s, "leading_batches", list)()]
        for piece, batches in reference_batch_chunks(plan):
            res = {"reference": stream_residuals(piece)}
            batches = feed_stages(stages, batches)
            for _, stage in stages:
                res.update(getattr(stage, "take_residuals", dict)())
            nav_errors = navigator.final_errors if navigator is not None else {}
            if leading:  # e.g. /tf_static once, at t0, first
                batches, leading = [*leading, *batches], []
            yield Piece(piece.cycles, res, batches, nav_errors)

    producer = Producer(pieces())
    done = 0
    parts: dict[str, list[Residuals]] = {}
    latched = [p.topic for p in plan.topics.values() if p.key == "tf_static" and p.topic in written]
    try:
        custom_data = bag_custom_data(plan)
        with BagWriter(
            out, storage=storage, compression=compression, force=force, custom_data=custom_data
        ) as writer:
            for topic in latched:  # offered as a latched publisher's (ros2 bag play keeps it)
                writer.add_topic(topic, TF_MESSAGE, qos=STATIC_QOS)
            for cycles, res, batches, nav_errors in producer:  # type: ignore[misc]
                if len(written) < len(plan.topics):
                    batches = [b for b in batches if b.topic in written]
                writer.write_batches(batches)
                summary.navigation = nav_errors
                for name, r in res.items():
                    parts.setdefault(name, []).append(r)
                done += cycles
                if progress is not None:
                    progress("generating", done, total)
            summary.topics = dict(writer.message_counts)
    finally:
        producer.close()
    summary.residuals = {name: merge_residuals(r) for name, r in parts.items()}
    summary.elapsed_s = time.perf_counter() - start
    return summary


def merge_residuals(parts: list[Residuals]) -> Residuals:
    """Residuals of consecutive pieces as one (cycles in order)."""
    return Residuals(
        attitude=np.concatenate([p.attitude for p in parts]) if parts else np.zeros(0),
        velocity=np.concatenate([p.velocity for p in parts]) if parts else np.zeros(0),
        position=np.concatenate([p.position for p in parts]) if parts else np.zeros(0),
    )
