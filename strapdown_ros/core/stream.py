"""A generated stream: increments and truth on the cycle grid of docs/interface.md §2.

A stream has cycles m = 0..M at ``t_m = t0 + m T`` (T an integer number of nanoseconds).
Increments exist for m = 1..M and cover ``(t_{m-1}, t_m]``; truth exists for m = 0..M. All
quantities are in the core's frames: body FRD, inertial E0 (docs/interface.md §1). Conversion to ROS
messages
(FLU, ENU, ECEF) happens in :mod:`strapdown_ros.messages`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.core.array_types import F64


@dataclass(frozen=True)
class Stream:
    """Increments and E0 truth of one stream (reference, variation, ...).

    Attributes
    ----------
    t0_ns : int
        Stamp of cycle 0 (ns since the Unix epoch; ``start_time_s`` of the scenario).
    period_ns : int
        Cycle period T (ns), > 0.
    dalpha : array (M, 3)
        Δα_m, integrated body angular rate over cycle m = 1..M (rad, FRD).
    dv : array (M, 3)
        Δv_m, integrated specific force over cycle m = 1..M (m/s, FRD).
    c_b_e0 : array (M+1, 3, 3)
        ``C_B^E0`` at t_m, body FRD to E0.
    v_e0 : array (M+1, 3)
        Inertial velocity ``dR^E0/dt`` at t_m (m/s, E0 axes).
    r_e0 : array (M+1, 3)
        Position ``R^E0`` at t_m (m).
    gravity_model : str
        Gravitation model of the stream (docs/interface.md §1, e.g. ``"j2"``); the exactness rule
        uses it.
    e0_epoch_ns : int or None
        Instant (ns since the epoch) at which E0 coincides with ECEF: the start of the whole
        stream (docs/interface.md §1). A piece of a longer stream keeps the start of the whole;
        ``None``
        means ``t0_ns``.
    """

    t0_ns: int
    period_ns: int
    dalpha: F64
    dv: F64
    c_b_e0: F64
    v_e0: F64
    r_e0: F64
    gravity_model: str = "j2"
    e0_epoch_ns: int | None = None

    def __post_init__(self) -> None:
        """Check shapes so that a malformed stream fails where it is made."""
        if self.e0_epoch_ns is None:
            object.__setattr__(self, "e0_epoch_ns", self.t0_ns)
        m = self.dalpha.shape[0]
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")
        if self.dalpha.shape != (m, 3) or self.dv.shape != (m, 3):
            raise ValueError("dalpha and dv must both have shape (M, 3)")
        if self.c_b_e0.shape != (m + 1, 3, 3):
            raise ValueError(f"c_b_e0 must have shape ({m + 1}, 3, 3), got {self.c_b_e0.shape}")
        if self.v_e0.shape != (m + 1, 3) or self.r_e0.shape != (m + 1, 3):
            raise ValueError(f"v_e0 and r_e0 must have shape ({m + 1}, 3)")

    @property
    def cycles(self) -> int:
        """Number M of increment cycles (truth has M + 1 samples)."""
        return int(self.dalpha.shape[0])

    @property
    def period(self) -> float:
        """T (s)."""
        return self.period_ns * 1e-9

    @property
    def t(self) -> F64:
        """Times (s) of the truth samples since the E0 epoch, m = 0..M (``C_E^E0 = Rz(ω t)``).

        Computed from integer nanoseconds, so equal to ``t_m - t0`` exactly for a whole stream.
        """
        offset = self.t0_ns - int(self.e0_epoch_ns)  # type: ignore[arg-type]
        return (offset + np.arange(self.cycles + 1, dtype=np.int64) * self.period_ns) * 1e-9

    @property
    def stamps_ns(self) -> NDArray[np.int64]:
        """Stamps t_m (ns since the epoch), m = 0..M."""
        return self.t0_ns + np.arange(self.cycles + 1, dtype=np.int64) * self.period_ns

    def window(self, m0: int, m1: int) -> Stream:
        """Cycles ``m0..m1`` (truth m0..m1, increments m0+1..m1), restamped at m0 (same E0)."""
        return replace(
            self,
            t0_ns=self.t0_ns + m0 * self.period_ns,
            dalpha=self.dalpha[m0:m1],
            dv=self.dv[m0:m1],
            c_b_e0=self.c_b_e0[m0 : m1 + 1],
            v_e0=self.v_e0[m0 : m1 + 1],
            r_e0=self.r_e0[m0 : m1 + 1],
        )
