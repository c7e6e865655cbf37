"""``strapdown-sim generate``: every stream of a scenario, offline, into one rosbag2 directory.

This module only orchestrates: the mathematics is in :mod:`strapdown_ros.core` and
:mod:`strapdown_ros.reference`, the messages in :mod:`strapdown_ros.messages`, the bag I/O in
:mod:`strapdown_ros.bag`. The trajectory node publishes the very batches built here
(:func:`reference_batches`), which is why the bag and the live topics carry identical messages.
"""

from __future__ import annotations

import multiprocessing as mp
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, clock_batch, stream_batches
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.trajectory.base import Trajectory
from strapdown_ros.core.variation import OffsetArrays, generate_variation
from strapdown_ros.messages import (
    ImuFields,
    OdometryFields,
    imu_increments,
    odometry_state,
    stream_from_messages,
)
from strapdown_ros.reference import (
    build_trajectory,
    generate_reference_chunks,
    output_cycles,
)
from strapdown_ros.scenario import Scenario

__all__ = [
    "DatasetSummary",
    "generate_dataset",
    "merge_residuals",
    "reference_batch_chunks",
    "reference_batches",
]

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


def reference_batch_chunks(
    scenario: Scenario, trajectory: Trajectory | None = None
) -> Iterator[tuple[Stream, list[Batch]]]:
    """Pieces of the reference stream with their serialized batches, in stamp order.

    Consecutive pieces share one truth sample; it is published (and written) once, with the
    earlier piece. Concatenating the batches of all pieces gives exactly
    ``reference_batches(scenario, generate_reference(scenario))``.
    """
    for k, piece in enumerate(generate_reference_chunks(scenario, trajectory)):
        batches = reference_batches(scenario, piece)
        if k:
            batches = [_drop_up_to(b, piece.t0_ns) for b in batches]
        yield piece, batches


def _drop_up_to(b: Batch, stamp_ns: int) -> Batch:
    keep = int(np.searchsorted(b.stamps_ns, stamp_ns, side="right"))
    if keep == 0:
        return b
    return Batch(b.topic, b.msgtype, b.stamps_ns[keep:], b.payloads[keep:])


def decode_reference(scenario: Scenario, batches: list[Batch]) -> Stream:
    """The reference stream as a subscriber sees it: decoded from its Imu and Odometry payloads.

    The variation is computed from this (not from the generator's arrays) so that the offline
    path and ``variation_node``, which only has the messages, compute on identical numbers.
    """
    rec = scenario.recording
    by_topic = {b.topic: b for b in batches}
    imu = by_topic[rec.topics["reference_imu"]]
    odom = by_topic[rec.topics["reference_odom"]]
    return stream_from_messages(
        cdr.deserialize(imu.msgtype, imu.payloads),  # type: ignore[arg-type]
        cdr.deserialize(odom.msgtype, odom.payloads),  # type: ignore[arg-type]
        scenario.gravity_model,
        e0_epoch_ns=scenario.start_time_ns,
    )


def variation_settings(scenario: Scenario) -> tuple[int, str]:
    """``variation.method`` (default 2) and ``variation.gravity`` (default ``full``)."""
    cfg = scenario.variation or {}
    return int(cfg.get("method", 2)), str(cfg.get("gravity", "full"))


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
        method, gravity = variation_settings(scenario)
        data["variation.method"], data["variation.gravity"] = str(method), gravity
    if scenario.navigator is not None:
        from strapdown_ros.navigator import navigator_settings

        settings = navigator_settings(scenario)
        data["navigator.algorithm"], data["navigator.mode"] = settings.algorithm, settings.mode
    if scenario.imu_errors is not None:
        for key in ("preset", "seed"):
            if key in scenario.imu_errors:
                data[f"imu_errors.{key}"] = str(scenario.imu_errors[key])
    return data


def scenario_offsets(scenario: Scenario, samples: int) -> OffsetArrays:
    """Offsets of the scenario's ``variation`` section on the output cycle grid m = 0..N-1."""
    from strapdown_ros.core.offsets import offset_history

    history = offset_history(scenario.variation or {}, scenario.period_ns * 1e-9, samples - 1)
    return OffsetArrays(history.lever_arm, history.displacement, history.c_bvar_bref)


def variation_streams(scenario: Scenario, reference: Stream) -> tuple[Stream, Stream]:
    """The variation and the regenerated reference (zero offsets, same routines) of a scenario."""
    method, gravity = variation_settings(scenario)
    samples = reference.cycles + 1
    variation = generate_variation(reference, scenario_offsets(scenario, samples), method, gravity)
    regenerated = generate_variation(reference, OffsetArrays.zero(samples), method, gravity)
    return variation, regenerated


def variation_batches(scenario: Scenario, variation: Stream, regenerated: Stream) -> list[Batch]:
    """Serialized ``/variation/*`` and ``/variation/reference/*`` batches."""
    rec = scenario.recording
    frame = rec.frames["variation_imu"]
    batches = stream_batches(
        variation,
        imu_topic=rec.topics["variation_imu"],
        odom_topic=rec.topics["variation_odom"],
        fix_topic=rec.topics["variation_fix"],
        body_frame=frame,
        earth_frame=rec.frames["earth"],
    )
    batches += stream_batches(
        regenerated,
        imu_topic=rec.topics["variation_reference_imu"],
        odom_topic=rec.topics["variation_reference_odom"],
        fix_topic=None,
        body_frame=rec.frames["reference_imu"],
        earth_frame=rec.frames["earth"],
    )
    return batches


_END = "end"


def _produce(items: Iterator[object], out: object) -> None:
    """Producer body (thread or forked process): put every item, then _END or the exception."""
    try:
        for item in items:
            out.put(item)  # type: ignore[attr-defined]
        out.put(_END)  # type: ignore[attr-defined]
    except BaseException as exc:  # re-raised by the consumer
        out.put(exc)  # type: ignore[attr-defined]


class _Producer:
    """Computes the next pieces while the caller writes the previous ones.

    On Linux the producer is a forked process (true parallelism on the second core; the
    already-built trajectory is inherited, pieces come back pickled); elsewhere a thread.
    At most ``depth`` pieces wait in the queue, which bounds memory.
    """

    def __init__(self, items: Iterator[object], depth: int = 2) -> None:
        if "fork" in mp.get_all_start_methods():
            ctx = mp.get_context("fork")
            self._queue = ctx.Queue(maxsize=depth)
            self._worker: threading.Thread | mp.process.BaseProcess = ctx.Process(
                target=_produce, args=(items, self._queue), daemon=True
            )
        else:
            self._queue = queue.Queue(maxsize=depth)  # type: ignore[assignment]
            self._worker = threading.Thread(target=_produce, args=(items, self._queue), daemon=True)
        self._worker.start()

    def __iter__(self) -> Iterator[object]:
        while True:
            try:
                item = self._queue.get(timeout=1.0)
            except queue.Empty:
                if not self._worker.is_alive():
                    raise RuntimeError("the generator worker died without a result") from None
                continue
            if isinstance(item, str) and item == _END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item

    def close(self) -> None:
        """Stop the worker (if still running) and release the queue."""
        if isinstance(self._worker, threading.Thread):
            return  # a daemon thread; it ends with the iterator or the process
        if self._worker.is_alive():
            self._worker.terminate()
        self._worker.join(timeout=5)
        self._queue.close()


class _NavigatorStreamer:
    """The scenario's navigator fed piece by piece with the decoded messages of its input
    stream (as ``navigator_node`` is), returning the ``/navigator/*`` batches now complete."""

    def __init__(self, scenario: Scenario) -> None:
        from strapdown_ros.navigator import OUTPUT_TOPICS, navigator_settings

        self.scenario = scenario
        self.settings = navigator_settings(scenario)
        self.topics = {k: scenario.recording.topics[v] for k, v in OUTPUT_TOPICS.items()}
        self.run: object = None
        self.final_errors: dict[str, float] = {}

    def feed(self, batches: list[Batch]) -> list[Batch]:
        """Take one piece's batches; return the navigator batches now computable."""
        from strapdown_ros.navigator import (
            NavigatorRun,
            initial_state_from_scenario,
            initial_state_from_truth,
        )

        st = self.settings
        by_topic = {b.topic: b for b in batches}
        truth = None
        if st.truth_topic and st.truth_topic in by_topic and by_topic[st.truth_topic].payloads:
            b = by_topic[st.truth_topic]
            truth = odometry_state(cdr.deserialize(b.msgtype, b.payloads))
        if self.run is None:
            period = self.scenario.period_ns
            if st.initialization == "truth":
                if truth is None:
                    return []
                initial = initial_state_from_truth(truth, 0, st)
                start, omega = int(truth.stamps_ns[0]), truth.omega_eb_b[0]
            else:
                assert self.scenario.initial is not None
                initial = initial_state_from_scenario(self.scenario.initial.as_dict(), st)
                start, omega = self.scenario.start_time_ns, None
            self.run = NavigatorRun(
                st, start, period, initial, bool(st.truth_topic), omega,
                self.scenario.recording.frames["earth"],
            )  # fmt: skip
        run: NavigatorRun = self.run  # type: ignore[assignment]
        if truth is not None:
            run.add_truth(truth)
        if st.imu_topic in by_topic and by_topic[st.imu_topic].payloads:
            b = by_topic[st.imu_topic]
            inc = imu_increments(cdr.deserialize(b.msgtype, b.payloads), self.scenario.period_ns)
            run.add_imu(inc.stamps_ns, inc.dalpha, inc.dv)
        out = run.outputs()
        if out is None:
            return []
        if out.error_position is not None:
            dr = np.asarray(out.error_position.vector)
            self.final_errors = {
                "horizontal_m": float(np.hypot(dr[-1, 0], dr[-1, 1])),
                "vertical_m": float(abs(dr[-1, 2])),
                "max_horizontal_m": max(
                    self.final_errors.get("max_horizontal_m", 0.0),
                    float(np.hypot(dr[:, 0], dr[:, 1]).max()),
                ),
            }
        return [batch(self.topics[k], f) for k, f in out.items()]


class _VariationStreamer:
    """Variation and regenerated reference computed piece by piece as the reference arrives.

    Works on the decoded reference messages (like ``variation_node``) and on windows that start
    one cycle before the last emitted even cycle (``lead=1``): the windows give bit-identical
    results to one vectorized run over the whole stream (Method 2 pairs are independent).
    """

    def __init__(self, scenario: Scenario, total: int) -> None:
        self.scenario = scenario
        self.method, self.gravity = variation_settings(scenario)
        self.offsets = scenario_offsets(scenario, total + 1)
        self.zero = OffsetArrays.zero(total + 1)
        self.imu: ImuFields | None = None
        self.odom: OdometryFields | None = None
        self.emitted = -1  # last variation cycle published (even), -1: none yet
        self.base = 0  # cycle of self.odom's first row (self.imu's first row is cycle base + 1)
        rec = scenario.recording
        self.imu_topic = rec.topics["reference_imu"]
        self.odom_topic = rec.topics["reference_odom"]

    def feed(self, batches: list[Batch], res: dict[str, Residuals]) -> list[Batch]:
        """Take one reference piece's batches; return the variation batches now computable."""
        by_topic = {b.topic: b for b in batches}
        imu_b, odom_b = by_topic[self.imu_topic], by_topic[self.odom_topic]
        imu = cdr.deserialize(imu_b.msgtype, imu_b.payloads)
        odom = cdr.deserialize(odom_b.msgtype, odom_b.payloads)
        self.imu = imu if self.imu is None else self.imu.append(imu)  # type: ignore[union-attr]
        self.odom = odom if self.odom is None else self.odom.append(odom)  # type: ignore[union-attr]
        avail = self.base + len(self.odom) - 1  # reference cycles base..avail are held
        last = (avail - 1) - (avail - 1) % 2  # last even cycle with its look-ahead sample
        if last < 2 or last <= self.emitted:
            return []
        lead = 0 if self.emitted < 0 else 1
        a = 0 if lead == 0 else self.emitted - 1
        b0 = self.base
        window = stream_from_messages(
            self.imu.rows(a - b0, last + 1 - b0),  # type: ignore[union-attr]
            self.odom.rows(a - b0, last + 2 - b0),
            self.scenario.gravity_model,
            e0_epoch_ns=self.scenario.start_time_ns,
        )
        sl = slice(a, last + 2)
        off = OffsetArrays(
            self.offsets.lever_arm[sl], self.offsets.displacement[sl], self.offsets.c_bvar_bref[sl]
        )
        zero = OffsetArrays(
            self.zero.lever_arm[sl], self.zero.displacement[sl], self.zero.c_bvar_bref[sl]
        )
        variation = generate_variation(window, off, self.method, self.gravity, lead)
        regenerated = generate_variation(window, zero, self.method, self.gravity, lead)
        res["variation"] = stream_residuals(variation)
        res["variation/reference"] = stream_residuals(regenerated)
        out = variation_batches(self.scenario, variation, regenerated)
        if lead:
            out = [_drop_up_to(b, variation.t0_ns) for b in out]  # truth already published
        self.emitted = last
        # keep only what the next window (from cycle last - 1) needs: memory stays bounded
        keep = last - 1 - self.base
        self.odom = self.odom.rows(keep, len(self.odom))
        self.imu = self.imu.rows(keep, len(self.imu))  # type: ignore[union-attr]
        self.base = last - 1
        return out


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
    from strapdown_ros.imu_model import generate_measured_stream

    measured = generate_measured_stream(scenario)  # validates imu_errors' topics first

    def pieces() -> Iterator[tuple[int, dict[str, Residuals], list[Batch]]]:
        streamer = None if scenario.variation is None else _VariationStreamer(scenario, total)
        navigator = None if scenario.navigator is None else _NavigatorStreamer(scenario)
        for piece, batches in reference_batch_chunks(scenario, trajectory):
            res = {"reference": stream_residuals(piece)}
            if streamer is not None:
                batches = batches + streamer.feed(batches, res)
            if measured is not None:  # issue 7: before the navigator, which may consume it
                batches = batches + measured.feed_batches(batches)
            nav_errors: dict[str, float] = {}
            if navigator is not None:
                batches = batches + navigator.feed(batches)
                nav_errors = navigator.final_errors
            yield piece.cycles, res, batches, nav_errors

    producer = _Producer(pieces())
    done = 0
    parts: dict[str, list[Residuals]] = {}
    try:
        custom_data = bag_custom_data(scenario)
        with BagWriter(out, storage=storage, force=force, custom_data=custom_data) as writer:
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
