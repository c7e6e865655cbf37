"""The navigator over one contiguous stretch of IMU messages (:class:`NavigatorRun`): the core
navigator of a resolved spec, fed increments and truth, returning the complete outputs."""

from __future__ import annotations

import numpy as np

from strapdown_ros.config.navigator import NavigatorSpec
from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
)
from strapdown_ros.core.navigation import (
    MultirateNavigator,
    NavSolution,
    NavState,
    SimultaneousNavigator,
    VerticalDamping,
)
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.messages import EarthState
from strapdown_ros.stages.navigator_outputs import NavigatorOutputs, output_fields
from strapdown_ros.stages.navigator_truth import truth_rows


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
            (self.start_ns, solution_rows(initial, self.n), w0[None])
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
        sol = concat_solutions([r[1] for r in ready])
        omega = np.concatenate([r[2] for r in ready])
        truth = None
        if self.use_truth and not lost:
            rows = [self._truth[int(s)] for s in stamps]
            truth = truth_rows(
                EarthState(stamps, *(np.array([r[i] for r in rows]) for i in range(4)))
            )
        self._prune_truth()
        return output_fields(stamps, sol, omega, truth, self.spec.frame_id, self.earth_frame)

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
                    sol = part if sol is None else concat_solutions([sol, part])
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
            self._held.append((stamp, solution_rows(sol, n, k), omega[k : k + 1]))
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


def solution_rows(sol: NavSolution | NavState, n: int, k: int | None = None) -> NavSolution:
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


def concat_solutions(parts: list[NavSolution]) -> NavSolution:
    return NavSolution(
        *(np.concatenate([getattr(p, f) for p in parts]) for f in
          ("t", "lat", "lon", "alt", "v_ned", "q_b_n")),
        parts[0].n,
    )  # fmt: skip
