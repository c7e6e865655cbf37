"""``strapdown-sim generate``: every stream of a scenario, offline, into one rosbag2 directory.

This module only orchestrates: the mathematics is in :mod:`strapdown_ros.core` and
:mod:`strapdown_ros.stages.reference`, the messages in :mod:`strapdown_ros.messages`, the bag I/O in
:mod:`strapdown_ros.bag`. The trajectory node publishes the very batches built here
(:func:`reference_batches`), which is why the bag and the live topics carry identical messages.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from strapdown_ros.bag.cdr import TF_MESSAGE
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import Scenario
from strapdown_ros.config.navigator import navigator_spec
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.producer import Piece, Producer
from strapdown_ros.stages.aiding import (
    aiding_custom_data,
    aiding_spec,
    generate_aiding_stream,
)
from strapdown_ros.stages.frames import STATIC_QOS, FramesStage, static_topic
from strapdown_ros.stages.navigation import NavigationStage
from strapdown_ros.stages.reference import (
    build_trajectory,
    output_cycles,
    reference_batch_chunks,
)
from strapdown_ros.stages.variation import VariationStage

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
        width = max((len(t) for t in self.topics), default=0)
        for topic, count in self.topics.items():
            lines.append(f"  {topic:<{width}}  {count:>9d} messages")
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










def bag_custom_data(scenario: Scenario) -> dict[str, str]:
    """The bag metadata ``custom_data`` describing how a scenario's streams were made.

    ``generator``, ``scenario`` (name), ``rate_hz``, the gravitation model and, for the sections
    the scenario has, ``variation.method`` / ``variation.gravity``, ``navigator.algorithm`` /
    ``navigator.mode`` and ``imu_errors.preset`` / ``imu_errors.seed``; ``strapdown-sim
    report`` names the variation method from it. Written by ``generate`` and ``bag_recorder``.
    """
    data = {
        "generator": "strapdown_ros",
        "scenario": scenario.name,
        "rate_hz": f"{scenario.rate_hz:g}",
        "gravity_model": str(scenario.gravity_model),
    }
    if scenario.variation is not None:
        spec = scenario.variation
        data["variation.method"], data["variation.gravity"] = str(spec.method), spec.gravity
    nav = navigator_spec(scenario)
    if nav is not None:
        data["navigator.algorithm"], data["navigator.mode"] = nav.algorithm, str(nav.mode)
    if scenario.imu_errors is not None:
        for key in ("preset", "seed"):  # the ones the file gives
            if key in scenario.imu_errors.model_fields_set:
                data[f"imu_errors.{key}"] = str(getattr(scenario.imu_errors, key))
    data.update(aiding_custom_data(aiding_spec(scenario)))
    return data








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
    is only replaced with ``force``. The computation runs piece by piece in a producer thread
    while the bag writer writes the previous piece.
    """
    start = time.perf_counter()
    storage = storage or scenario.recording.storage
    out = Path(out)
    # Fail early on the destination (BagWriter checks again when it opens).
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")
    trajectory = build_trajectory(scenario)  # validates the kind's parameters
    total = output_cycles(scenario, trajectory)
    summary = DatasetSummary(
        path=out,
        storage=storage,
        rate_hz=scenario.rate_hz,
        cycles=total,
        duration_s=total * scenario.period_ns * 1e-9,
    )

    # --- issue 7: /variation/imu_measured (the imu_errors model on its ideal input topic) ---
    from strapdown_ros.stages.measurement import generate_measured_stream

    measured = generate_measured_stream(scenario)

    # --- issue 16: aiding sensors from /reference/odom (docs/aiding.md) ---
    aiding = generate_aiding_stream(scenario)

    def pieces() -> Iterator[Piece]:
        streamer = None if scenario.variation is None else VariationStage.offline(scenario, total)
        navigator = None
        if scenario.navigator is not None:
            navigator = NavigationStage.for_scenario(scenario, period_ns=scenario.period_ns)
        # TF, map-frame odometry and increments of every stage's output (docs/interface.md)
        offsets = None if streamer is None else streamer.offsets
        frames = FramesStage(scenario, offsets=offsets, cycles=total)
        static = frames.static_batch()
        for piece, batches in reference_batch_chunks(scenario, trajectory):
            res = {"reference": stream_residuals(piece)}
            if streamer is not None:
                batches = batches + streamer.feed_batches(batches, res)
            if measured is not None:  # issue 7: before the navigator, which may consume it
                batches = batches + measured.feed_batches(batches)
            nav_errors: dict[str, float] = {}
            if navigator is not None:
                batches = batches + navigator.feed_batches(batches)
                nav_errors = navigator.final_errors
            if aiding is not None:  # issue 16: from /reference/odom, after every other stream
                batches = batches + aiding.feed_batches(batches)
            batches = batches + frames.feed_batches(batches)
            if static is not None:  # /tf_static once, at t0, first
                batches, static = [static, *batches], None
            yield Piece(piece.cycles, res, batches, nav_errors)

    producer = Producer(pieces())
    done = 0
    parts: dict[str, list[Residuals]] = {}
    try:
        custom_data = bag_custom_data(scenario)
        with BagWriter(out, storage=storage, force=force, custom_data=custom_data) as writer:
            tf_static = static_topic(scenario)
            if tf_static is not None:  # offered as a latched publisher's (ros2 bag play keeps it)
                writer.add_topic(tf_static, TF_MESSAGE, qos=STATIC_QOS)
            for cycles, res, batches, nav_errors in producer:  # type: ignore[misc]
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
