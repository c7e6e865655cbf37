"""The reference stream of a scenario: trajectory model → Method 2 regeneration → output rate.

This is the offline path shared by ``strapdown-sim generate`` and ``trajectory_node`` (which
publishes exactly these messages). ROS-free: numpy and the core only.

Steps (docs/interface.md §2-§3, Savage 2020):

1. Build the trajectory model of ``trajectory.kind`` (validated; errors name the key).
2. ``increments`` kind: integrate Savage's constant-rate segments directly (exact by
   construction). Every other kind: sample the continuous truth at the generation instants,
   convert it to E0 and regenerate it through Method 2 with zero offsets (eqs. (8), (23)-(31)
   with S = 0, C_Bvar^Bref = I), which makes increments and truth obey eqs. (2)-(4).
3. ``oversample`` > 1: output increments are sums of ``oversample`` generation increments (what a
   real IMU reports) and the truth is the generation truth at the output instants.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, clock_batch
from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.config.trajectory import IncrementsTrajectorySpec, core_initial
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.method2 import method2, pair_displacement
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.trajectory.base import TrajectoryError, local_to_e0
from strapdown_ros.messages import stream_from_messages
from strapdown_ros.plan.model import Plan
from strapdown_ros.plan.resolve import resolve_plan
from strapdown_ros.stages.recording_batches import named_stream_batches

__all__ = [
    "as_plan",
    "decimate",
    "concatenate_streams",
    "generate_reference",
    "generate_reference_chunks",
    "smooth_displacement",
]


def as_plan(source: Plan | Scenario) -> Plan:
    """``source`` itself, or the plan of a scenario (for scripts and tests that start from a
    scenario; ``generate`` and the nodes resolve theirs once and pass it)."""
    return source if isinstance(source, Plan) else resolve_plan(source)


#: Largest disagreement (m) between a model's position differences and Simpson's rule on its
#: velocity for which the Simpson displacement is used (20 % of the docs/interface.md §3 position
#budget).
DISPLACEMENT_TOLERANCE_M = 2e-8


def smooth_displacement(r_e0: np.ndarray, v_e0: np.ndarray, period: float) -> np.ndarray | None:
    """Pair displacements for Method 2 without coordinate rounding noise, when consistent.

    Uses :func:`~strapdown_ros.core.method2.pair_displacement` (Simpson's rule on the velocity)
    when it agrees with the model's own position differences to
    :data:`DISPLACEMENT_TOLERANCE_M`; otherwise (a model whose velocity is not the derivative
    of its position) returns ``None`` so Method 2 uses the position differences themselves.
    """
    disp = pair_displacement(v_e0, period)
    pairs = disp.shape[0]
    diff = r_e0[2 : 2 * pairs + 1 : 2] - r_e0[0 : 2 * pairs - 1 : 2]
    if pairs and np.max(np.abs(diff - disp)) > DISPLACEMENT_TOLERANCE_M:
        return None
    return disp


def decimate(stream: Stream, factor: int) -> Stream:
    """Output-rate stream: sums of ``factor`` generation increments, truth at output instants.

    docs/interface.md §2: output increments are sums of generation increments (what a real IMU
    reports);
    the truth is the generation truth sampled at the output instants.
    """
    if factor == 1:
        return stream
    m = stream.cycles // factor
    n = m * factor
    return replace(
        stream,
        period_ns=stream.period_ns * factor,
        dalpha=stream.dalpha[:n].reshape(m, factor, 3).sum(axis=1),
        dv=stream.dv[:n].reshape(m, factor, 3).sum(axis=1),
        c_b_e0=stream.c_b_e0[: n + 1 : factor],
        v_e0=stream.v_e0[: n + 1 : factor],
        r_e0=stream.r_e0[: n + 1 : factor],
    )


#: Output cycles per chunk of the offline path (even, so Method 2 pairs never straddle chunks).
#: Every chunk is computed independently (Method 2 pairs only depend on their constraints), so
#: the chunking changes neither the results nor the messages; it bounds memory and lets the
#: bag writer overlap the computation.
CHUNK_CYCLES = 20_000
#: The first chunk is short so that a consumer (the bag writer) can start early; the next ones
#: double in length up to CHUNK_CYCLES.
FIRST_CHUNK_CYCLES = 2_000


def _chunk_bounds(total: int, chunk_cycles: int, first_cycles: int) -> Iterator[tuple[int, int]]:
    """Chunks of ``first_cycles``, doubling up to ``chunk_cycles`` (all even): the consumer
    starts early and, while it writes a chunk, the next (twice as long) is computed."""
    m0 = 0
    size = min(first_cycles, chunk_cycles)
    while m0 < total:
        m1 = min(m0 + size, total)
        yield m0, m1
        m0, size = m1, min(2 * size, chunk_cycles)


def generate_reference_chunks(
    source: Plan | Scenario,
    chunk_cycles: int = CHUNK_CYCLES,
    first_cycles: int = FIRST_CHUNK_CYCLES,
    workers: int = 1,
) -> Iterator[Stream]:
    """The reference stream of ``scenario`` in consecutive pieces at the output rate.

    Piece k covers output cycles ``m0..m1`` (truth at m0..m1, increments of m0+1..m1) with
    ``m0`` of piece k equal to ``m1`` of piece k-1: consecutive pieces share one truth sample.
    """
    if chunk_cycles < 2 or chunk_cycles % 2 or first_cycles < 2 or first_cycles % 2:
        raise ValueError(
            f"chunk sizes must be even and >= 2, got {chunk_cycles} and {first_cycles}"
        )
    plan = as_plan(source)
    scenario = plan.scenario
    spec = scenario.trajectory
    trajectory = plan.trajectory
    out_cycles = plan.cycles
    oversample = scenario.oversample
    gen_period_ns = scenario.generation_period_ns
    model = scenario.gravity_model

    if trajectory is None:  # kind: increments, exact by construction (sequential integration)
        from strapdown_ros.core.trajectory.increments import generate_increments_stream

        assert isinstance(spec, IncrementsTrajectorySpec) and scenario.initial is not None
        try:
            full = generate_increments_stream(
                *core_initial(scenario.initial),
                spec.core_segments(),
                gen_period_ns,
                scenario.start_time_ns,
                gravity_model=model,
            )
        except TrajectoryError as exc:
            raise ScenarioError(spec.key_of(exc.where), exc.problem) from None
        full = decimate(_truncate(full, out_cycles * oversample), oversample)
        for m0, m1 in _chunk_bounds(out_cycles, chunk_cycles, first_cycles):
            yield full.window(m0, m1)
        return

    period = gen_period_ns * 1e-9

    def chunk(bounds: tuple[int, int]) -> Stream:
        m0, m1 = bounds
        g0, g1 = m0 * oversample, m1 * oversample  # g0 is even: pairs align across chunks
        t = np.arange(g0, g1 + 1, dtype=np.int64) * gen_period_ns * 1e-9
        # Trajectories that know their E0 truth directly (samples) skip the geodetic round trip.
        if hasattr(trajectory, "truth_e0"):
            truth = trajectory.truth_e0(t)
        else:
            truth = local_to_e0(trajectory.local_truth(t))
        solution = method2(
            truth.c_b_e0,
            truth.r_e0,
            truth.v_e0,
            period,
            lambda r: gravitation(r, model),
            displacement=smooth_displacement(truth.r_e0, truth.v_e0, period),
        )
        stream = Stream(
            t0_ns=scenario.start_time_ns + g0 * gen_period_ns,
            period_ns=gen_period_ns,
            dalpha=solution.dalpha,
            dv=solution.dv,
            c_b_e0=solution.c_b_e0,
            v_e0=solution.v_e0,
            r_e0=solution.r_e0,
            gravity_model=model,
            e0_epoch_ns=scenario.start_time_ns,
        )
        return decimate(stream, oversample)

    bounds = _chunk_bounds(out_cycles, chunk_cycles, first_cycles)
    if workers <= 1:
        yield from map(chunk, bounds)
        return
    # Chunks are independent: compute them on ``workers`` threads (numpy and the compiled
    # kernels release the GIL), in order, at most ``workers`` ahead.
    with ThreadPoolExecutor(workers) as pool:
        pending: deque[Future[Stream]] = deque()
        for b in bounds:
            pending.append(pool.submit(chunk, b))
            if len(pending) > workers:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


def concatenate_streams(pieces: Iterable[Stream]) -> Stream:
    """Join consecutive pieces of :func:`generate_reference_chunks` (shared samples once)."""
    pieces = list(pieces)
    if not pieces:
        raise ValueError("no stream pieces to concatenate")
    first = pieces[0]
    return replace(
        first,
        dalpha=np.concatenate([p.dalpha for p in pieces]),
        dv=np.concatenate([p.dv for p in pieces]),
        c_b_e0=np.concatenate([first.c_b_e0] + [p.c_b_e0[1:] for p in pieces[1:]]),
        v_e0=np.concatenate([first.v_e0] + [p.v_e0[1:] for p in pieces[1:]]),
        r_e0=np.concatenate([first.r_e0] + [p.r_e0[1:] for p in pieces[1:]]),
    )


def generate_reference(source: Plan | Scenario, workers: int | None = None) -> Stream:
    """The reference stream of a plan (or scenario) at its output rate (docs/interface.md
    §2-§3), in one piece; chunks on ``workers`` threads (default: up to 2)."""
    workers = min(2, os.cpu_count() or 1) if workers is None else workers
    return concatenate_streams(generate_reference_chunks(source, workers=workers))


def _truncate(stream: Stream, cycles: int) -> Stream:
    if stream.cycles < cycles:
        raise ScenarioError(
            "duration_s", f"the increments segments cover only {stream.cycles} cycles"
        )
    return stream.window(0, cycles)


def reference_batches(scenario: Scenario, stream: Stream) -> list[Batch]:
    """Serialized ``/reference/*`` (and ``/clock`` if recording.clock) batches of a scenario."""
    rec = scenario.recording
    batches = named_stream_batches(scenario, stream, "reference", "reference_imu")
    if rec.clock:
        batches.insert(0, clock_batch(stream.stamps_ns, rec.topics["clock"]))
    return batches


def reference_batch_chunks(source: Plan | Scenario) -> Iterator[tuple[Stream, list[Batch]]]:
    """Pieces of the reference stream with their serialized batches, in stamp order.

    Consecutive pieces share one truth sample; it is published (and written) once, with the
    earlier piece. Concatenating the batches of all pieces gives exactly
    ``reference_batches(scenario, generate_reference(plan))``.
    """
    plan = as_plan(source)
    scenario = plan.scenario
    for k, piece in enumerate(generate_reference_chunks(plan)):
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
