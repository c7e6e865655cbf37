"""Offset history of a variation trajectory on the cycle grid (inputs of Savage 2020 eq. (5)-(7)).

The variation differs from the reference by an attitude offset ``C_Bvar^Bref`` (eq. (5)), a lever
arm ``l^Bref`` and a displacement ``s^Bvar`` (eq. (7)). :class:`OffsetModel` holds them as
functions of time (plain arguments: metres, radians, seconds; body vectors FRD) and evaluates
them at ``t_m = m T``, vectorized over the cycles. The scenario keys and their model are in
:mod:`strapdown_ros.config.variation`; theory and conventions in docs/theory/offsets.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.scan_filter import LinearFilter, smooth_attitude_offset
from strapdown_ros.core.threads import rowwise

__all__ = [
    "OffsetHistory",
    "OffsetModel",
    "RandomBending",
    "RasterScan",
    "SegmentsScan",
    "Sinusoids",
    "SweepScan",
    "bending_sinusoids",
]

LongArray = NDArray[np.longdouble]

_LD = np.longdouble
_X, _Y, _Z = np.eye(3)


@dataclass(frozen=True)
class OffsetHistory:
    """Offsets at cycles m = 0..M (Savage 2020 eqs. (5), (7)).

    Attributes
    ----------
    lever_arm : array (M+1, 3)
        ``l^Bref_m`` (m, Bref FRD axes): constant lever arm plus bending.
    displacement : array (M+1, 3)
        ``s^Bvar_m`` (m, Bvar FRD axes).
    c_bvar_bref : array (M+1, 3, 3)
        ``C_{Bvar_m}^{Bref}``: mounting times scan, smoothed by Appendix D.
    """

    lever_arm: F64
    displacement: F64
    c_bvar_bref: F64


# -- the model ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Sinusoids:
    """``Σ_j amp_j sin(2π f_j t + φ_j)`` per axis; arrays (K, 3) (m, Hz, rad)."""

    amplitude: F64
    frequency: F64
    phase: F64

    def __call__(self, t: F64) -> F64:
        """The sum at times ``t`` (s, (N,)): (N, 3) m (long ``t`` on two threads, same bits)."""
        return rowwise(self._sum, np.asarray(t, dtype=np.float64).reshape(-1))

    def _sum(self, t: F64) -> F64:
        out = np.zeros((t.size, 3))
        buf = np.empty((t.size, 3))
        tt = t[:, None]
        for amp, f, ph in zip(self.amplitude, self.frequency, self.phase, strict=True):
            # amp sin(2π f t + φ): K terms, each vectorized over the cycles, in place
            np.multiply(tt, 2.0 * np.pi * f, out=buf)
            buf += ph
            np.sin(buf, out=buf)
            buf *= amp
            out += buf
        return out


@dataclass(frozen=True)
class RandomBending:
    """Band-limited random bending (docs/theory/offsets.md).

    ``components`` sinusoids per axis with phases uniform in [0, 2π) and frequencies
    ``(k + u_k) B / K`` (one per sub-band of width B/K), each of amplitude ``σ sqrt(2/K)``:
    standard deviation ``sigma_m`` (m, (3,), >= 0) per axis, flat spectrum up to
    ``bandwidth_hz`` B > 0, bit-reproducible from ``seed`` (numpy ``default_rng``).
    """

    sigma_m: F64
    bandwidth_hz: float
    seed: int = 0
    components: int = 64


def bending_sinusoids(
    sinusoids: Sequence[tuple[ArrayLike, float, float]] = (),
    random: RandomBending | None = None,
) -> Sinusoids:
    """The bending added to the lever arm: the given sinusoids, then the random ones.

    Parameters
    ----------
    sinusoids : sequence of (amplitude (3,) m, frequency Hz > 0, phase rad)
        ``A sin(2π f t + p)`` per axis.
    random : RandomBending, optional
        Band-limited random motion appended after the sinusoids.
    """
    amps, freqs, phases = [], [], []
    for amplitude, frequency, phase in sinusoids:
        amps.append(np.asarray(amplitude, dtype=np.float64))
        freqs.append(np.full(3, float(frequency)))
        phases.append(np.full(3, float(phase)))
    if random is not None:
        n, band = int(random.components), float(random.bandwidth_hz)
        sigma = np.asarray(random.sigma_m, dtype=np.float64)
        rng = np.random.default_rng(random.seed)
        u = 1.0 - rng.random((n, 3))  # uniform in (0, 1]
        freqs.extend(band * (np.arange(n)[:, None] + u) / n)
        phases.extend(2.0 * np.pi * rng.random((n, 3)))
        amps.extend(np.tile(sigma * math.sqrt(2.0 / n), (n, 1)))
    shape = (len(amps), 3)
    return Sinusoids(
        np.reshape(np.asarray(amps, dtype=np.float64), shape),
        np.reshape(np.asarray(freqs, dtype=np.float64), shape),
        np.reshape(np.asarray(phases, dtype=np.float64), shape),
    )


def _triangle(t: F64, amplitude: float, rate: float) -> F64:
    """0 → +A → −A → +A … at ``rate`` (A per s), continuous and piecewise linear."""
    period = 4.0 * amplitude / rate
    u = np.mod(t / period, 1.0)
    return amplitude * np.where(u < 0.25, 4.0 * u, np.where(u < 0.75, 2.0 - 4.0 * u, 4.0 * u - 4.0))


def _axis_rotation(axis: ArrayLike, angle: ArrayLike) -> LongArray:
    """``I + sin θ (u×) + (1 - cos θ) (u×)²`` for the unit vector along ``axis``, in long double.

    The scans are evaluated in extended precision (where numpy's long double has it, e.g. the
    80-bit x87 format) and rounded once to float64, so that the offsets are orthonormal to the
    rounding of their elements at any angle (the float64 Rodrigues form reaches 3e-15 near π).
    """
    theta = np.asarray(angle, dtype=_LD)
    u = np.asarray(axis, dtype=_LD)
    u = u / np.sqrt(np.sum(u * u))
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]], dtype=_LD)
    k2 = np.outer(u, u) - np.eye(3, dtype=_LD)
    return (
        np.eye(3, dtype=_LD)
        + np.sin(theta)[..., None, None] * k
        + (1 - np.cos(theta))[..., None, None] * k2
    )


@dataclass(frozen=True)
class SegmentsScan:
    """Scan of constant Bvar-axis rates, held after the last segment.

    ``rates`` (K, 3) rad/s over ``durations`` (K,) s > 0, from t = 0 and the identity.
    """

    durations: F64
    rates: F64

    def __call__(self, t: F64) -> LongArray:
        """``C_scan`` at times ``t`` (s, (N,)): (N, 3, 3) in long double."""
        c = np.empty((t.size, 3, 3), dtype=_LD)
        start, c_start = 0.0, np.eye(3, dtype=_LD)
        for i, (dur, rate) in enumerate(zip(self.durations, self.rates, strict=True)):
            last = i == len(self.durations) - 1
            sel = (t >= start) & ((t < start + dur) | last)
            tau = np.minimum(t[sel] - start, dur)  # held at the end of the last segment
            speed = float(np.linalg.norm(rate))
            if speed == 0.0:
                c[sel] = c_start
            else:
                c[sel] = c_start @ _axis_rotation(rate, tau * speed)
                c_start = c_start @ _axis_rotation(rate, dur * speed)
            start += dur
        return c


@dataclass(frozen=True)
class SweepScan:
    """Triangular sweep 0 → +A → −A → +A … of the angle about ``axis``.

    ``axis`` (Bvar, non-zero, normalized here), amplitude (rad) and rate (rad/s) > 0, from
    ``start`` (s; identity before).
    """

    axis: F64
    amplitude: float  # rad, > 0
    rate: float  # rad/s, > 0
    start: float = 0.0  # s, >= 0

    def __post_init__(self) -> None:
        axis = np.asarray(self.axis, dtype=np.float64)
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ValueError("axis: must not be zero")
        object.__setattr__(self, "axis", axis / norm)

    def __call__(self, t: F64) -> LongArray:
        """``C_scan`` at times ``t`` (s, (N,)): (N, 3, 3) in long double."""
        angle = _triangle(np.maximum(t - self.start, 0.0), self.amplitude, self.rate)
        return _axis_rotation(self.axis, angle)


@dataclass(frozen=True)
class RasterScan:
    """Raster scan: azimuth sweeps about z with elevation steps about y.

    The azimuth ``az`` sweeps as :class:`SweepScan`; at each end of a sweep the elevation ``el``
    moves one ``step`` at ``elevation_rate`` (rows 0..rows-1 and back);
    ``C_scan = Rz(az) Ry(el)``. ``rows = 1`` or ``step = 0`` is the sweep.
    """

    amplitude: float  # rad
    rate: float  # rad/s
    step: float  # rad
    rows: int
    elevation_rate: float  # rad/s
    start: float  # s

    def __call__(self, t: F64) -> LongArray:
        """``C_scan`` at times ``t`` (s, (N,)): (N, 3, 3) in long double."""
        s = np.maximum(t - self.start, 0.0)
        if self.rows == 1 or self.step == 0.0:
            return _axis_rotation(_Z, _triangle(s, self.amplitude, self.rate))
        a, r = self.amplitude, self.rate
        step_time = abs(self.step) / self.elevation_rate
        unit = step_time + 2.0 * a / r  # one elevation step, then one full sweep
        u = s - a / r  # time since the end of the first half sweep (0 -> +A)
        j = np.floor(np.maximum(u, 0.0) / unit)  # completed step+sweep units
        w = np.maximum(u, 0.0) - j * unit  # time into unit j
        bounce = 2 * (self.rows - 1)  # rows 0..n-1..1 then again
        ji = j.astype(np.int64)
        row_from = _bounce(ji, self.rows, bounce)
        row_to = _bounce(ji + 1, self.rows, bounce)
        frac = np.minimum(w / step_time, 1.0)
        el = self.step * (row_from + (row_to - row_from) * frac)
        side = np.where(ji % 2 == 0, a, -a)  # azimuth at the start of unit j
        az_unit = side - np.sign(side) * r * np.maximum(w - step_time, 0.0)
        az = np.where(u < 0.0, r * s, az_unit)
        el = np.where(u < 0.0, 0.0, el)
        return _axis_rotation(_Z, az) @ _axis_rotation(_Y, el)


def _bounce(i: NDArray[np.int64], rows: int, period: int) -> NDArray[np.float64]:
    r = np.mod(i, period)
    return np.where(r < rows, r, period - r).astype(np.float64)


@dataclass(frozen=True)
class OffsetModel:
    """The offsets as functions of time.

    Plain arguments; built from the scenario by
    :meth:`strapdown_ros.config.variation.VariationSpec.offset_model`.

    Attributes
    ----------
    lever_arm : array (3,)
        Constant lever arm (m, Bref FRD).
    bending : Sinusoids
        ``t (N,) s -> (N, 3) m``: bending added to the lever arm.
    displacement : array (3,)
        Constant ``s^Bvar`` (m, Bvar FRD).
    mounting_rph : array (3,)
        Mounting roll, pitch, yaw (rad): ``C_mount = Rz(yaw) Ry(pitch) Rx(roll)``.
    scan : SegmentsScan, SweepScan, RasterScan or None
        ``t (N,) s -> (N, 3, 3)``: ``C_scan`` (unfiltered), None without a scan.
    filter : LinearFilter or None
        Appendix D smoothing filter of the scan (None: no smoothing).
    lag_compensation : bool
        Advance the filter input by ``round(τ_Flt/T)`` cycles.
    """

    lever_arm: F64 = field(default_factory=lambda: np.zeros(3))
    bending: Sinusoids = field(default_factory=bending_sinusoids)
    displacement: F64 = field(default_factory=lambda: np.zeros(3))
    mounting_rph: F64 = field(default_factory=lambda: np.zeros(3))
    scan: SegmentsScan | SweepScan | RasterScan | None = None
    filter: LinearFilter | None = None
    lag_compensation: bool = False

    @property
    def mount(self) -> F64:
        """``C_mount`` (Bvar relative to Bref at zero scan), ``dcm_from_euler`` convention."""
        return self._mount_ld().astype(np.float64)

    def _mount_ld(self) -> LongArray:
        roll, pitch, yaw = self.mounting_rph
        return _axis_rotation(_Z, yaw) @ _axis_rotation(_Y, pitch) @ _axis_rotation(_X, roll)

    def lever_arm_at(self, t: ArrayLike) -> F64:
        """``l^Bref(t)`` (m, Bref FRD) at times ``t`` (s, shape (N,)): constant plus bending."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return self.lever_arm + self.bending(t)

    def history(self, period_s: float, cycles: int) -> OffsetHistory:
        """Offsets at ``t_m = m T``, m = 0..``cycles``.

        Parameters
        ----------
        period_s : float
            Cycle period T (s), > 0.
        cycles : int
            Last cycle M (>= 0).

        Returns
        -------
        OffsetHistory
            Bit-reproducible; the history for M is a prefix of the history for any M' > M.
        """
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period_s: must be > 0, got {period_s!r}")
        if isinstance(cycles, bool) or not isinstance(cycles, int | np.integer) or cycles < 0:
            raise ValueError(f"cycles: must be an integer >= 0, got {cycles!r}")
        n = int(cycles) + 1
        t = np.arange(n) * period_s
        lever_arm = self.lever_arm_at(t)
        displacement = np.tile(self.displacement, (n, 1))
        if self.scan is None:
            return OffsetHistory(lever_arm, displacement, np.tile(self.mount, (n, 1, 1)))
        ahead = 0
        if self.filter is not None and self.lag_compensation:
            ahead = max(self.filter.compensation_shift(), 0)  # the shifted filter looks ahead
        t_ext = np.arange(n + ahead) * period_s
        c = (self._mount_ld() @ self.scan(t_ext)).astype(np.float64)  # rounded once
        if self.filter is not None:
            c = smooth_attitude_offset(c, self.filter, self.lag_compensation)
        return OffsetHistory(lever_arm, displacement, c[:n])
