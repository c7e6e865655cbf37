"""The aided filter as an object: IMU increments and measurements in, states out, with rollback.

:class:`AidedFilter` owns the arrays of the compiled loop (:mod:`._loop`) and keeps the
bookkeeping that makes delayed measurements exact (docs/theory/aided_ins.md §7):

* a ring of the raw IMU increments and a ring of checkpoints (the prior state at every grid
  point) over the rollback window (the largest sensor latency);
* a history of the measurements, sorted by (validity cycle, kind), kept over the window.

:meth:`insert` adds measurements; one whose validity is not after the current cycle (it arrived
late: a latency) makes the filter go back to the checkpoint of its validity time, apply it
there and re-run the stored increments and later measurements up to where it was. The result
is the filter that processed every measurement at its time of validity, in (time, kind) order;
each measurement's innovation and NIS are those of its first application (what a live filter
reports when the message arrives).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from strapdown_ros.core.aided import _loop
from strapdown_ros.core.aided.measurement_models import KINDS
from strapdown_ros.core.aided.model import FilterModel
from strapdown_ros.core.aiding.magnetometer import IGRF_REFERENCE_RADIUS_M, _recursion_factors
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.navigation._kernels import GRAVITY_CODES

__all__ = [
    "AidedFilter", "FilterSetup", "MeasurementResults", "Snapshot", "Snapshots",
    "gate_thresholds",
]

#: Rows of the IMU ring beyond the rollback window (the largest block written at once).
RING_CHUNK = 4096
#: Output-epoch states stored per buffer (spilled to a list when full).
OUTPUT_ROWS = 256


def gate_thresholds(probability: float) -> F64:
    """χ² thresholds for 0..3 degrees of freedom (index = dof); ``probability`` ≥ 1: no gate."""
    out = np.full(4, np.inf)
    if probability < 1.0:
        out[1:] = chi2.ppf(probability, np.arange(1, 4))
    return out


@dataclass(frozen=True)
class FilterSetup:
    """Everything of the filter that is not its stochastic model.

    Attributes
    ----------
    period_ns : int
        IMU period T (ns).
    start_cycle : int
        Absolute cycle ``k0 = t_start / T`` of the filter's start (its E0 epoch, cycle m = 0).
    grid_periods : tuple of int
        Periods (cycles, absolute grid) at which P is propagated and measurements may apply:
        the covariance period, each sensor's and the output period.
    levers : (5, 3) array
        Lever arm of each measurement kind (body FRD, m; row by kind, mag unused).
    wheel_mask : (3,) bool
        Wheel rows used: speed, lateral and vertical constraint.
    igrf : (g, h) or None
        IGRF Gauss coefficients (nT) at the run's year (magnetometer only).
    gate_probability : float
        χ² gate probability (≥ 1: no gate).
    window_cycles : int
        Rollback window (cycles): the largest latency; 0 without delayed sensors.
    gravity_model : str
    gravity_steps : int
        Gravitation sub-steps P of the exact kernel per IMU cycle.
    output_period : int
        Output period (cycles, absolute grid): the states stored by :meth:`AidedFilter.advance`.
    """

    period_ns: int
    start_cycle: int
    grid_periods: tuple[int, ...]
    levers: F64 = field(default_factory=lambda: np.zeros((5, 3)))
    wheel_mask: NDArray[np.bool_] = field(default_factory=lambda: np.ones(3, dtype=bool))
    igrf: tuple[F64, F64] | None = None
    gate_probability: float = 0.9999
    window_cycles: int = 0
    gravity_model: str = "j2"
    gravity_steps: int = 1
    output_period: int = 1


@dataclass(frozen=True)
class Snapshot:
    """The filter at one cycle (posterior): cycle m, nominal ``nav`` (27,), ``est`` (n,), P."""

    m: int
    nav: F64
    est: F64
    p: F64


@dataclass(frozen=True)
class Snapshots:
    """Stored output-epoch states: cycles ``m`` (K,), ``nav`` (K, 27), ``est`` (K, n), P."""

    m: NDArray[np.int64]
    nav: F64
    est: F64
    p: F64


@dataclass(frozen=True)
class MeasurementResults:
    """First applications of K measurements.

    Ids, kinds, validity cycles, innovations (K, 3; zero beyond the dof), NIS, dof, accepted.
    """

    uid: NDArray[np.int64]
    kind: NDArray[np.int64]
    m: NDArray[np.int64]
    innovation: F64
    nis: F64
    dof: NDArray[np.int64]
    accepted: NDArray[np.bool_]


class AidedFilter:
    """Closed-loop error-state Kalman filter on IMU increments (see the module docstring).

    Parameters
    ----------
    model : FilterModel
        The stochastic model (:func:`strapdown_ros.core.aided.model.build_model`).
    setup : FilterSetup
    r0, v0 : (3,) arrays
        Initial position and inertial velocity in E0 (= ECEF at the start), m, m/s.
    c0 : (3, 3) array
        Initial ``C_B^E0`` (body FRD).
    p0 : (n, n) array
        Initial covariance.
    """

    def __init__(self, model: FilterModel, setup: FilterSetup, r0: F64, v0: F64, c0: F64,
                 p0: F64) -> None:  # fmt: skip
        lay = model.layout
        n = lay.n
        if p0.shape != (n, n):
            raise ValueError(f"P0 must be ({n}, {n}), got {p0.shape}")
        self.model, self.setup, self.layout = model, setup, lay
        self.period_ns = int(setup.period_ns)
        self.ist = np.array([0, 0, -1, 0], dtype=np.int64)
        self.nav = np.zeros(27)
        self.nav[0:3], self.nav[3:6] = r0, v0
        self.nav[6:15] = np.asarray(c0, dtype=np.float64).reshape(9)
        self.est = np.zeros(n)
        self.p = np.array(p0, dtype=np.float64)
        self.acc = np.zeros(19)
        self.periods = np.array(sorted(set(int(p) for p in setup.grid_periods)), dtype=np.int64)
        if self.periods.size == 0 or self.periods.min() < 1:
            raise ValueError("grid periods must be >= 1 cycle")
        self.k0 = int(setup.start_cycle)
        self.window = int(setup.window_cycles)
        cap = 1 << int(math.ceil(math.log2(self.window + RING_CHUNK + 2)))
        self.ring_da = np.zeros((cap, 3))
        self.ring_dv = np.zeros((cap, 3))
        # checkpoints: grid points within the window (+ margin); none without delays
        self.gstep = int(np.gcd.reduce(self.periods))
        ncap = self.window // self.gstep + 4 if self.window > 0 else 0
        self.ck_m = np.full(ncap, -1, dtype=np.int64)
        self.ck_nav = np.zeros((ncap, 27))
        self.ck_est = np.zeros((ncap, n))
        self.ck_p = np.zeros((ncap, n, n))
        if ncap:
            self._checkpoint_now()
        # history
        self.h_n = 0
        self._h_alloc(64)
        # scratch: the longest stretch between grid points
        longest = int(self.periods.min()) if self.periods.size else 1
        longest = max(int(self.periods.max()), longest) + 1
        self.sr = np.zeros((longest + 1, 3))
        self.sv = np.zeros((longest + 1, 3))
        self.sc = np.zeros((longest + 1, 3, 3))
        self.da_c = np.zeros((longest, 3))
        self.dv_c = np.zeros((longest, 3))
        # constants of the compiled calls
        self.levers = np.ascontiguousarray(setup.levers, dtype=np.float64).reshape(5, 3)
        self.wheel_mask = np.asarray(setup.wheel_mask, dtype=np.bool_).reshape(3)
        if setup.igrf is not None:
            g, h = (np.ascontiguousarray(a, dtype=np.float64) for a in setup.igrf)
            a1, a2, diag = _recursion_factors(g.shape[0] - 1)
        else:
            g = h = a1 = a2 = np.zeros((2, 2))
            diag = np.ones(2)
        self.igrf = (g, h, np.ascontiguousarray(a1), np.ascontiguousarray(a2),
                     np.ascontiguousarray(diag), float(IGRF_REFERENCE_RADIUS_M))  # fmt: skip
        self.gate = gate_thresholds(setup.gate_probability)
        self.out_period = int(setup.output_period)
        self.out_m = np.zeros(OUTPUT_ROWS, dtype=np.int64)
        self.out_nav = np.zeros((OUTPUT_ROWS, 27))
        self.out_est = np.zeros((OUTPUT_ROWS, n))
        self.out_p = np.zeros((OUTPUT_ROWS, n, n))
        self._spilled: list[Snapshots] = []
        self.gmodel = GRAVITY_CODES[setup.gravity_model]
        self.p_int = int(setup.gravity_steps)
        self.imu_end = 0  # last cycle whose increments are buffered
        self._pending: list[tuple[F64, F64]] = []
        self._pending_rows = 0
        self.rollbacks = 0
        self._rate0 = False  # cycle 0 has the rate of cycle 1 (the truth's definition)

    # -- history storage ----------------------------------------------------------------------

    _H = ("h_m", "h_kind", "h_z", "h_r", "h_dim", "h_status", "h_out", "h_uid")

    def _h_arrays(self) -> list[np.ndarray]:
        return [getattr(self, a) for a in self._H]

    def _h_alloc(self, size: int) -> None:
        old = None if not hasattr(self, "h_m") else self._h_arrays()
        self.h_uid = np.zeros(size, dtype=np.int64)
        self.h_m = np.zeros(size, dtype=np.int64)
        self.h_kind = np.zeros(size, dtype=np.int64)
        self.h_z = np.zeros((size, 6))
        self.h_r = np.zeros((size, 3, 3))
        self.h_dim = np.zeros(size, dtype=np.int64)
        self.h_status = np.zeros(size, dtype=np.int64)
        self.h_out = np.zeros((size, 6))
        if old is not None:
            k = self.h_n
            for new, o in zip(self._h_arrays(), old, strict=True):
                new[:k] = o[:k]

    @property
    def m(self) -> int:
        """Current cycle (since the start)."""
        return int(self.ist[0])

    # -- input ---------------------------------------------------------------------------------

    def add_imu(self, dalpha: F64, dv: F64) -> None:
        """Raw increments (FRD) of the next cycles ``imu_end + 1 ...``."""
        da = np.asarray(dalpha, dtype=np.float64).reshape(-1, 3)
        dvv = np.asarray(dv, dtype=np.float64).reshape(-1, 3)
        if da.shape != dvv.shape:
            raise ValueError("dalpha and dv must have the same shape (k, 3)")
        if len(da):
            self._pending.append((da, dvv))
            self._pending_rows += len(da)
            self.imu_end += len(da)

    def _fill_ring(self, upto: int) -> None:
        """Move pending increments of cycles up to ``upto`` into the ring."""
        cap = self.ring_da.shape[0]
        first = self.imu_end - self._pending_rows + 1  # cycle of the first pending row
        while self._pending and first <= upto:
            da, dv = self._pending[0]
            take = min(len(da), upto - first + 1)
            idx = (first + np.arange(take)) % cap
            self.ring_da[idx] = da[:take]
            self.ring_dv[idx] = dv[:take]
            if take == len(da):
                self._pending.pop(0)
            else:
                self._pending[0] = (da[take:], dv[take:])
            self._pending_rows -= take
            first += take

    def insert(self, kind: int, m: int, z: Sequence[float], r: F64, uid: int) -> None:
        """Add a measurement of ``kind`` valid at cycle ``m`` (not after the current cycle).

        ``z`` (≤ 6,): the measured values as the model takes them (see ``_loop.apply_epoch``);
        ``r`` (d, d): its covariance; ``uid``: the caller's id, returned by :meth:`collect`.
        Delayed measurements (``m`` before the current cycle, or at it after its updates) roll
        the filter back and re-run it (docs/theory/aided_ins.md §7).
        """
        self.insert_many([(kind, m, z, r, uid)])

    def insert_many(self, rows: Sequence[tuple[int, int, Sequence[float], F64, int]]) -> None:
        """Insert several measurements ``(kind, m, z, r, uid)``.

        One rollback to the earliest delayed one.
        """
        if not rows:
            return
        k = len(rows)
        z = np.zeros((k, 6))
        rr = np.zeros((k, 3, 3))
        dim = np.empty(k, dtype=np.int64)
        for i, row in enumerate(rows):
            zv = np.asarray(row[2], dtype=np.float64).reshape(-1)
            z[i, : len(zv)] = zv
            ri = np.asarray(row[3], dtype=np.float64)
            dim[i] = ri.shape[0]
            rr[i, : dim[i], : dim[i]] = ri
        self.insert_arrays(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), z, rr,
                           dim, np.array([r[4] for r in rows]))  # fmt: skip

    def insert_arrays(self, kind: NDArray[np.int64], m: NDArray[np.int64], z: F64, r: F64,
                      dim: NDArray[np.int64], uid: NDArray[np.int64]) -> None:  # fmt: skip
        """Insert K measurements given as arrays.

        Kinds, validity cycles, values (K, 6), covariances (K, 3, 3; the leading dim × dim block
        used), dims, ids.
        """
        kind = np.asarray(kind, dtype=np.int64)
        m = np.asarray(m, dtype=np.int64)
        k = len(kind)
        if not k:
            return
        if np.any((kind < 0) | (kind >= len(KINDS))):
            raise ValueError(f"unknown measurement kind in {sorted(set(kind.tolist()))}")
        oldest = self.m - self.window
        if np.any(m < oldest):
            raise ValueError(
                f"measurement at cycle {int(m.min())} is older than the rollback window "
                f"({self.window} cycles before cycle {self.m})"
            )
        n = self.h_n
        if n + k > len(self.h_m):
            self._h_alloc(max(2 * len(self.h_m), n + k))
        new = (m, kind, np.asarray(z, dtype=np.float64), np.asarray(r, dtype=np.float64),
               np.asarray(dim, dtype=np.int64), np.zeros(k, dtype=np.int64), np.zeros((k, 6)),
               np.asarray(uid, dtype=np.int64))  # fmt: skip
        old_key = self.h_m[:n] * 8 + self.h_kind[:n]
        new_key = m * 8 + kind
        if n == 0 or new_key.min() >= old_key[-1]:  # the common case: appended in order
            order = np.argsort(new_key, kind="stable")
            for name, add in zip(self._H, new, strict=True):
                getattr(self, name)[n : n + k] = add[order]
        else:
            order = np.argsort(np.concatenate([old_key, new_key]), kind="stable")
            for name, add in zip(self._H, new, strict=True):
                arr = getattr(self, name)
                arr[: n + k] = np.concatenate([arr[:n], add])[order]
        self.h_n = n + k
        late = (m < self.m) | ((m == self.m) & (self.ist[1] != 0))
        if np.any(late):
            self._rollback(int(m[late].min()))

    def _rollback(self, m: int) -> None:
        slot = self._slot(m)
        if len(self.ck_m) == 0 or self.ck_m[slot] != m:
            raise RuntimeError(f"no checkpoint at cycle {m} (not a grid point, or too old)")
        back_to = self.m
        was_posterior = bool(self.ist[1])
        self.nav[:] = self.ck_nav[slot]
        self.est[:] = self.ck_est[slot]
        self.p[:] = self.ck_p[slot]
        self.acc[:] = 0.0
        self.ist[0], self.ist[1] = m, 0
        self.rollbacks += 1
        if back_to > m:
            self._advance(back_to, False)
        if was_posterior:
            self.make_posterior()

    # -- running -------------------------------------------------------------------------------

    def _call(self, target: int, record: bool) -> None:
        _loop.advance(
            target, self.ist, self.nav, self.est, self.p, self.acc, self.ring_da, self.ring_dv,
            self.periods, self.k0, self.period_ns, self.layout.offsets, self.model.beta,
            self.model.q, self.model.q_ins, self.layout.n_coupled, self.gmodel, self.p_int,
            self.gstep, self.ck_m, self.ck_nav, self.ck_est, self.ck_p, self.h_m, self.h_kind,
            self.h_z,
            self.h_r, self.h_dim, self.h_status, self.h_out, self.h_n, self.levers,
            self.wheel_mask, *self.igrf, self.gate, self.sr, self.sv, self.sc, self.da_c,
            self.dv_c, self.out_period, record, self.out_m, self.out_nav, self.out_est,
            self.out_p,
        )  # fmt: skip

    def _advance(self, target: int, record: bool) -> None:
        cap = self.ring_da.shape[0]
        step = cap - self.window - 2
        if record:  # room in the output buffer for every output epoch of a call
            step = min(step, max(1, (len(self.out_m) - 2) * self.out_period))
        self._first_rate()
        while self.m < target:
            upto = min(target, self.m + step)
            self._fill_ring(upto)
            if record and int(self.ist[3]) + (upto - self.m) // self.out_period + 2 > len(
                self.out_m
            ):
                self._spill()
            self._call(upto, record)

    def advance(self, target: int) -> None:
        """Integrate up to cycle ``target`` (its increments added), stopping at its prior.

        The posterior states at the output epochs passed are stored (:meth:`outputs`).
        """
        if target > self.imu_end:
            raise ValueError(f"cycle {target} is beyond the increments received ({self.imu_end})")
        self._advance(target, True)
        self._prune()

    def record_now(self) -> None:
        """Make the current cycle posterior and store it if it is an output epoch."""
        self.make_posterior()
        if int(self.ist[3]) + 1 > len(self.out_m):
            self._spill()
        _loop.record_output(self.ist, self.nav, self.est, self.p, self.k0, self.out_period,
                            self.out_m, self.out_nav, self.out_est, self.out_p)  # fmt: skip

    def _spill(self) -> None:
        k = int(self.ist[3])
        if k:
            self._spilled.append(Snapshots(self.out_m[:k].copy(), self.out_nav[:k].copy(),
                                           self.out_est[:k].copy(), self.out_p[:k].copy()))
            self.ist[3] = 0

    def outputs(self) -> Snapshots:
        """The output-epoch states stored since the last call (cycles ``m`` increasing)."""
        self._spill()
        parts, self._spilled = self._spilled, []
        if not parts:
            n = self.layout.n
            return Snapshots(np.zeros(0, dtype=np.int64), np.zeros((0, 27)), np.zeros((0, n)),
                             np.zeros((0, n, n)))  # fmt: skip
        return Snapshots(*(np.concatenate([getattr(p, f) for p in parts])
                           for f in ("m", "nav", "est", "p")))  # fmt: skip

    def _first_rate(self) -> None:
        """At cycle 0 use the body rate of cycle 1.

        That is ``twist.angular`` of the first truth message (docs/messages.md): its raw
        increments are copied into the state (and the checkpoint).
        """
        if self._rate0 or self.m != 0 or self.imu_end < 1:
            return
        self._fill_ring(1)
        cap = self.ring_da.shape[0]
        self.nav[21:24] = self.ring_da[1 % cap]
        self.nav[24:27] = self.ring_dv[1 % cap]
        if len(self.ck_m):
            self._checkpoint_now()
        self._rate0 = True

    def make_posterior(self) -> None:
        """Apply the current cycle's measurements if not done yet."""
        self._first_rate()
        _loop.make_posterior(
            self.ist, self.nav, self.est, self.p, self.layout.offsets, self.period_ns,
            self.h_m, self.h_kind, self.h_z, self.h_r, self.h_dim, self.h_status, self.h_out,
            self.h_n, self.levers, self.wheel_mask, *self.igrf, self.gate,
        )  # fmt: skip

    def snapshot(self) -> Snapshot:
        """The posterior state at the current cycle (copies)."""
        self.make_posterior()
        return Snapshot(self.m, self.nav.copy(), self.est.copy(), self.p.copy())

    def collect(self) -> MeasurementResults:
        """Results of the measurements applied for the first time since the last call."""
        rows = np.flatnonzero(self.h_status[: self.h_n] == 1)
        out = MeasurementResults(self.h_uid[rows].copy(), self.h_kind[rows].copy(),
                                 self.h_m[rows].copy(), self.h_out[rows, :3].copy(),
                                 self.h_out[rows, 3].copy(), self.h_out[rows, 4].astype(np.int64),
                                 self.h_out[rows, 5] != 0.0)  # fmt: skip
        self.h_status[rows] = 2
        return out

    def _prune(self) -> None:
        """Forget reported measurements older than the rollback window."""
        n = self.h_n
        if not n:
            return
        old = self.m - self.window
        keep_from = int(np.searchsorted(self.h_m[:n], old, side="left"))
        pending = np.flatnonzero(self.h_status[:keep_from] != 2)
        if pending.size:  # unreported rows stay (collect reports them)
            keep_from = int(pending[0])
        if keep_from < max(256, n // 2):  # amortized: shift only when much can go
            return
        k = n - keep_from
        for a in self._h_arrays():
            a[:k] = a[keep_from:n].copy()
        self.h_n = k

    def _slot(self, m: int) -> int:
        return ((self.k0 + m) // self.gstep) % max(len(self.ck_m), 1)

    def _checkpoint_now(self) -> None:
        slot = self._slot(self.m)
        self.ck_m[slot] = self.m
        self.ck_nav[slot] = self.nav
        self.ck_est[slot] = self.est
        self.ck_p[slot] = self.p

