"""Maneuver segments in navigation terms: the ``segments`` trajectory kind.

A trajectory is an initial state (geodetic position, NED velocity, roll/pitch/heading of the
body FRD frame w.r.t. NED) followed by a list of segments, each holding constant Euler-angle
rates and a constant along-track acceleration, a target climb rate, or a constant NED
acceleration — the motion-definition style of common INS simulators (e.g. gnss-ins-sim motion
files). Between segments the commanded rates and accelerations blend over ``transition_s`` with
the C² quintic smoothstep ``w(x) = 10x³ - 15x⁴ + 6x⁵`` (``w'`` and ``w''`` vanish at both ends),
so attitude rates and accelerations have no step unless ``transition_s = 0``.

Everything but latitude and longitude is a closed-form polynomial in time per piece (each
segment is a blending piece of length ``transition_s`` followed by a steady piece). Latitude and
longitude integrate the geodetic rates (Groves 2013 eq. (2.111))::

    φ' = v_N / (R_N(φ) + h),   λ' = v_E / ((R_E(φ) + h) cos φ),   h' = -v_D

by Chebyshev collocation piece by piece (:class:`LatLonPath`): the returned position is the
exact integral of an interpolant of the geodetic rates that matches them to ~1e-15 relative, so
the returned velocity is the time derivative of the returned position, and the position is
within float64 rounding of the exact solution (measured ≤ 0.5 ulp of latitude, ~4e-10 m).
Frames and units: NED, FRD, rad, m, s (SPEC §1); see ``docs/theory/trajectories.md`` (section
"segments").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import chebyshev as cheb
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.earth import geodetic_rates, radii
from strapdown_ros.core.trajectory.base import LocalTruth

__all__ = [
    "LatLonPath",
    "Segment",
    "SegmentsTrajectory",
    "parse_initial",
    "read_number",
    "read_vector3",
    "smoothstep5",
]

Array = NDArray[np.float64]

#: Number of polynomial coefficients stored per channel (degree ≤ 7).
_NCOEF = 8
#: Channels of a piece: Euler angles, horizontal pair, down velocity, altitude.
_ROLL, _PITCH, _HEAD, _P, _Q, _VD, _ALT = range(7)
_NCHAN = 7
#: Horizontal parametrisation of a piece: (P, Q) = (speed, course) or (v_N, v_E).
_TRACK, _NED = 0, 1

#: Limits of a physically meaningful trajectory (SPEC §5: impossible trajectories are rejected).
PITCH_LIMIT = math.radians(89.9)
ALTITUDE_MIN = -10_000.0
LATITUDE_LIMIT = math.radians(89.9)

SEGMENT_KEYS = (
    "duration_s",
    "roll_rate_dps",
    "pitch_rate_dps",
    "heading_rate_dps",
    "accel_mps2",
    "climb_rate_mps",
    "accel_ned_mps2",
    "transition_s",
)
INITIAL_KEYS = (
    "latitude_deg",
    "longitude_deg",
    "altitude_m",
    "velocity_ned_mps",
    "attitude_rph_deg",
)

# Quintic smoothstep and its integral, ascending powers of x in [0, 1].
_W = np.array([0.0, 0.0, 0.0, 10.0, -15.0, 6.0])
_ONE_MINUS_W = np.array([1.0, 0.0, 0.0, -10.0, 15.0, -6.0])


def smoothstep5(x: ArrayLike) -> Array:
    """C² blending weight ``w(x) = 10x³ - 15x⁴ + 6x⁵`` on [0, 1] (clipped outside).

    ``w(0) = 0``, ``w(1) = 1``, ``w' = w'' = 0`` at both ends, ``∫₀¹ w = 1/2``.
    """
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return x**3 * (10.0 + x * (-15.0 + 6.0 * x))


def _pad(c: ArrayLike) -> Array:
    c = np.trim_zeros(np.atleast_1d(np.asarray(c, dtype=np.float64)), "b")
    if c.size > _NCOEF:
        raise AssertionError("polynomial degree exceeds storage")
    out = np.zeros(_NCOEF)
    out[: c.size] = c
    return out


def _integral(c: Array, length: float, start: float) -> Array:
    """``start + L ∫₀^x c(ξ) dξ`` for a rate polynomial ``c`` in normalised time x = u/L."""
    out = npoly.polyint(c) * length
    out[0] = start
    return out


def _horner(coef: Array, x: Array | float) -> Array:
    """Evaluate polynomials ``coef[..., k]`` (ascending) at ``x`` (broadcast over ``...``)."""
    out = coef[..., -1].copy()
    for k in range(coef.shape[-1] - 2, -1, -1):
        out = out * x + coef[..., k]
    return out


def _dcm_rph(roll: Array, pitch: Array, heading: Array) -> Array:
    """``C_B^N = Rz(ψ) Ry(θ) Rx(φ)`` (N, 3, 3), written out (as ``dcm_from_euler``)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    ch, sh = np.cos(heading), np.sin(heading)
    chsp, shsp = ch * sp, sh * sp
    c = np.empty((roll.size, 3, 3))
    c[:, 0, 0] = ch * cp
    c[:, 0, 1] = chsp * sr - sh * cr
    c[:, 0, 2] = chsp * cr + sh * sr
    c[:, 1, 0] = sh * cp
    c[:, 1, 1] = shsp * sr + ch * cr
    c[:, 1, 2] = shsp * cr - ch * sr
    c[:, 2, 0] = -sp
    c[:, 2, 1] = cp * sr
    c[:, 2, 2] = cp * cr
    return c


def _horner_gather(coef: Array, k: Array, x: Array, channels: Sequence[int] | None = None) -> Array:
    """``coef[k[n], ch, ·]`` evaluated at ``x[n]``, shape (N, C) in ``channels`` order.

    Memory is O(N·C) (no (N, C, degree) gather).
    """
    channels = range(coef.shape[1]) if channels is None else channels
    out = np.empty((x.size, len(channels)))
    for i, ch in enumerate(channels):
        acc = coef[k, ch, -1]
        for j in range(coef.shape[2] - 2, -1, -1):
            acc = acc * x + coef[k, ch, j]
        out[:, i] = acc
    return out


# ---------------------------------------------------------------------------------------------
# Latitude/longitude from a known velocity and altitude history.


def _cheb_lobatto(n: int) -> tuple[Array, Array, Array, Array]:
    """Chebyshev–Lobatto machinery on ``x ∈ [-1, 1]`` with ``n`` points.

    Returns the ascending points ``x`` (n,), the values-to-coefficients matrix ``to_coef``
    (n, n) of the degree ``n-1`` interpolant (DCT-I), the matrix ``integ`` (n+1, n) mapping its
    Chebyshev coefficients to those of its integral from -1, and ``quad`` (n, n) mapping values
    at the points to that integral at the points (row n-1: Clenshaw–Curtis weights).
    """
    m = n - 1
    i = np.arange(n)
    x = -np.cos(np.pi * i / m)
    x[0], x[-1] = -1.0, 1.0
    # T_k(x_i) = cos(k π (m - i)/m), with the integer angle reduced exactly.
    tk = np.cos(np.pi * ((np.outer(m - i, np.arange(n + 1)) % (2 * m)) / m))  # (n, n+1)
    w = np.full(n, 2.0 / m)
    w[[0, -1]] = 1.0 / m
    to_coef = tk[:, :n].T * w
    to_coef[[0, -1]] *= 0.5
    integ = cheb.chebint(np.eye(n), lbnd=-1.0, axis=0)
    quad = tk @ integ @ to_coef
    return x, to_coef, integ, quad


def _clenshaw(c: Sequence[float], x: Array) -> Array:
    """Chebyshev series ``Σ c_k T_k(x)`` at ``x`` (Clenshaw recurrence)."""
    if len(c) == 1:
        return np.full(x.size, c[0])
    two_x = 2.0 * x
    b1 = np.full(x.size, c[-1])
    b2 = np.zeros(x.size)
    for ck in c[-2:0:-1]:
        b = two_x * b1
        b -= b2
        b += ck
        b1, b2 = b, b1
    b1 *= x
    b1 -= b2
    b1 += c[0]
    return b1


def _sort(t: Array) -> tuple[Array | None, Array]:
    """``(order, t[order])``, or ``(None, t)`` when ``t`` is already non-decreasing."""
    if t.size < 2 or not np.any(t[1:] < t[:-1]):
        return None, t
    order = np.argsort(t, kind="stable")
    return order, t[order]


def _bounds(starts: Array, ts: Array) -> Array:
    """Slice bounds into sorted ``ts`` per interval beginning at ``starts`` (first/last open)."""
    return np.concatenate(([0], np.searchsorted(ts, starts[1:], side="left"), [ts.size]))


class LatLonPath:
    """Geodetic latitude and longitude integrated from ``v_N(t)``, ``v_E(t)``, ``h(t)``.

    Solves ``φ' = v_N/(R_N(φ)+h)``, ``λ' = v_E/((R_E(φ)+h) cos φ)`` (Groves 2013 eq. (2.111))
    by spectral collocation. Each piece ``[breaks[k], breaks[k+1]]`` (where higher derivatives
    of the velocity may jump) is cut into equal intervals of at most :attr:`MAX_STEP`; on each
    interval the rates are replaced by their degree ``NODES - 1`` Chebyshev interpolant on
    ``NODES`` Chebyshev–Lobatto points, and the position is the exact integral of that
    interpolant (a Chebyshev series of degree ``NODES``), continued from the previous interval.
    :meth:`derivative` returns the interpolant, i.e. the exact time derivative of the position.

    * ``φ`` enters the rates only through ``R_N``, ``R_E`` and ``cos φ``, so the collocation
      equations are solved by Picard iteration over the whole path at once (vectorized). The
      error after m sweeps is ≤ ``(L T)^m/m!`` times the first, with ``L = |∂φ'/∂φ| ≲ 3e²|φ'|/2``
      (``L T ≈ 1e-4`` for 600 s at 150 m/s); the iteration stops one sweep after the update
      falls below :attr:`PICARD_TOL` (1e-17 rad). ``λ`` does not feed back: one quadrature.
    * Interpolation. An interval is accepted when the last two Chebyshev coefficients of both
      rates are at most ``max(TOL · max|rate| over the path, NOISE · rounding level of the
      samples on the interval)``, otherwise it is halved and everything is solved again (down
      to ``2 MIN_STEP``). The rounding level is ``ε |rate|``, plus ``|λ' tan φ| ulp(φ)`` for
      ``λ'`` (the ill-conditioning of ``1/cos φ`` near the poles). For rates analytic on each
      piece the coefficients decay geometrically, so the interpolation error is of the size of
      the accepted tail: ``|derivative - rates| ≲ 2e-15 |rate|max`` (1.5e-13 m/s measured at
      150-200 m/s), and the position error, its integral, is ≤ ``2 TOL T v_max`` = 2e-10 m
      for 600 s at 150 m/s (away from the poles).
    * Rounding. The position is ``lat0 + (S_j + δ_j(x))``, the small offsets added first, so
      it is rounded once, to 0.5 ulp of latitude (3.5e-10 m at 45°). For evaluation, trailing
      coefficients of ``δ_j`` summing to ≤ :attr:`SERIES_TOL` (1e-20 rad) are dropped.

    Measured against a 34-digit Taylor solution (mpmath) of the same ODE: ≤ 0.5 ulp of latitude
    over the 600 s default scenario (3.5e-10 m north, 6e-11 m east; DOP853 at rtol 1e-13, the
    previous method, reaches 1.6e-9 m), 6.3e-10 m for 20°/s turns at 250 m/s, 6.9e-10 m at
    89.85°. The construction involves no adaptive step control on floating-point noise beyond
    the halving rule above: the same inputs give the same bits.

    Parameters
    ----------
    breaks : array (K+1,)
        Increasing piece boundaries (s); the path covers ``[breaks[0], breaks[-1]]``.
    lat0, lon0 : float
        Latitude and longitude at ``breaks[0]`` (rad).
    velocity : callable
        ``velocity(t) -> (v_N, v_E, h)`` for an array ``t`` (s): NED velocity components
        relative to the Earth (m/s) and ellipsoidal altitude (m). Smooth (analytic) on each piece.
    """

    #: Largest initial interval (s).
    MAX_STEP = 20.0
    #: Chebyshev–Lobatto points per interval (rate interpolant of degree NODES - 1).
    NODES = 16
    #: Accepted size of the last two Chebyshev coefficients, relative to the largest rate.
    TOL = 1e-15
    #: Picard update (rad) below which one last sweep is made.
    PICARD_TOL = 1e-17
    #: Trailing Chebyshev coefficients of the position summing to at most this (rad, 6e-14 m)
    #: are dropped for evaluation.
    SERIES_TOL = 1e-20
    #: Multiple of the rounding level of the rate samples accepted as the coefficient tail.
    NOISE = 16.0
    #: Intervals of at most twice this length (s) are not halved further.
    MIN_STEP = 5e-4

    _cheb = _cheb_lobatto(NODES)

    def __init__(
        self,
        breaks: ArrayLike,
        lat0: float,
        lon0: float,
        velocity: Callable[[Array], tuple[Array, Array, Array]],
    ) -> None:
        self._velocity = velocity
        self.lat0, self.lon0 = float(lat0), float(lon0)
        breaks = np.asarray(breaks, dtype=np.float64)
        lo: list[float] = []
        hi: list[float] = []
        for a, b in zip(breaks[:-1], breaks[1:], strict=True):
            if b <= a:
                continue
            m = math.ceil((b - a) / self.MAX_STEP)
            edges = a + (b - a) * np.arange(m + 1) / m
            edges[-1] = b
            lo.extend(edges[:-1])
            hi.extend(edges[1:])
        self._lo = np.array(lo)
        self._hi = np.array(hi)
        if not lo:
            self._coef = np.zeros((0, self.NODES + 1, 2))
            self._start = np.zeros((0, 2))
            self.node_t = breaks[:1].copy()
            self.node_y = np.array([[self.lat0, self.lon0]])
            return
        while np.any(bad := self._solve()):  # halve the unresolved intervals, solve again
            mid = 0.5 * (self._lo[bad] + self._hi[bad])
            self._lo = np.sort(np.concatenate([self._lo, mid]))
            self._hi = np.sort(np.concatenate([self._hi, mid]))

    def _solve(self) -> Array:
        """Collocation on the current intervals; returns the intervals to halve."""
        x, to_coef, integ, quad = self._cheb
        mid = 0.5 * (self._lo + self._hi)
        half = 0.5 * (self._hi - self._lo)
        t = mid[:, None] + half[:, None] * x
        t[:, 0], t[:, -1] = self._lo, self._hi
        vn, ve, h = (
            np.asarray(a, dtype=np.float64).reshape(t.shape) for a in self._velocity(t.ravel())
        )
        qt = quad.T

        def offsets(rate: Array) -> Array:
            d = half[:, None] * (rate @ qt)
            start = np.concatenate(([0.0], np.cumsum(d[:-1, -1])))
            return start[:, None] + d

        lat = np.full(t.shape, self.lat0)
        prev = np.zeros(t.shape)
        done = False
        for _ in range(60):
            lat_rate = vn / (radii(lat)[0] + h)
            off = offsets(lat_rate)
            lat = self.lat0 + off
            if done:
                break
            done = bool(np.max(np.abs(off - prev)) <= self.PICARD_TOL)
            prev = off
        else:  # pragma: no cover - the iteration contracts by ~L T per sweep
            raise RuntimeError("latitude/longitude: Picard iteration did not converge")
        lon_rate = ve / ((radii(lat)[1] + h) * np.cos(lat))
        rates = np.stack([lat_rate, lon_rate], axis=-1)  # (J, n, 2)
        coef = np.einsum("kn,jnc->jkc", to_coef, rates)  # (J, n, 2)
        tail = np.max(np.abs(coef[:, -2:]), axis=1)  # (J, 2)
        scale = np.max(np.abs(rates), axis=(0, 1))
        # Rounding of the samples: a few ulp, plus λ' tan φ times the rounding of φ for λ'.
        eps = np.finfo(np.float64).eps
        rel = np.stack([np.full(t.shape, eps), eps + np.abs(np.tan(lat) * np.spacing(lat))], -1)
        noise = self.NOISE * np.max(np.abs(rates) * rel, axis=1)  # (J, 2)
        bad = np.any(tail > np.maximum(self.TOL * scale, noise), axis=1) & (half > self.MIN_STEP)
        self._mid, self._half = mid, half
        self._coef = half[:, None, None] * np.einsum("kn,jnc->jkc", integ, coef)  # (J, n+1, 2)
        ends = self._coef.sum(axis=1)  # T_k(1) = 1
        self._start = np.concatenate([np.zeros((1, 2)), np.cumsum(ends[:-1], axis=0)])
        # Series for evaluation, without trailing coefficients summing to ≤ SERIES_TOL.
        keep = np.cumsum(np.abs(self._coef[:, ::-1]), axis=1)[:, ::-1] > self.SERIES_TOL
        n_keep = np.maximum(keep.sum(axis=1), 1)  # (J, 2); keep is monotone along k
        self._series = [
            [self._coef[j, : n_keep[j, c], c].tolist() for c in range(2)]
            for j in range(self._coef.shape[0])
        ]
        #: Collocation nodes (s) and latitude/longitude there (rad), shape (J·n,) and (J·n, 2).
        self.node_t = t.ravel()
        lon = self.lon0 + offsets(lon_rate)
        self.node_y = np.stack([lat.ravel(), lon.ravel()], axis=-1)
        return bad

    def rates(self, t: ArrayLike, lat: ArrayLike) -> tuple[Array, Array]:
        """``(φ', λ')`` (rad/s) at times ``t`` for latitudes ``lat`` (rad): the ODE's right side."""
        t = np.asarray(t, dtype=np.float64)
        vn, ve, h = self._velocity(t.ravel())
        v = np.stack([vn, ve, np.zeros_like(vn)], axis=-1)
        lat_dot, lon_dot, _ = geodetic_rates(np.asarray(lat).ravel(), h, v)
        return lat_dot.reshape(t.shape), lon_dot.reshape(t.shape)

    def offsets_sorted(self, ts: Array) -> Array:
        """Latitude and longitude minus their initial values (rad), (M, 2), for sorted ``ts``."""
        out = np.zeros((ts.size, 2))
        if not self._lo.size:
            return out
        b = _bounds(self._lo, ts)
        for j in np.flatnonzero(b[1:] > b[:-1]):
            sl = slice(b[j], b[j + 1])
            x = (ts[sl] - self._mid[j]) / self._half[j]
            for c in range(2):
                out[sl, c] = self._start[j, c] + _clenshaw(self._series[j][c], x)
        return out

    def derivative(self, t: ArrayLike) -> tuple[Array, Array]:
        """``(φ', λ')`` (rad/s) of the returned path at times ``t``: the rate interpolants.

        Equal to :meth:`rates` at the collocation nodes; elsewhere the difference is the
        interpolation error bounded in the class notes.
        """
        t = np.asarray(t, dtype=np.float64)
        out = np.zeros((t.size, 2))
        if self._lo.size:
            tr = t.ravel()
            j = np.clip(np.searchsorted(self._lo, tr, side="right") - 1, 0, self._lo.size - 1)
            d = cheb.chebder(self._coef, axis=1) / self._half[:, None, None]
            x = (tr - self._mid[j]) / self._half[j]
            for i in np.unique(j):
                sel = j == i
                for c in range(2):
                    out[sel, c] = _clenshaw(d[i, :, c].tolist(), x[sel])
        return out[:, 0].reshape(t.shape), out[:, 1].reshape(t.shape)

    def __call__(self, t: ArrayLike) -> tuple[Array, Array]:
        """Latitude and longitude (rad) at times ``t`` (s), arrays shaped like ``t``."""
        t = np.asarray(t, dtype=np.float64)
        shape = t.shape
        order, ts = _sort(t.ravel())
        off = self.offsets_sorted(ts)
        if order is not None:
            off[order] = off.copy()
        return (self.lat0 + off[:, 0]).reshape(shape), (self.lon0 + off[:, 1]).reshape(shape)


# ---------------------------------------------------------------------------------------------
# Segments.


@dataclass(frozen=True)
class Segment:
    """One maneuver segment in SI units (the config form is in :data:`SEGMENT_KEYS`).

    Attributes
    ----------
    duration : float
        Length (s), > 0.
    roll_rate, pitch_rate, heading_rate : float
        Constant Euler-angle rates of the segment (rad/s), FRD w.r.t. NED.
    accel : float or None
        Along-track acceleration (m/s²) of the horizontal ground speed; None = 0.
    climb_rate : float or None
        Target vertical speed up (m/s), reached at the end of the transition; None = hold.
    accel_ned : array (3,) or None
        Constant NED acceleration (m/s²) instead of ``accel``/``climb_rate``: the horizontal
        velocity then no longer follows the heading.
    transition : float or None
        Blend length (s) from the previous segment's rates/accelerations; None =
        ``min(1, duration/2)``; 0 = explicit step.
    """

    duration: float
    roll_rate: float = 0.0
    pitch_rate: float = 0.0
    heading_rate: float = 0.0
    accel: float | None = None
    climb_rate: float | None = None
    accel_ned: tuple[float, ...] | None = None
    transition: float | None = None

    @property
    def blend(self) -> float:
        """Effective transition length (s)."""
        if self.transition is None:
            return min(1.0, 0.5 * self.duration)
        return float(self.transition)


def read_number(value: Any, where: str) -> float:
    """A finite real number from a config value; ``ValueError`` naming ``where`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{where}: must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{where}: must be finite, got {value!r}")
    return x


def read_vector3(value: Any, where: str) -> Array:
    """A list of 3 finite numbers from a config value; ``ValueError`` naming ``where``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence | np.ndarray):
        raise ValueError(f"{where}: must be a list of 3 numbers, got {value!r}")
    if len(value) != 3:
        raise ValueError(f"{where}: must be a list of 3 numbers, got {len(value)} values")
    return np.array([read_number(v, f"{where}[{i}]") for i, v in enumerate(value)])


def parse_initial(
    initial: Mapping[str, Any],
) -> tuple[float, float, float, Array, Array]:
    """Read the scenario ``initial`` mapping (SPEC §5).

    Parameters
    ----------
    initial : mapping
        ``latitude_deg``, ``longitude_deg`` (required), ``altitude_m`` (m, default 0),
        ``velocity_ned_mps`` (3, m/s, default 0), ``attitude_rph_deg`` (roll, pitch, heading of
        FRD w.r.t. NED, deg, default 0).

    Returns
    -------
    lat, lon, alt, v_ned, rph
        rad, rad, m, array (3,) m/s, array (3,) rad.

    Raises
    ------
    ValueError
        Naming the key, for a missing, unknown, non-finite or out-of-range value.
    """
    if not isinstance(initial, Mapping):
        raise ValueError(f"initial: must be a mapping, got {type(initial).__name__}")
    for key in initial:
        if key not in INITIAL_KEYS:
            raise ValueError(
                f"initial.{key}: unknown key; expected one of {', '.join(INITIAL_KEYS)}"
            )
    for key in ("latitude_deg", "longitude_deg"):
        if key not in initial:
            raise ValueError(f"initial.{key}: is required")
    lat = read_number(initial["latitude_deg"], "initial.latitude_deg")
    if abs(lat) > math.degrees(LATITUDE_LIMIT):
        raise ValueError(f"initial.latitude_deg: must be within ±89.9°, got {lat}")
    lon = read_number(initial["longitude_deg"], "initial.longitude_deg")
    alt = read_number(initial.get("altitude_m", 0.0), "initial.altitude_m")
    if alt < ALTITUDE_MIN:
        raise ValueError(f"initial.altitude_m: must be ≥ {ALTITUDE_MIN} m, got {alt}")
    v = read_vector3(initial.get("velocity_ned_mps", [0.0, 0.0, 0.0]), "initial.velocity_ned_mps")
    rph = read_vector3(initial.get("attitude_rph_deg", [0.0, 0.0, 0.0]), "initial.attitude_rph_deg")
    if abs(rph[1]) > math.degrees(PITCH_LIMIT):
        raise ValueError(f"initial.attitude_rph_deg: pitch must be within ±89.9°, got {rph[1]}")
    return math.radians(lat), math.radians(lon), alt, v, np.radians(rph)


def _parse_segment(i: int, seg: Mapping[str, Any]) -> Segment:
    where = f"segments[{i}]"
    if not isinstance(seg, Mapping):
        raise ValueError(f"{where}: must be a mapping, got {type(seg).__name__}")
    for key in seg:
        if key not in SEGMENT_KEYS:
            raise ValueError(
                f"{where}.{key}: unknown key; expected one of {', '.join(SEGMENT_KEYS)}"
            )
    if "duration_s" not in seg:
        raise ValueError(f"{where}.duration_s: is required")
    duration = read_number(seg["duration_s"], f"{where}.duration_s")
    if duration <= 0.0:
        raise ValueError(f"{where}.duration_s: must be > 0, got {duration}")
    rates = {
        k: math.radians(read_number(seg.get(k, 0.0), f"{where}.{k}"))
        for k in ("roll_rate_dps", "pitch_rate_dps", "heading_rate_dps")
    }
    accel = read_number(seg["accel_mps2"], f"{where}.accel_mps2") if "accel_mps2" in seg else None
    climb = (
        read_number(seg["climb_rate_mps"], f"{where}.climb_rate_mps")
        if "climb_rate_mps" in seg
        else None
    )
    accel_ned = None
    if "accel_ned_mps2" in seg:
        for other in ("accel_mps2", "climb_rate_mps"):
            if other in seg:
                raise ValueError(
                    f"{where}.accel_ned_mps2: cannot be combined with {other} in one segment"
                )
        accel_ned = tuple(
            float(x) for x in read_vector3(seg["accel_ned_mps2"], f"{where}.accel_ned_mps2")
        )
    transition = None
    if "transition_s" in seg:
        transition = read_number(seg["transition_s"], f"{where}.transition_s")
        if not 0.0 <= transition <= duration:
            raise ValueError(
                f"{where}.transition_s: must be in [0, duration_s = {duration}], got {transition}"
            )
    return Segment(
        duration=duration,
        roll_rate=rates["roll_rate_dps"],
        pitch_rate=rates["pitch_rate_dps"],
        heading_rate=rates["heading_rate_dps"],
        accel=accel,
        climb_rate=climb,
        accel_ned=accel_ned,
        transition=transition,
    )


@dataclass
class _Piece:
    t0: float
    length: float
    mode: int
    coef: Array  # (_NCHAN, _NCOEF), ascending powers of x = (t - t0)/length
    segment: int


def _poly_extremes(c: Array) -> tuple[float, float]:
    """Min and max of polynomial ``c(x)`` on x ∈ [0, 1] (ends and interior stationary points)."""
    xs = [0.0, 1.0]
    d = np.trim_zeros(npoly.polyder(c), "b")
    if d.size > 1:
        r = npoly.polyroots(d)
        xs += [float(z.real) for z in r if abs(z.imag) < 1e-9 and 0.0 < z.real < 1.0]
    vals = npoly.polyval(np.array(xs), c)
    return float(vals.min()), float(vals.max())


class SegmentsTrajectory:
    """Piecewise maneuvers in navigation terms (the ``segments`` kind).

    Parameters
    ----------
    lat, lon : float
        Initial geodetic latitude and longitude (rad), |lat| ≤ 89.9°.
    alt : float
        Initial ellipsoidal altitude (m).
    v_ned : array (3,)
        Initial velocity relative to the Earth, NED (m/s).
    rph : array (3,)
        Initial roll, pitch, heading (rad) of FRD w.r.t. NED.
    segments : sequence of Segment
        The maneuvers, in order; the trajectory lasts their total duration.

    Notes
    -----
    Motion model (all derivatives are with respect to time, local level NED):

    * Euler angles: ``(φ, θ, ψ)' = r(t)``, the commanded rates blended as
      ``r = r_prev + (r_k - r_prev) w((t - t_k)/τ_k)`` over the transition ``τ_k``, then held;
      ``C_B^N = Rz(ψ) Ry(θ) Rx(φ)``.
    * Track segments (default): horizontal velocity ``s [cos χ, sin χ]``, ground speed
      ``s' = a(t)`` (``accel`` blended like the rates), course ``χ' = ψ'`` — the track follows
      the heading (no sideslip). The crab angle ``χ - ψ`` is the initial one (0 when the initial
      velocity is along the heading or zero) and may change only in the transition after an
      ``accel_ned`` segment, where ``χ'`` blends from the previous lateral acceleration ``a⊥/s``
      to ``ψ'`` so that the acceleration stays continuous. Vertical speed up ``c(t)``: quintic
      Hermite from the current value and vertical acceleration to ``climb_rate`` (zero
      acceleration and jerk at the end of the transition); without ``climb_rate`` the vertical
      acceleration ramps to zero and the vertical speed is then held.
    * NED segments: ``v' = a_prev + (a_k - a_prev) w``.
    * Position: ``h = h0 - ∫ v_D`` in closed form, latitude/longitude by :class:`LatLonPath`.

    Raises
    ------
    ValueError
        For an impossible trajectory, naming the segment and field: negative ground speed
        (``accel_mps2``), pitch beyond ±89.9° (``pitch_rate_dps``), altitude below -10 km
        (``climb_rate_mps``/``accel_ned_mps2``), latitude beyond ±89.9°, or a climb-rate change
        with ``transition_s = 0``.
    """

    def __init__(
        self,
        lat: float,
        lon: float,
        alt: float,
        v_ned: ArrayLike,
        rph: ArrayLike,
        segments: Sequence[Segment],
    ) -> None:
        if not segments:
            raise ValueError("segments: must be a non-empty list")
        self.segments = tuple(segments)
        v0 = np.asarray(v_ned, dtype=np.float64).reshape(3)
        rph0 = np.asarray(rph, dtype=np.float64).reshape(3)
        self._pieces = self._build(alt, v0, rph0)
        self._t0 = np.array([p.t0 for p in self._pieces])
        self._len = np.array([p.length for p in self._pieces])
        self._mode = np.array([p.mode for p in self._pieces])
        self._coef = np.stack([p.coef for p in self._pieces])  # (K, _NCHAN, _NCOEF)
        # Per piece and channel, the coefficients without the (exactly skippable) zero tail.
        self._horner = [
            [np.trim_zeros(c, "b").tolist() or [0.0] for c in p.coef] for p in self._pieces
        ]
        self._duration = float(sum(s.duration for s in self.segments))
        breaks = np.append(self._t0, self._duration)
        self._path = LatLonPath(breaks, lat, lon, self._vn_ve_h)
        bad = np.abs(self._path.node_y[:, 0]) > LATITUDE_LIMIT
        if np.any(bad):
            t_bad = float(self._path.node_t[np.argmax(bad)])
            k = int(np.clip(np.searchsorted(self._t0, t_bad, side="right") - 1, 0, None))
            raise ValueError(
                f"segments[{self._pieces[k].segment}]: latitude would exceed ±89.9° "
                f"at t = {t_bad:.3f} s"
            )

    # -- construction ------------------------------------------------------------------------

    def _build(self, alt0: float, v0: Array, rph0: Array) -> list[_Piece]:
        pieces: list[_Piece] = []
        # State at the current boundary.
        t = 0.0
        angles = rph0.copy()
        rates = np.zeros(3)
        mode = _TRACK
        vel = v0.copy()
        acc = np.zeros(3)  # NED acceleration at the boundary
        h = float(alt0)
        speed0 = float(np.hypot(v0[0], v0[1]))
        crab = math.atan2(v0[1], v0[0]) - rph0[2] if speed0 > 0.0 else 0.0
        course = rph0[2] + crab

        for k, seg in enumerate(self.segments):
            tau = seg.blend
            if (
                tau == 0.0
                and seg.accel_ned is None
                and seg.climb_rate is not None
                and abs(seg.climb_rate + vel[2]) > 1e-12 * max(1.0, abs(vel[2]))
            ):
                raise ValueError(
                    f"segments[{k}].climb_rate_mps: changing the vertical speed from "
                    f"{-vel[2]:.6g} to {seg.climb_rate:.6g} m/s needs transition_s > 0"
                )
            new_rates = np.array([seg.roll_rate, seg.pitch_rate, seg.heading_rate])
            parts = [(tau, True), (seg.duration - tau, False)]
            for length, blending in parts:
                if length <= 0.0:
                    continue
                coef = np.zeros((_NCHAN, _NCOEF))
                # Euler angles.
                for ch in (_ROLL, _PITCH, _HEAD):
                    r0, r1 = rates[ch], new_rates[ch]
                    rate = r0 * _ONE_MINUS_W + r1 * _W if blending else np.array([r1])
                    coef[ch] = _pad(_integral(rate, length, angles[ch]))
                heading_rate_poly = npoly.polyder(coef[_HEAD]) / length
                if seg.accel_ned is None:
                    piece_mode = _TRACK
                    speed = float(np.hypot(vel[0], vel[1]))
                    if mode == _NED:
                        if speed > 1e-9:
                            course = math.atan2(vel[1], vel[0])
                        elif np.hypot(acc[0], acc[1]) > 0.0:
                            course = math.atan2(acc[1], acc[0])
                        else:
                            course = angles[_HEAD]
                    u = np.array([math.cos(course), math.sin(course)])
                    u_perp = np.array([-u[1], u[0]])
                    a_along = float(acc[:2] @ u)
                    kappa0 = float(acc[:2] @ u_perp) / speed if speed > 1e-9 else rates[_HEAD]
                    a1 = 0.0 if seg.accel is None else seg.accel
                    accel_poly = a_along * _ONE_MINUS_W + a1 * _W if blending else np.array([a1])
                    coef[_P] = _pad(_integral(accel_poly, length, speed))
                    course_rate = npoly.polyadd(
                        heading_rate_poly,
                        (kappa0 - rates[_HEAD]) * _ONE_MINUS_W if blending else [0.0],
                    )
                    coef[_Q] = _pad(_integral(course_rate, length, course))
                    coef[_VD] = -self._vertical(k, seg, blending, length, -vel[2], -acc[2])
                else:
                    piece_mode = _NED
                    a1 = np.asarray(seg.accel_ned, dtype=np.float64)
                    for ch, i in ((_P, 0), (_Q, 1), (_VD, 2)):
                        a_poly = (
                            acc[i] * _ONE_MINUS_W + a1[i] * _W if blending else np.array([a1[i]])
                        )
                        coef[ch] = _pad(_integral(a_poly, length, vel[i]))
                coef[_ALT] = _pad(_integral(-coef[_VD], length, h))
                piece = _Piece(t0=t, length=length, mode=piece_mode, coef=coef, segment=k)
                self._check(piece)
                pieces.append(piece)
                # State at the end of the piece.
                vals = _horner(coef, 1.0)
                ders = _horner(np.stack([_pad(npoly.polyder(c)) for c in coef]), 1.0) / length
                angles = vals[[_ROLL, _PITCH, _HEAD]]
                rates = ders[[_ROLL, _PITCH, _HEAD]]
                h = float(vals[_ALT])
                if piece_mode == _TRACK:
                    s, chi = vals[_P], vals[_Q]
                    s_dot, chi_dot = ders[_P], ders[_Q]
                    cu, su = math.cos(chi), math.sin(chi)
                    vel = np.array([s * cu, s * su, vals[_VD]])
                    acc = np.array(
                        [
                            s_dot * cu - s * chi_dot * su,
                            s_dot * su + s * chi_dot * cu,
                            ders[_VD],
                        ]
                    )
                    course = float(chi)
                else:
                    vel = vals[[_P, _Q, _VD]]
                    acc = ders[[_P, _Q, _VD]]
                mode = piece_mode
                t += length
        return pieces

    @staticmethod
    def _vertical(
        k: int, seg: Segment, blending: bool, length: float, c0: float, a0: float
    ) -> Array:
        """Vertical speed up (m/s) over a track piece, ascending powers of x = u/length."""
        if not blending:
            return _pad([c0])  # the blending piece ended with zero vertical acceleration
        target = c0 + 0.5 * a0 * length if seg.climb_rate is None else seg.climb_rate
        slope = a0 * length
        d = target - c0 - slope
        # c(x) = c0 + slope x + c3 x³ + c4 x⁴ + c5 x⁵ with c(1) = target, c'(1) = c''(1) = 0.
        m = np.array([[1.0, 1.0, 1.0], [3.0, 4.0, 5.0], [6.0, 12.0, 20.0]])
        c3, c4, c5 = np.linalg.solve(m, np.array([d, -slope, 0.0]))
        return _pad([c0, slope, 0.0, c3, c4, c5])

    def _check(self, piece: _Piece) -> None:
        k = piece.segment
        seg = self.segments[k]
        lo, hi = _poly_extremes(piece.coef[_PITCH])
        if max(hi, -lo) > PITCH_LIMIT:
            bad = hi if hi > -lo else lo
            raise ValueError(
                f"segments[{k}].pitch_rate_dps: pitch would reach {math.degrees(bad):.3f}°, "
                "beyond ±89.9°"
            )
        if piece.mode == _TRACK:
            lo, _ = _poly_extremes(piece.coef[_P])
            if lo < -1e-9:
                raise ValueError(
                    f"segments[{k}].accel_mps2: the ground speed would become negative "
                    f"({lo:.6g} m/s); the segment decelerates past standstill"
                )
        lo, _ = _poly_extremes(piece.coef[_ALT])
        if lo < ALTITUDE_MIN:
            key = "accel_ned_mps2" if seg.accel_ned is not None else "climb_rate_mps"
            raise ValueError(
                f"segments[{k}].{key}: altitude would fall to {lo:.1f} m, below -10 km"
            )

    @classmethod
    def from_config(
        cls, initial: Mapping[str, Any], segments: Sequence[Mapping[str, Any]]
    ) -> SegmentsTrajectory:
        """Build from the scenario ``initial`` and ``trajectory.segments`` mappings.

        Parameters
        ----------
        initial : mapping
            SPEC §5 ``initial``: ``latitude_deg``, ``longitude_deg``, ``altitude_m``,
            ``velocity_ned_mps`` (NED, m/s), ``attitude_rph_deg`` (FRD w.r.t. NED, deg).
        segments : sequence of mappings
            Each with ``duration_s`` (s, > 0, required) and optionally ``roll_rate_dps``,
            ``pitch_rate_dps``, ``heading_rate_dps`` (deg/s, Euler-angle rates, default 0),
            ``accel_mps2`` (m/s², along-track, default 0), ``climb_rate_mps`` (m/s up, target
            reached at the end of the transition, default: hold), ``accel_ned_mps2``
            (3 values, m/s², excludes the two previous keys), ``transition_s`` (s, in
            [0, duration_s], default ``min(1, duration_s/2)``).

        Raises
        ------
        ValueError
            Naming the key (``segments[i].key`` / ``initial.key``) for bad values or an
            impossible trajectory.
        """
        lat, lon, alt, v, rph = parse_initial(initial)
        if isinstance(segments, (str, bytes, Mapping)) or not isinstance(segments, Sequence):
            raise ValueError("segments: must be a list of mappings")
        if len(segments) == 0:
            raise ValueError("segments: must be a non-empty list")
        parsed = [_parse_segment(i, s) for i, s in enumerate(segments)]
        return cls(lat, lon, alt, v, rph, parsed)

    # -- evaluation --------------------------------------------------------------------------

    @property
    def duration(self) -> float:
        """Total duration (s): the sum of the segment durations."""
        return self._duration

    def _locate(self, t: Array) -> tuple[Array, Array]:
        k = np.clip(np.searchsorted(self._t0, t, side="right") - 1, 0, self._t0.size - 1)
        x = (t - self._t0[k]) / self._len[k]
        return k, x

    def _channels_sorted(
        self, ts: Array, channels: Sequence[int] = range(_NCHAN)
    ) -> tuple[Array, Array]:
        """Piece index and ``channels`` (N, C) at non-decreasing times ``ts``, piece by piece.

        Same arithmetic per sample as :func:`_horner_gather` (leading zero coefficients
        skipped, which is exact), without the per-coefficient gathers.
        """
        b = _bounds(self._t0, ts)
        k = np.empty(ts.size, dtype=np.intp)
        vals = np.empty((ts.size, len(channels)))
        for i in np.flatnonzero(b[1:] > b[:-1]):
            sl = slice(b[i], b[i + 1])
            k[sl] = i
            x = (ts[sl] - self._t0[i]) / self._len[i]
            for col, c in enumerate(self._horner[i][ch] for ch in channels):
                acc = np.full(x.size, c[-1])
                for cj in c[-2::-1]:
                    acc *= x
                    acc += cj
                vals[sl, col] = acc
        return k, vals

    def _velocity_ned(self, k: Array, vals: Array) -> Array:
        track = self._mode[k] == _TRACK
        p, q = vals[:, _P], vals[:, _Q]
        vn = np.where(track, p * np.cos(q), p)
        ve = np.where(track, p * np.sin(q), q)
        return np.stack([vn, ve, vals[:, _VD]], axis=-1)

    def _vn_ve_h(self, t: Array) -> tuple[Array, Array, Array]:
        order, ts = _sort(np.asarray(t, dtype=np.float64).ravel())
        k, vals = self._channels_sorted(ts, (_P, _Q, _ALT))
        if order is not None:
            k[order], vals[order] = k.copy(), vals.copy()
        p, q, h = vals.T
        track = self._mode[k] == _TRACK
        vn = np.where(track, p * np.cos(q), p)
        ve = np.where(track, p * np.sin(q), q)
        return vn, ve, h

    def _check_times(self, t: Array) -> None:
        tol = 1e-9 * max(1.0, self._duration)
        if t.size and (t.min() < -tol or t.max() > self._duration + tol):
            raise ValueError(
                f"times must lie in [0, {self._duration}] s, got [{t.min()}, {t.max()}]"
            )

    def local_truth(self, t: ArrayLike) -> LocalTruth:
        """Truth at times ``t`` (s since t0, within ``[0, duration]``), vectorized.

        Returns
        -------
        LocalTruth
            Geodetic position (rad, rad, m), NED velocity relative to the Earth (m/s), and
            ``C_B^N`` (FRD to NED).
        """
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        self._check_times(t)
        order, ts = _sort(t)
        k, vals = self._channels_sorted(ts)
        v = self._velocity_ned(k, vals)
        off = self._path.offsets_sorted(ts)
        c_b_n = _dcm_rph(vals[:, _ROLL], vals[:, _PITCH], vals[:, _HEAD])
        alt = vals[:, _ALT]
        if order is not None:  # back to the caller's order
            for a in (off, alt, v, c_b_n):
                a[order] = a.copy()
        lat, lon = self._path.lat0 + off[:, 0], self._path.lon0 + off[:, 1]
        return LocalTruth(t=t, lat=lat, lon=lon, alt=alt, v_ned=v, c_b_n=c_b_n)

    def euler_rates(self, t: ArrayLike) -> Array:
        """Euler-angle rates ``(φ', θ', ψ')`` (rad/s) at times ``t``, shape (N, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        k, x = self._locate(t)
        d = np.apply_along_axis(lambda c: _pad(npoly.polyder(c)), -1, self._coef[:, :_P])
        return _horner_gather(d, k, x) / self._len[k][:, None]
