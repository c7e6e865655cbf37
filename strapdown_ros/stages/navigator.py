"""The navigation stage: the navigator on messages, for ``generate`` and ``navigator_node``.

:class:`NavigatorStage` is the one streaming implementation: it takes the Imu and truth
Odometry messages of its input (raw payloads or decoded fields, in any chunking), checks them
(period, gaps, order, repeats, frames), runs the navigator of :mod:`strapdown_ros.core.
navigation` over each contiguous stretch (:class:`NavigatorRun`) and returns the serialized
``/navigator/*`` messages now complete. Conventions (runs, stamps, errors, ``/navigator/odom``):
docs/navigator.md; the node's behaviour: docs/nodes.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch, merge_order
from strapdown_ros.config import Initial, Scenario, navigator_spec
from strapdown_ros.config.navigator import INPUT_STREAMS, OUTPUT_TOPICS, NavigatorSpec
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.navigation import (
    MultirateNavigator,
    NavSolution,
    NavState,
    SimultaneousNavigator,
    VerticalDamping,
)
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    euler_from_dcm,
    quat_from_dcm,
)
from strapdown_ros.messages import (
    SERVICE_UNKNOWN,
    STATUS_NO_FIX,
    EarthState,
    ImuFields,
    NavSatFixFields,
    OdometryFields,
    Vector3StampedFields,
    imu_increments,
    navsatfix_fields_from_geodetic,
    odometry_fields_from_ecef,
    odometry_state,
    vector3_stamped_fields,
)
from strapdown_ros.stages.intake import (
    InputEvents,
    decode_one,
    format_stamp,
    nonfinite_rows,
    quiet,
    screen,
    stamp_verdict,
    stretches,
    without_rows,
)

__all__ = [
    "INPUT_STREAMS",
    "OUTPUT_TOPICS",
    "NavigatorStage",
    "NavigatorOutputs",
    "NavigatorRun",
    "StreamError",
    "build_navigator",
    "initial_state_from_scenario",
    "initial_state_from_truth",
    "navigate_messages",
]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Log = Callable[[str], None]
Message = tuple[str, int, bytes]

#: Truth messages kept for (re)starting runs.
TRUTH_KEEP = 4096
class StreamError(ValueError):
    """The input messages cannot be integrated as they are (gap, out of order, wrong rate)."""


def build_navigator(
    spec: NavigatorSpec, initial: NavState, t_gyr: float, n: int | None = None
) -> MultirateNavigator | SimultaneousNavigator:
    """The core navigator of a resolved ``spec`` starting at ``initial``.

    ``t_gyr``: IMU period (s); ``n``: N (default ``spec.n``; ``navigator_node`` may derive it
    from ``nav_period_s``).
    """
    n = spec.n if n is None else n
    vd = spec.vertical_damping
    damping = None
    if vd is not None:
        damping = VerticalDamping(k1=vd.k1, k2=vd.k2, paper_signs=vd.paper_signs)
    gravity = str(spec.gravity_model)
    if spec.algorithm == "simultaneous":
        return SimultaneousNavigator(
            initial, t_gyr, n, gravity, spec.normalize_quaternion, spec.table1_radii, damping
        )
    return MultirateNavigator(
        initial, t_gyr, n, spec.p, mode=str(spec.mode), gravity_model=gravity,
        normalize=spec.normalize_quaternion, table1_radii=spec.table1_radii, damping=damping,
    )  # fmt: skip


# --------------------------------------------------------------------------------------------
# Truth and initialization
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Truth:
    """Truth rows in navigation terms (from Odometry messages): ECEF position (m), geodetic
    latitude, longitude (rad), altitude (m), NED velocity (m/s), ``C_B^N``, body rate relative
    to the Earth (rad/s, FRD)."""

    r_e: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    c_b_n: F64
    omega_eb_b: F64


def _truth(state: EarthState) -> _Truth:
    lat, lon, alt = ecef_to_geodetic(state.r_e)
    c_e_n = dcm_ecef_to_ned(lat, lon)
    return _Truth(
        state.r_e,
        lat,
        lon,
        alt,
        np.einsum("nij,nj->ni", c_e_n, state.v_e),
        c_e_n @ state.c_b_e,
        state.omega_eb_b,
    )


def _rows(state: EarthState, rows: slice | NDArray[np.intp]) -> EarthState:
    return EarthState(*(np.asarray(a)[rows] for a in state))


def initial_state_from_truth(
    truth: EarthState, row: int, spec: NavigatorSpec, t: float = 0.0
) -> NavState:
    """The initial state from truth row ``row`` plus the spec's initial errors.

    Position error: NED metres in the true local level, applied in ECEF; velocity error: NED;
    attitude error: offsets of roll, pitch and heading (Euler angles of ``C_B^N``).
    """
    tr = _truth(_rows(truth, slice(row, row + 1)))
    r = tr.r_e[0] + dcm_ned_to_ecef(tr.lat[0], tr.lon[0]) @ spec.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    c = tr.c_b_n[0]
    att = spec.attitude_error_rph
    if np.any(att):
        c = dcm_from_euler(*(np.asarray(euler_from_dcm(c)) + att))
    return NavState(
        float(t), float(lat), float(lon), float(alt),
        tr.v_ned[0] + spec.velocity_error_ned, quat_from_dcm(c),
    )  # fmt: skip


def initial_state_from_scenario(initial: Initial, spec: NavigatorSpec) -> NavState:
    """The initial state from a scenario's ``initial`` (the reference IMU at t0) plus the
    spec's initial errors (see :func:`initial_state_from_truth`)."""
    lat, lon = np.radians(initial.latitude_deg), np.radians(initial.longitude_deg)
    alt = float(initial.altitude_m)
    r = geodetic_to_ecef(lat, lon, alt) + dcm_ned_to_ecef(lat, lon) @ spec.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    rph = np.radians(np.asarray(initial.attitude_rph_deg, dtype=np.float64))
    v = np.asarray(initial.velocity_ned_mps, dtype=np.float64) + spec.velocity_error_ned
    c = dcm_from_euler(*(rph + spec.attitude_error_rph))
    return NavState(0.0, float(lat), float(lon), float(alt), v, quat_from_dcm(c))


# --------------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------------


@dataclass
class NavigatorOutputs:
    """Fields of the navigator topics for consecutive output stamps (errors: None without
    truth)."""

    odom: OdometryFields
    fix: NavSatFixFields
    error_position: Vector3StampedFields | None = None
    error_velocity: Vector3StampedFields | None = None
    error_attitude: Vector3StampedFields | None = None

    def __len__(self) -> int:
        return len(self.odom)

    def items(self) -> list[tuple[str, object]]:
        """``(output key, fields)`` of the topics present (keys of :data:`OUTPUT_TOPICS`)."""
        return [(k, getattr(self, k)) for k in OUTPUT_TOPICS if getattr(self, k) is not None]


def _output_fields(
    stamps: I64,
    sol: NavSolution,
    omega_eb_b: F64,
    truth: _Truth | None,
    frame_id: str,
    earth_frame: str,
) -> NavigatorOutputs:
    r_e = geodetic_to_ecef(sol.lat, sol.lon, sol.alt)
    c_n_e = dcm_ned_to_ecef(sol.lat, sol.lon)
    v_e = np.einsum("nij,nj->ni", c_n_e, sol.v_ned)
    c_b_n = dcm_from_quat(sol.q_b_n)
    out = NavigatorOutputs(
        odometry_fields_from_ecef(
            stamps, r_e, v_e, c_n_e @ c_b_n, omega_eb_b, frame_id, earth_frame
        ),  # fmt: skip
        # an inertial-only position: no GNSS fix claimed (docs/interface.md §4)
        navsatfix_fields_from_geodetic(
            stamps, sol.lat, sol.lon, sol.alt, frame_id,
            status=STATUS_NO_FIX, service=SERVICE_UNKNOWN,
        ),  # fmt: skip
    )
    if truth is not None:
        dr = position_error_ned(r_e, truth.r_e, truth.lat, truth.lon)
        out.error_position = vector3_stamped_fields(stamps, dr, "ned")
        out.error_velocity = vector3_stamped_fields(
            stamps, velocity_error_ned(sol.v_ned, truth.v_ned), "ned"
        )
        out.error_attitude = vector3_stamped_fields(
            stamps, attitude_error_young(c_b_n, truth.c_b_n), "young_uen"
        )
    return out


# --------------------------------------------------------------------------------------------
# A run over contiguous messages
# --------------------------------------------------------------------------------------------


class NavigatorRun:
    """The navigator over one contiguous stretch of IMU messages (no gap).

    Feed decoded IMU increments (:meth:`add_imu`) and truth states (:meth:`add_truth`) in any
    interleaving; :meth:`outputs` returns the messages of every output that is complete (its
    cycle integrated and, with a truth topic, its truth received).

    Parameters
    ----------
    spec : NavigatorSpec
        Resolved navigator section.
    start_ns : int
        Stamp of the initial state ``t_s``.
    period_ns : int
        IMU period T (ns); ``T_gyr = T``.
    initial : NavState
        State at ``t_s`` (with the initial errors already applied).
    use_truth : bool
        Compute errors (and wait for the truth of each output stamp).
    initial_omega : array (3,), optional
        Body rate relative to the Earth for the j = 0 output (truth's, if known).
    earth_frame : str
        Odometry ``header.frame_id``.
    n : int, optional
        N (default ``spec.n``).
    """

    def __init__(
        self,
        spec: NavigatorSpec,
        start_ns: int,
        period_ns: int,
        initial: NavState,
        use_truth: bool,
        initial_omega: F64 | None = None,
        earth_frame: str = "earth",
        n: int | None = None,
    ) -> None:
        if period_ns <= 0:
            raise StreamError(f"IMU period must be positive, got {period_ns} ns")
        self.spec = spec
        self.n = spec.n if n is None else int(n)
        self.damped = spec.vertical_damping is not None
        self.start_ns, self.period_ns = int(start_ns), int(period_ns)
        self.nav_period_ns = self.n * self.period_ns
        self.use_truth = use_truth
        self.earth_frame = earth_frame
        self.navigator = build_navigator(spec, initial, self.period_ns * 1e-9, self.n)
        self.next_imu_ns = self.start_ns + self.period_ns
        self._da: list[F64] = []
        self._dv: list[F64] = []
        self._buffered = 0
        self._truth: dict[int, tuple[F64, ...]] = {}
        self.truth_latest_ns: int | None = None  # latest truth stamp received (any stamp)
        self.truth_lost: list[int] = []  # output stamps whose truth is lost, not yet reported
        self._alt = float(initial.alt)  # altitude (m) of the last cycle integrated
        w0 = np.zeros(3) if initial_omega is None else np.asarray(initial_omega, dtype=np.float64)
        self._held: list[tuple[int, NavSolution, F64]] = [
            (self.start_ns, _solution_rows(initial, self.n), w0[None])
        ]
        self.cycles = 0

    # -- input -------------------------------------------------------------------------------

    def add_imu(self, stamps_ns: I64, dalpha: F64, dv: F64) -> None:
        """Append IMU increments (FRD) with stamps continuing the run exactly.

        Raises
        ------
        StreamError
            If the first stamp is not the expected next one, or the stamps are not spaced by T
            (a gap or out-of-order data): nothing is integrated across it.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        if not stamps.size:
            return
        expected = self.next_imu_ns + self.period_ns * np.arange(stamps.size)
        if not np.array_equal(stamps, expected):
            bad = int(np.argmax(stamps != expected))
            raise StreamError(
                f"IMU stamp {int(stamps[bad])} ns where {int(expected[bad])} ns was expected "
                f"(T = {self.period_ns} ns): "
                + ("gap" if stamps[bad] > expected[bad] else "out of order or repeated")
            )
        self._da.append(np.asarray(dalpha, dtype=np.float64))
        self._dv.append(np.asarray(dv, dtype=np.float64))
        self._buffered += stamps.size
        self.next_imu_ns = int(stamps[-1]) + self.period_ns

    def add_truth(self, state: EarthState) -> None:
        """Remember truth rows by stamp (those on the navigation grid are kept)."""
        stamps = np.asarray(state.stamps_ns, dtype=np.int64)
        if stamps.size:
            latest = int(stamps.max())
            if self.truth_latest_ns is None or latest > self.truth_latest_ns:
                self.truth_latest_ns = latest
        rel = stamps - self.start_ns
        keep = np.flatnonzero((rel >= 0) & (rel % self.nav_period_ns == 0))
        for i in keep:
            self._truth[int(stamps[i])] = tuple(np.asarray(a)[i] for a in state[1:])

    # -- output ------------------------------------------------------------------------------

    def _truth_lost(self, stamp: int) -> bool:
        """The truth of ``stamp`` did not arrive and a later one did: it is lost (truth comes in
        stamp order)."""
        return self.truth_latest_ns is not None and self.truth_latest_ns > stamp

    def outputs(self) -> NavigatorOutputs | None:
        """Integrate every complete cycle; return the outputs now complete (None if none).

        With a truth topic an output waits for the truth of its stamp; if that truth is lost
        (a later one arrived), the output is published without its error messages (the
        navigator runs on from its own state; call again for the outputs after it).
        """
        self._integrate()
        ready = []
        lost = False
        for item in self._held:
            if self.use_truth and item[0] not in self._truth:
                if ready or not self._truth_lost(item[0]):
                    break
                lost = True
                self.truth_lost.append(item[0])
                ready.append(item)
                break
            ready.append(item)
        if not ready:
            return None
        self._held = self._held[len(ready) :]
        stamps = np.array([s for s, _, _ in ready], dtype=np.int64)
        sol = _concat([r[1] for r in ready])
        omega = np.concatenate([r[2] for r in ready])
        truth = None
        if self.use_truth and not lost:
            rows = [self._truth[int(s)] for s in stamps]
            truth = _truth(EarthState(stamps, *(np.array([r[i] for r in rows]) for i in range(4))))
        self._prune_truth()
        return _output_fields(stamps, sol, omega, truth, self.spec.frame_id, self.earth_frame)

    def _integrate(self) -> None:
        n = self.n
        cycles = self._buffered // n
        if self.damped:
            # h_aux of cycle k: truth altitude at its start stamp (must have arrived; if it is
            # lost, the navigator's own altitude: no damping correction over that cycle).
            have = 0
            while have < cycles:
                start = self._cycle_start(self.cycles + have)
                if start not in self._truth and not self._truth_lost(start):
                    break
                have += 1
            cycles = have
        if not cycles:
            return
        da = np.concatenate(self._da) if len(self._da) > 1 else self._da[0]
        dv = np.concatenate(self._dv) if len(self._dv) > 1 else self._dv[0]
        used = cycles * n
        h_aux = None
        if self.damped:
            starts = [self._cycle_start(self.cycles + k) for k in range(cycles)]
            if all(s in self._truth for s in starts):
                h_aux = ecef_to_geodetic(np.array([self._truth[s][0] for s in starts]))[2]
            else:  # cycle by cycle: a lost truth altitude is the navigator's own
                sol = None
                for k, s in enumerate(starts):
                    h = (ecef_to_geodetic(self._truth[s][0])[2] if s in self._truth
                         else self._alt)  # fmt: skip
                    part = self.navigator.run(
                        da[k * n : (k + 1) * n], dv[k * n : (k + 1) * n], np.array([h])
                    )
                    self._alt = float(part.alt[-1])
                    sol = part if sol is None else _concat([sol, part])
                self._finish_cycles(sol, da, dv, cycles, used)
                return
        sol = self.navigator.run(da[:used], dv[:used], h_aux)
        self._finish_cycles(sol, da, dv, cycles, used)

    def _finish_cycles(self, sol: NavSolution, da: F64, dv: F64, cycles: int, used: int) -> None:
        n = self.n
        self._alt = float(sol.alt[-1])
        self._da, self._dv = [da[used:]], [dv[used:]]
        self._buffered -= used
        # Mean body rate relative to the Earth over each cycle: ΣΔα/T_nav - C_E^B ω_ie.
        t_nav = self.nav_period_ns * 1e-9
        rate = da[:used].reshape(cycles, n, 3).sum(axis=1) / t_nav
        c_b_e = dcm_ned_to_ecef(sol.lat, sol.lon) @ dcm_from_quat(sol.q_b_n)
        omega = rate - np.einsum("nji,j->ni", c_b_e, OMEGA_IE_VEC)
        for k in range(cycles):
            stamp = self._cycle_start(self.cycles + k + 1)
            self._held.append((stamp, _solution_rows(sol, n, k), omega[k : k + 1]))
        self.cycles += cycles

    def _prune_truth(self) -> None:
        """Forget truth older than both the next held output and the next cycle start."""
        oldest = self._cycle_start(self.cycles)
        if self._held:
            oldest = min(oldest, self._held[0][0])
        for s in [s for s in self._truth if s < oldest]:
            del self._truth[s]

    def _cycle_start(self, k: int) -> int:
        return self.start_ns + k * self.nav_period_ns


def _solution_rows(sol: NavSolution | NavState, n: int, k: int | None = None) -> NavSolution:
    """One output row as a NavSolution (from a state or row k of a solution)."""
    if isinstance(sol, NavState):
        return NavSolution(
            np.array([sol.t]), np.array([sol.lat]), np.array([sol.lon]), np.array([sol.alt]),
            np.asarray(sol.v_ned, dtype=np.float64)[None],
            np.asarray(sol.q_b_n, dtype=np.float64)[None], n,
        )  # fmt: skip
    sl = slice(k, k + 1)
    return NavSolution(
        sol.t[sl], sol.lat[sl], sol.lon[sl], sol.alt[sl], sol.v_ned[sl], sol.q_b_n[sl], n
    )


def _concat(parts: list[NavSolution]) -> NavSolution:
    return NavSolution(
        *(np.concatenate([getattr(p, f) for p in parts]) for f in
          ("t", "lat", "lon", "alt", "v_ned", "q_b_n")),
        parts[0].n,
    )  # fmt: skip


# --------------------------------------------------------------------------------------------
# The streaming stage
# --------------------------------------------------------------------------------------------


class _TruthStore:
    """The latest ``keep`` truth rows by stamp (a repeated stamp: the last one received),
    kept as a few arrays and sorted when a run is to start."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self._parts: list[EarthState] = []
        self._rows = 0
        self._sorted = True

    def add(self, state: EarthState) -> None:
        self._parts.append(state)
        self._rows += len(state.stamps_ns)
        self._sorted = False
        if self._rows > 2 * self.keep:
            self.sorted()

    def sorted(self) -> EarthState | None:
        """The rows kept, in stamp order (None if none)."""
        if not self._parts:
            return None
        if not self._sorted:
            parts = self._parts
            cat = EarthState(*(np.concatenate([p[i] for p in parts]) for i in range(5)))
            rev = np.asarray(cat.stamps_ns, dtype=np.int64)[::-1]
            _, first = np.unique(rev, return_index=True)  # last occurrence of each stamp
            rows = (rev.size - 1 - first)[-self.keep :]
            self._parts = [_rows(cat, rows)]
            self._rows = rows.size
            self._sorted = True
        return self._parts[0]


@dataclass
class _Decoded:
    """One topic's part of an input chunk: fields (None: decode each payload alone)."""

    fields: Any
    stamps: I64
    payloads: Sequence[bytes | memoryview] | None = None
    states: EarthState | None = None  # truth in the Earth frame (None: wrong frame)


class NavigatorStage:
    """The streaming navigator: Imu and truth messages in, ``/navigator/*`` messages out.

    Input in arrival order and any chunking (:meth:`on_batch` raw payloads, :meth:`feed_fields`
    decoded fields, :meth:`feed_batches` a piece of ``generate``); the state is carried between
    calls and the output does not depend on the chunking. The input checks are here:

    * **Period.** T is ``period_ns`` if given, else the difference of the first two increasing
      IMU stamps; with ``nav_period_s`` > 0, N = T_nav / T must be a whole number.
    * **Start.** A run starts at a truth stamp ``t_s`` whose next IMU message ``t_s + T`` has
      arrived (``initialization: truth``), or at ``start_ns`` (``scenario``).
    * **Gaps.** A missing IMU message ends the run at its last complete cycle; a new run starts
      from the truth before the next message. Out-of-order and repeated messages are dropped;
      truth in another frame than ``earth_frame`` and malformed messages are rejected. Each is
      logged.

    Parameters
    ----------
    spec : NavigatorSpec
        Resolved ``navigator`` section (:func:`~strapdown_ros.config.navigator.
        resolve_navigator`).
    output_topics : mapping
        Output key (:data:`OUTPUT_TOPICS`) → topic name.
    initial : Initial, optional
        The scenario's initial state (``initialization: scenario``).
    start_ns : int, optional
        The scenario's start stamp (``initialization: scenario``).
    period_ns : int, optional
        IMU period T (ns) if known (``generate``); None: from the stamps.
    nav_period_s : float
        If > 0, ``T_nav`` (s) instead of ``spec.n``.
    end_ns : int, optional
        Last IMU stamp of the input stream, if known: :attr:`finished`.
    earth_frame : str
        Frame id of the truth Odometry and of ``/navigator/odom``.
    info, warn, error : callables
        Log sinks (default: silent).
    """

    def __init__(
        self,
        spec: NavigatorSpec,
        output_topics: Mapping[str, str],
        *,
        initial: Initial | None = None,
        start_ns: int | None = None,
        period_ns: int | None = None,
        nav_period_s: float = 0.0,
        end_ns: int | None = None,
        earth_frame: str = "earth",
        info: Log = quiet,
        warn: Log = quiet,
        error: Log = quiet,
    ) -> None:
        if not spec.resolved:
            raise ValueError("the navigator spec must be resolved (resolve_navigator)")
        if spec.initialization == "scenario" and (initial is None or start_ns is None):
            raise ValueError("initialization 'scenario' needs the initial state and start stamp")
        self.spec = spec
        self.n = spec.n
        self.output_topics = dict(output_topics)
        self.initial = initial
        self.start_ns = start_ns
        self.nav_period_s = nav_period_s
        self.end_ns = end_ns
        self.earth_frame = earth_frame
        self.info, self.warn, self.error = info, warn, error
        #: Input events by class (one log line each; counted for the node's summary).
        self.events = InputEvents(warn, error)
        self.period_ns: int | None = None
        self.first_imu: list[tuple[int, Any]] = []  # (stamp, fields) before T is known
        self.imu_buffer: list[tuple[int, F64, F64]] = []  # waiting for a run
        self.truth = _TruthStore(TRUTH_KEEP)
        self.run: NavigatorRun | None = None
        self.runs = 0
        self.published_outputs = 0
        self.last_output_ns: int | None = None
        self.failed: str | None = None
        #: End-of-output errors (m): ``horizontal_m``, ``vertical_m``, ``max_horizontal_m``.
        self.final_errors: dict[str, float] = {}
        self._flush_pending: list[NavigatorOutputs] = []
        self._diverged = False  # the current run produced a non-finite solution
        self.imu_frame: str | None = None  # frame_id of the Imu messages so far
        if period_ns is not None:
            self._set_period(int(period_ns), "given")

    @classmethod
    def for_scenario(
        cls, scenario: Scenario, spec: NavigatorSpec | None = None, **kwargs: Any
    ) -> NavigatorStage:
        """The stage of ``scenario``'s navigator (or of ``spec``, resolved), with its output
        topics, frames, initial state and start; ``kwargs`` as for the constructor."""
        spec = navigator_spec(scenario) if spec is None else spec
        if spec is None:
            raise ValueError(f"scenario {scenario.name!r} has no navigator section")
        topics = scenario.recording.topics
        kwargs.setdefault("earth_frame", scenario.recording.frames["earth"])
        return cls(
            spec,
            {k: topics[v] for k, v in OUTPUT_TOPICS.items()},
            initial=scenario.initial,
            start_ns=scenario.start_time_ns,
            **kwargs,
        )

    # -- state -------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        """Whether a run has started."""
        return self.run is not None or self.runs > 0

    @property
    def finished(self) -> bool:
        """True when the last output the input stream allows has been published."""
        if self.end_ns is None or self.run is None:
            return False
        nav = self.run.nav_period_ns
        last = self.run.start_ns + (self.end_ns - self.run.start_ns) // nav * nav
        return self.last_output_ns is not None and self.last_output_ns >= last

    # -- input -------------------------------------------------------------------------------

    def on_batch(self, items: Sequence[tuple[str, bytes | memoryview]]) -> list[Message]:
        """Raw payloads ``(kind, payload)`` (kind ``imu`` | ``truth``) in arrival order.

        Returns ``(topic, stamp_ns, payload)`` to publish, in order. Each topic's payloads are
        decoded with one CDR call; a chunk that does not decode as a whole (a malformed message,
        mixed frame ids) is taken message by message, so every message gets its own verdict.
        """
        is_imu = np.fromiter((k == "imu" for k, _ in items), dtype=bool, count=len(items))
        imu = self._decode(cdr.IMU, [p for k, p in items if k == "imu"])
        truth = self._decode(cdr.ODOMETRY, [p for k, p in items if k != "imu"])
        return self._messages(self._feed(is_imu, imu, truth))

    def on_imu(self, payload: bytes | memoryview) -> list[Message]:
        """One raw Imu payload (``on_batch([("imu", payload)])``)."""
        return self.on_batch([("imu", payload)])

    def on_truth(self, payload: bytes | memoryview) -> list[Message]:
        """One raw truth Odometry payload (``on_batch([("truth", payload)])``)."""
        return self.on_batch([("truth", payload)])

    def feed_fields(
        self,
        imu: ImuFields | None = None,
        truth: OdometryFields | None = None,
        is_imu: NDArray[np.bool_] | None = None,
    ) -> list[Message]:
        """Decoded messages: ``is_imu[k]`` says whether the k-th message received is the next
        Imu row or the next truth row (default: the truth rows, then the Imu rows)."""
        n_imu = 0 if imu is None else len(imu.stamps_ns)
        n_truth = 0 if truth is None else len(truth.stamps_ns)
        if is_imu is None:
            is_imu = np.repeat([False, True], [n_truth, n_imu])
        dec_imu = None if imu is None else self._decoded(imu)
        dec_truth = None if truth is None else self._decoded(truth)
        return self._messages(self._feed(np.asarray(is_imu, dtype=bool), dec_imu, dec_truth))

    def feed_batches(self, batches: Sequence[Batch]) -> list[Batch]:
        """A piece of ``generate``: the batches of the input topics among ``batches`` (truth
        first, then Imu); returns the ``/navigator/*`` batches now complete."""
        spec = self.spec
        by_topic = {b.topic: b for b in batches}
        imu_payloads = by_topic[spec.imu_topic].payloads if spec.imu_topic in by_topic else []
        truth_payloads: Sequence[bytes | memoryview] = []
        if spec.truth_topic and spec.truth_topic in by_topic:
            truth_payloads = by_topic[spec.truth_topic].payloads
        is_imu = np.repeat([False, True], [len(truth_payloads), len(imu_payloads)])
        groups = self._feed(
            is_imu,
            self._decode(cdr.IMU, list(imu_payloads)),
            self._decode(cdr.ODOMETRY, list(truth_payloads)),
        )
        if self.failed:
            raise StreamError(self.failed)
        return [b for group in groups for b in self._batches(group)]

    # -- decoding ----------------------------------------------------------------------------

    def _decode(self, msgtype: str, payloads: list[bytes | memoryview]) -> _Decoded | None:
        """All ``payloads`` decoded at once, or (if they do not) kept to be decoded one by one."""
        if not payloads:
            return None
        try:
            fields = cdr.deserialize(msgtype, payloads)
        except cdr.CdrError:
            return _Decoded(None, np.zeros(0, dtype=np.int64), payloads)
        return self._decoded(fields)

    def _decoded(self, fields: Any) -> _Decoded:
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64)
        states = None
        if isinstance(fields, OdometryFields) and fields.frame_id == self.earth_frame:
            states = odometry_state(fields)
        return _Decoded(fields, stamps, None, states)

    # -- the one path ------------------------------------------------------------------------

    def _feed(
        self, is_imu: NDArray[np.bool_], imu: _Decoded | None, truth: _Decoded | None
    ) -> list[NavigatorOutputs]:
        """Messages in arrival order; returns the output groups now complete.

        Stretches that only extend the current run are added in blocks (no output in between);
        a message that could change the run (none yet, a gap, a repeat) or that is rejected
        takes the one-message path, after the block before it.
        """
        is_imu, imu, truth = self._drop_nonfinite(is_imu, imu, truth)
        if imu is not None and imu.fields is not None and imu.stamps.size:  # one frame id
            self._imu_frame_changed(imu.fields.frame_id, int(imu.stamps[0]))
        out: list[NavigatorOutputs] = []
        total = is_imu.size
        imu_before = np.concatenate([[0], np.cumsum(is_imu)])  # Imu rows before item k
        imu_items = np.flatnonzero(is_imu)
        truth_items = np.flatnonzero(~is_imu)
        imu_ok = imu is not None and imu.fields is not None
        truth_ok = truth is not None and truth.states is not None
        pos = 0
        while pos < total:
            end = total
            if not truth_ok:  # the next truth message is taken alone
                k = np.searchsorted(truth_items, pos)
                end = int(truth_items[k]) if k < truth_items.size else total
            r0, r1 = int(imu_before[pos]), int(imu_before[end])
            if r1 > r0:
                if not imu_ok or self.run is None or self.period_ns is None:
                    end = int(imu_items[r0])  # taken alone
                else:  # the Imu messages continuing the run exactly
                    expected = self.run.next_imu_ns + self.period_ns * np.arange(r1 - r0)
                    bad = np.flatnonzero(imu.stamps[r0:r1] != expected)  # type: ignore[union-attr]
                    if bad.size:
                        end = int(imu_items[r0 + int(bad[0])])
            self._add_block(pos, end, imu_before, imu, truth)
            if end < total:
                out += self._one(int(end), bool(is_imu[end]), imu_before, imu, truth)
            pos = end + 1
        return out + self._advance()

    def _drop_nonfinite(
        self, is_imu: NDArray[np.bool_], imu: _Decoded | None, truth: _Decoded | None
    ) -> tuple[NDArray[np.bool_], _Decoded | None, _Decoded | None]:
        """The input without its messages holding a NaN or an infinity (each stretch logged):
        a dropped Imu is a lost Imu message (the run ends at its last complete cycle), a
        dropped truth a lost truth message (the navigator runs on from its own state)."""
        keep = np.ones(is_imu.size, dtype=bool)
        parts = []
        for dec, flag in ((imu, True), (truth, False)):
            if dec is None or dec.fields is None:
                parts.append(dec)
                continue
            fields, bad = self._screen(dec.fields, flag)
            if bad is None:
                parts.append(dec if fields is dec.fields else self._decoded(fields))
                continue
            keep[np.flatnonzero(is_imu == flag)[bad]] = False
            parts.append(None if fields is None else self._decoded(fields))
        if keep.all():
            return is_imu, parts[0], parts[1]
        return is_imu[keep], parts[0], parts[1]

    def _screen(self, fields: Any, imu: bool) -> tuple[Any, NDArray[np.bool_] | None]:
        """:func:`~strapdown_ros.stages.intake.screen` of Imu (``imu``) or truth messages: a
        dropped Imu is a lost one (the run ends at its last complete cycle), a dropped truth a
        lost truth (the navigator runs on from its own state)."""
        if imu:
            topic = self.spec.imu_topic
            return screen(fields, topic, self.events, "treated as lost: the run ends at its "
                          "last complete cycle, a new one starts from the truth",
                          lambda stamps: self.events.dropped(topic, stamps))  # fmt: skip
        return screen(fields, self.spec.truth_topic, self.events, "treated as lost: the "
                      "navigator runs on from its own state (no error messages at that "
                      "stamp)")  # fmt: skip

    def _add_block(
        self,
        pos: int,
        end: int,
        imu_before: NDArray[np.int64],
        imu: _Decoded | None,
        truth: _Decoded | None,
    ) -> None:
        """Items ``pos..end-1``: truth rows (Earth frame) and Imu rows continuing the run."""
        if end <= pos:
            return
        r0, r1 = int(imu_before[pos]), int(imu_before[end])
        t0, t1 = pos - r0, end - r1
        if t1 > t0:
            assert truth is not None and truth.states is not None
            self._add_truth(_rows(truth.states, slice(t0, t1)))
        if r1 > r0:
            assert imu is not None and self.run is not None and self.period_ns is not None
            inc = imu_increments(imu.fields.rows(r0, r1), self.period_ns)
            self.run.add_imu(inc.stamps_ns, inc.dalpha, inc.dv)

    def _one(
        self,
        k: int,
        is_imu: bool,
        imu_before: NDArray[np.int64],
        imu: _Decoded | None,
        truth: _Decoded | None,
    ) -> list[NavigatorOutputs]:
        """Item ``k`` alone (see :meth:`_feed`)."""
        if is_imu:
            row = int(imu_before[k])
            assert imu is not None
            if imu.fields is not None:
                return self._on_imu_fields(imu.fields.rows(row, row + 1))
            assert imu.payloads is not None
            fields = decode_one(cdr.IMU, imu.payloads[row], self.spec.imu_topic, self.events)
            if fields is None:
                return []
            fields, _ = self._screen(fields, True)
            return [] if fields is None else self._on_imu_fields(fields)
        row = k - int(imu_before[k])
        assert truth is not None
        if truth.fields is None:
            assert truth.payloads is not None
            fields = decode_one(cdr.ODOMETRY, truth.payloads[row], self.spec.truth_topic,
                                self.events)  # fmt: skip
            if fields is None:
                return []
            fields, _ = self._screen(fields, False)
            if fields is None:
                return []
            one = self._decoded(fields)
            if one.states is None:
                self._wrong_frame(fields.frame_id)
                return []
            self._add_truth(one.states)
            return self._advance()
        if truth.states is None:
            self._wrong_frame(truth.fields.frame_id)
            return []
        self._add_truth(_rows(truth.states, slice(row, row + 1)))
        return []

    def _imu_frame_changed(self, frame_id: str, stamp: int) -> bool:
        """Whether the Imu ``frame_id`` differs from the messages' before it (another body):
        then the run ends (its complete outputs are published) and a new one starts from the
        truth."""
        if self.imu_frame is None or frame_id == self.imu_frame:
            self.imu_frame = frame_id
            return False
        self.events(
            "wrong frame",
            f"{self.spec.imu_topic}: stamp {format_stamp(stamp)}: Imu frame_id {frame_id!r} "
            f"differs from {self.imu_frame!r} of the messages before (another body); the run "
            "ends and a new run starts from the truth",
            error=True,
        )
        self.imu_frame = frame_id
        if self.run is not None:
            self._flush_pending += self._outputs_of(self.run)
            self.run = None
        self.imu_buffer.clear()
        return True

    def _wrong_frame(self, frame_id: str) -> None:
        self.events(
            "wrong frame",
            f"{self.spec.truth_topic}: header.frame_id {frame_id!r} is not the Earth frame "
            f"{self.earth_frame!r}; dropped (treated as a lost truth message)",
            error=True,
        )

    def _set_period(self, period_ns: int, how: str = "from the stamps") -> bool:
        if period_ns <= 0:
            return False
        if self.nav_period_s > 0:
            n = self.nav_period_s * 1e9 / period_ns
            if abs(n - round(n)) > 1e-6 or round(n) < 1:
                self.failed = (
                    f"nav_period_s = {self.nav_period_s:g} s is not a whole multiple of the IMU "
                    f"period T = {period_ns} ns {how}"
                )
                self.error(self.failed)
                return False
            self.n = int(round(n))
        self.period_ns = period_ns
        self.info(
            f"IMU period T = {period_ns} ns ({1e9 / period_ns:g} Hz) {how}; "
            f"T_nav = N T = {self.n} x T = {self.n * period_ns * 1e-9:g} s, P = {self.spec.p}"
        )
        return True

    def _add_truth(self, state: EarthState) -> None:
        """Keep truth rows (for run starts) and hand them to the current run."""
        self.truth.add(state)
        if self.run is not None:
            self.run.add_truth(state)

    def _on_imu_fields(self, fields: Any) -> list[NavigatorOutputs]:
        """One decoded Imu message; returns the output groups now complete."""
        stamp = int(fields.stamps_ns[0])
        self._imu_frame_changed(fields.frame_id, stamp)
        if self.period_ns is None:
            # T is the first interval seen twice in a row (one interval may span a gap).
            if self.failed:
                return []
            first = self.first_imu
            if first and stamp <= first[-1][0]:
                self.events(
                    "restart" if stamp < first[0][0] else "out-of-order stamp",
                    f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} does not follow "
                    f"{format_stamp(first[-1][0])} before the IMU period is known; the period "
                    "search starts again from it",
                )
                first.clear()
            first.append((stamp, fields))
            if len(first) < 3:
                return []
            if first[-1][0] - first[-2][0] != first[-2][0] - first[-3][0]:
                del first[:-2]
                return []
            if not self._set_period(first[-1][0] - first[-2][0]):
                return []
            held, self.first_imu = first, []
            for s, f in held:
                self._queue(s, f)
            return self._advance()
        self._queue(stamp, fields)
        return self._advance()

    def _queue(self, stamp: int, fields: Any) -> None:
        assert self.period_ns is not None
        inc = imu_increments(fields, self.period_ns)
        da, dv = inc.dalpha, inc.dv
        if self.run is not None:
            try:
                self.run.add_imu(inc.stamps_ns, da, dv)
                return
            except StreamError as exc:
                expected = self.run.next_imu_ns
                verdict = stamp_verdict(stamp, expected - self.period_ns, self.period_ns)
                if verdict in ("duplicate", "out-of-order"):
                    self.events(f"{verdict} stamp", f"{self.spec.imu_topic}: {exc}; dropped")
                    return
                if verdict == "restart":
                    self.events(
                        "restart",
                        f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} jumps back from "
                        f"{format_stamp(expected - self.period_ns)}: the source restarted; "
                        f"the run that started at {format_stamp(self.run.start_ns)} ends and "
                        "a new run starts from the truth",
                    )
                else:
                    self.events.gap(
                        self.spec.imu_topic,
                        range(expected, stamp, self.period_ns),
                        f"{self.spec.imu_topic}: {exc} "
                        f"({(stamp - expected) // self.period_ns} message(s) missing after "
                        f"{format_stamp(expected - self.period_ns)}); the run that started at "
                        f"{format_stamp(self.run.start_ns)} ends at its last complete cycle "
                        "and a new run starts from the truth before the next message",
                        self.info,
                    )
                self._flush_pending = self._outputs_of(self.run)
                self.run = None
        if self.imu_buffer and stamp <= self.imu_buffer[-1][0]:
            if stamp_verdict(stamp, self.imu_buffer[-1][0], self.period_ns) == "restart":
                self.imu_buffer.clear()  # the source restarted before a run could start
            else:
                self.events(
                    "out-of-order stamp",
                    f"{self.spec.imu_topic}: stamp {format_stamp(stamp)} out of order; dropped",
                )
                return
        if self.imu_buffer and stamp != self.imu_buffer[-1][0] + self.period_ns:
            self.imu_buffer.clear()  # a gap before any run started: restart the search
        self.imu_buffer.append((stamp, da, dv))

    # -- runs --------------------------------------------------------------------------------

    def _try_start(self) -> None:
        if self.run is not None or self.period_ns is None or not self.imu_buffer:
            return
        spec, t = self.spec, self.period_ns
        if spec.initialization == "scenario":
            assert self.start_ns is not None and self.initial is not None
            while self.imu_buffer and self.imu_buffer[0][0] < self.start_ns + t:
                self.imu_buffer.pop(0)
            if not self.imu_buffer or self.imu_buffer[0][0] != self.start_ns + t:
                if self.imu_buffer and not self.failed:
                    self.failed = (
                        f"initialization 'scenario' needs the IMU message at "
                        f"{format_stamp(self.start_ns + t)} (scenario start + T); the first one "
                        f"received is {format_stamp(self.imu_buffer[0][0])}"
                    )
                    self.error(self.failed)
                return
            self._start(self.start_ns, initial_state_from_scenario(self.initial, spec), None)
            return
        truth = self.truth.sorted()
        if truth is None:
            return
        # The first truth stamp s (in stamp order) whose next IMU message s + T is buffered;
        # the IMU messages before s + T (or, without one, before the last s + T) are dropped.
        stamps = np.asarray(truth.stamps_ns, dtype=np.int64)
        buffered = np.array([b[0] for b in self.imu_buffer], dtype=np.int64)
        hits = np.flatnonzero(np.isin(stamps + t, buffered))
        cut = int(stamps[hits[0]] if hits.size else stamps[-1]) + t
        del self.imu_buffer[: int(np.searchsorted(buffered, cut))]
        if hits.size:
            row = int(hits[0])
            self._start(
                int(stamps[row]),
                initial_state_from_truth(truth, row, spec),
                np.asarray(truth.omega_eb_b)[row],
            )

    def _start(self, start_ns: int, initial: NavState, omega: F64 | None) -> None:
        assert self.period_ns is not None
        spec = self.spec
        self.run = NavigatorRun(
            spec, start_ns, self.period_ns, initial, bool(spec.truth_topic), omega,
            self.earth_frame, self.n,
        )  # fmt: skip
        truth = self.truth.sorted()
        if truth is not None:
            after = np.flatnonzero(np.asarray(truth.stamps_ns) >= start_ns)
            if after.size:
                self.run.add_truth(_rows(truth, after))
        buf, self.imu_buffer = self.imu_buffer, []
        if buf:
            self.run.add_imu(
                np.array([b[0] for b in buf], dtype=np.int64),
                np.concatenate([b[1] for b in buf]),
                np.concatenate([b[2] for b in buf]),
            )
        self.runs += 1
        how = "truth" if spec.initialization == "truth" else "the scenario's initial state"
        self.info(f"run {self.runs} starts at {format_stamp(start_ns)} (initial state from {how})")

    def _advance(self) -> list[NavigatorOutputs]:
        flushed, self._flush_pending = self._flush_pending, []
        self._try_start()
        if self.run is None:
            return flushed
        groups = self._outputs_of(self.run)
        if self._diverged:  # its state is not finite: a new run from the truth
            self._diverged = False
            self.info(f"the run that started at {format_stamp(self.run.start_ns)} diverged; a "
                      "new run starts from the truth before the next IMU message")  # fmt: skip
            self.run = None
        return [*flushed, *groups]

    def _outputs_of(self, run: NavigatorRun) -> list[NavigatorOutputs]:
        groups = []
        while True:
            out = self._output_group(run)
            if out is None:
                return groups
            groups.append(out)

    def _output_group(self, run: NavigatorRun) -> NavigatorOutputs | None:
        out = run.outputs()
        for stamp in run.truth_lost:
            self.events(
                "truth lost",
                f"{self.spec.truth_topic}: no truth at output stamp {format_stamp(stamp)} (a "
                "later one arrived); the output is published without its error messages and "
                "the navigator runs on from its own state",
            )
        run.truth_lost.clear()
        if out is None:
            return None
        out = self._finite_outputs(out)
        if out is None:
            return self._output_group(run)
        self.published_outputs += len(out)
        self.last_output_ns = int(out.odom.stamps_ns[-1])
        if out.error_position is not None:
            dr = np.asarray(out.error_position.vector)
            horizontal = np.hypot(dr[:, 0], dr[:, 1])
            self.final_errors = {
                "horizontal_m": float(horizontal[-1]),
                "vertical_m": float(abs(dr[-1, 2])),
                "max_horizontal_m": max(
                    self.final_errors.get("max_horizontal_m", 0.0), float(horizontal.max())
                ),
            }
        return out

    def _finite_outputs(self, out: NavigatorOutputs) -> NavigatorOutputs | None:
        """``out`` without the outputs holding a non-finite number (a diverged solution, e.g.
        an unstable vertical channel): never published, each stretch logged."""
        # The odometry holds the whole solution (the fix and, with finite truth, the errors are
        # computed from it): checking it is enough.
        bad = nonfinite_rows(out.odom)
        if bad is None:
            return None if len(out) == 0 else out
        stamps = np.asarray(out.odom.stamps_ns, dtype=np.int64)
        for a, b in stretches(bad):
            self.events(
                "non-finite output",
                f"{self.output_topics['odom']}: the solution at {format_stamp(int(stamps[a]))}"
                + (f"..{format_stamp(int(stamps[b]))}" if b > a else "")
                + " is not finite (the navigator diverged); not published",
                error=True,
            )
        self._diverged = True
        if bad.all():
            return None
        kept = {k: without_rows(f, bad) for k, f in out.items()}
        return NavigatorOutputs(**kept)

    # -- serialization -----------------------------------------------------------------------

    def _batches(self, group: NavigatorOutputs) -> list[Batch]:
        return [batch(self.output_topics[k], f) for k, f in group.items()]

    def _messages(self, groups: list[NavigatorOutputs]) -> list[Message]:
        out: list[Message] = []
        for group in groups:
            batches = self._batches(group)
            out += [
                (batches[b].topic, int(batches[b].stamps_ns[i]), batches[b].payloads[i])
                for b, i, _ in merge_order(batches)
            ]
        return out


def navigate_messages(
    spec: NavigatorSpec,
    imu: ImuFields,
    truth: OdometryFields | None,
    earth_frame: str = "earth",
    output_topics: Mapping[str, str] | None = None,
    initial: Initial | None = None,
    start_ns: int | None = None,
) -> dict[str, list[bytes]]:
    """What ``navigator_node`` publishes for whole topics received in stamp order (truth
    before Imu at equal stamps): output key (:data:`OUTPUT_TOPICS`) → payloads.

    ``spec``: resolved; ``initial``, ``start_ns``: for ``initialization: scenario``. Used by
    ``strapdown-sim replay`` to check a live replay.
    """
    topics = dict(output_topics or {k: k for k in OUTPUT_TOPICS})
    stage = NavigatorStage(
        spec, topics, initial=initial, start_ns=start_ns, earth_frame=earth_frame
    )
    n_truth = 0 if truth is None else len(truth.stamps_ns)
    stamps = np.concatenate(
        [np.asarray(truth.stamps_ns if truth is not None else [], dtype=np.int64),
         np.asarray(imu.stamps_ns, dtype=np.int64)]
    )  # fmt: skip
    order = np.argsort(stamps, kind="stable")
    out: dict[str, list[bytes]] = {}
    by_topic = {v: k for k, v in topics.items()}
    for topic, _, payload in stage.feed_fields(imu, truth, order >= n_truth):
        out.setdefault(by_topic[topic], []).append(bytes(payload))
    return out
