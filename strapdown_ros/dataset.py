"""``strapdown-sim generate``: every stream of a scenario, offline, into one rosbag2 directory.

This module only orchestrates: the mathematics is in :mod:`strapdown_ros.core` and
:mod:`strapdown_ros.reference`, the messages in :mod:`strapdown_ros.messages`, the bag I/O in
:mod:`strapdown_ros.bag`. The trajectory node publishes the very batches built here
(:func:`reference_batches`), which is why the bag and the live topics carry identical messages.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from strapdown_ros.bag.batches import Batch, clock_batch, stream_batches
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.core.stream import Stream
from strapdown_ros.reference import build_trajectory, generate_reference
from strapdown_ros.scenario import Scenario

__all__ = ["DatasetSummary", "generate_dataset", "reference_batches"]

Progress = Callable[[str, int, int], None]


def reference_batches(scenario: Scenario, stream: Stream) -> list[Batch]:
    """Serialized ``/reference/*`` (and ``/clock`` if recording.clock) batches of a scenario."""
    rec = scenario.recording
    batches = stream_batches(
        stream,
        imu_topic=rec.topics["reference_imu"],
        odom_topic=rec.topics["reference_odom"],
        fix_topic=rec.topics["reference_fix"],
        body_frame=rec.frames["reference_imu"],
        earth_frame=rec.frames["earth"],
    )
    if rec.clock:
        batches.insert(0, clock_batch(stream.stamps_ns, rec.topics["clock"]))
    return batches


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
        width = max((len(t) for t in self.topics), default=0)
        for topic, count in self.topics.items():
            lines.append(f"  {topic:<{width}}  {count:>9d} messages")
        for name, res in self.residuals.items():
            ok = "ok" if res.within_spec() else "DEFECT"
            lines.append(
                f"max one-step residual ({name}): attitude {res.max_attitude:.2e} rad, "
                f"velocity {res.max_velocity:.2e} m/s, position {res.max_position:.2e} m [{ok}]"
            )
        return "\n".join(lines)


def generate_dataset(
    scenario: Scenario,
    out: str | Path,
    *,
    storage: str | None = None,
    force: bool = False,
    progress: Progress | None = None,
) -> DatasetSummary:
    """Compute the scenario's streams and write them to the bag directory ``out``.

    The scenario and its trajectory are fully validated before anything is computed or written;
    the bag is written atomically (nothing is left at ``out`` on error) and an existing ``out``
    is only replaced with ``force``.
    """
    start = time.perf_counter()
    storage = storage or scenario.recording.storage
    out = Path(out)
    # Fail early on the destination (BagWriter checks again when it opens).
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")

    def report(stage: str, done: int, total: int) -> None:
        if progress is not None:
            progress(stage, done, total)

    trajectory = build_trajectory(scenario)  # validates the kind's parameters
    report("reference", 0, 1)
    reference = generate_reference(scenario, trajectory)
    report("reference", 1, 1)
    batches = reference_batches(scenario, reference)
    summary = DatasetSummary(
        path=out,
        storage=storage,
        rate_hz=scenario.rate_hz,
        cycles=reference.cycles,
        duration_s=reference.cycles * reference.period,
    )
    summary.residuals["reference"] = stream_residuals(reference)
    with BagWriter(out, storage=storage, force=force) as writer:
        writer.write_batches(batches, progress=lambda d, t: report("writing", d, t))
        summary.topics = dict(writer.message_counts)
    summary.elapsed_s = time.perf_counter() - start
    return summary
