"""Sensor timing errors: stamp offset, clock drift, stamp jitter, transport latency, drops.

ROS-free numpy. A sensor's messages are numbered by their sample index ``k`` (the epoch on the
sensor's grid: ``(t − grid0) / P``); every random draw of sample k comes from a block of
:data:`BLOCK` draws seeded by ``(seed, stream, block)``, so the errors of a sample do not depend
on how the stream is cut into pieces. With ``t`` the true measurement time (ns):

    stamp_k   = t_k + offset + round(drift_ppm·1e-6 (t_k − t0)) + round(jitter_s·1e9 n_k)
    arrival_k = (its arrival without timing errors) + latency
    dropped_k = u_k < drop_probability  or  t_k in drops

(``n_k ~ N(0, 1)``, ``u_k ~ U[0, 1)``). :func:`accumulate_dropped` carries the increments of
dropped IMU samples into the next kept one (``accumulated``); with ``lost`` they are discarded.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.core.array_types import F64, I64

__all__ = ["BLOCK", "TimingModel", "accumulate_dropped"]


#: Draws per seeded block.
BLOCK = 4096


@dataclass
class TimingModel:
    """The timing errors of one sensor stream.

    All times ns; ``stream`` separates the draws of sensors sharing a seed.
    """

    t0_ns: int
    period_ns: int
    grid0_ns: int
    offset_ns: int = 0
    drift_ppm: float = 0.0
    jitter_s: float = 0.0
    latency_ns: int = 0
    drop_probability: float = 0.0
    drops_ns: tuple[int, ...] = ()
    seed: int = 0
    stream: int = 0
    _blocks: dict[int, tuple[F64, F64]] = field(default_factory=dict, repr=False)

    def index(self, t_ns: I64) -> I64:
        """Sample index of true measurement times (on the sensor's grid)."""
        return (np.asarray(t_ns, dtype=np.int64) - self.grid0_ns) // self.period_ns

    def _draws(self, k: I64) -> tuple[F64, F64]:
        """``(n_k, u_k)``: standard normal and uniform draws of samples k."""
        k = np.asarray(k, dtype=np.int64)
        n, u = np.empty(k.shape), np.empty(k.shape)
        blocks = k // BLOCK
        for b in np.unique(blocks).tolist():
            if b not in self._blocks:
                rng = np.random.default_rng([self.seed, self.stream, int(b) + (1 << 40)])
                self._blocks[b] = (rng.standard_normal(BLOCK), rng.random(BLOCK))
            sel = blocks == b
            nb, ub = self._blocks[b]
            n[sel], u[sel] = nb[k[sel] % BLOCK], ub[k[sel] % BLOCK]
        return n, u

    def stamps(self, t_ns: I64) -> I64:
        """Published stamps of true measurement times ``t_ns``."""
        t = np.asarray(t_ns, dtype=np.int64)
        out = t + self.offset_ns
        if self.drift_ppm:
            out = out + np.rint(self.drift_ppm * 1e-6 * (t - self.t0_ns)).astype(np.int64)
        if self.jitter_s:
            n, _ = self._draws(self.index(t))
            out = out + np.rint(self.jitter_s * 1e9 * n).astype(np.int64)
        return out

    def dropped(self, t_ns: I64) -> NDArray[np.bool_]:
        """Whether each sample is dropped."""
        t = np.asarray(t_ns, dtype=np.int64)
        out = np.isin(t, np.asarray(self.drops_ns, dtype=np.int64))
        if self.drop_probability:
            _, u = self._draws(self.index(t))
            out |= u < self.drop_probability
        return out


def accumulate_dropped(
    dalpha: F64, dv: F64, dropped: NDArray[np.bool_], pending: tuple[F64, F64, int] | None
) -> tuple[F64, F64, NDArray[np.int64], tuple[F64, F64, int] | None]:
    """Increments of the kept samples with those of the dropped ones before each added in.

    ``Δα = ∫ω dt`` and ``Δv = ∫a_SF dt`` in body axes (docs/interface.md §2) add over adjacent
    intervals, so the sum is the increment over the longer interval. ``pending``: the sum and
    count of dropped samples carried from the previous call (the last ones of a piece).

    Returns ``(dalpha, dv, cycles, pending)`` for the kept rows: ``cycles`` = the number of
    sample intervals each kept message now covers.
    """
    kept = np.flatnonzero(~dropped)
    run = np.cumsum(np.concatenate([[0], (~dropped).astype(np.int64)]))[:-1]  # kept rows before
    ca = np.zeros((kept.size + 1, 3))
    cv = np.zeros((kept.size + 1, 3))
    counts = np.zeros(kept.size + 1, dtype=np.int64)
    if pending is not None:
        ca[0] += pending[0]
        cv[0] += pending[1]
        counts[0] += pending[2]
    # every row goes to the kept row at or after it (the next kept one); after the last: pending
    target = run.copy()  # index of the next kept row among the kept rows
    np.add.at(ca, target, dalpha)
    np.add.at(cv, target, dv)
    np.add.at(counts, target, 1)
    rest = (ca[-1], cv[-1], int(counts[-1])) if counts[-1] else None
    return ca[:-1], cv[:-1], counts[:-1], rest
