"""Maneuver segments in navigation terms: the ``segments`` trajectory kind.

An initial state (geodetic position, NED velocity, roll/pitch/heading of the body FRD frame
w.r.t. NED) followed by segments of constant Euler-angle rates with an along-track acceleration,
a target climb rate or a constant NED acceleration, blended over ``transition`` with a C²
quintic smoothstep. Everything but latitude and longitude is a closed-form polynomial per
piece; latitude and longitude come from :class:`~.latlon_path.LatLonPath`. Frames and units:
NED, FRD, rad, m, s (docs/interface.md §1). Theory and accuracy: docs/theory/trajectories.md
("segments").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import meridian_radius
from strapdown_ros.core.trajectory.base import LocalTruth, TrajectoryError
from strapdown_ros.core.trajectory.latlon_path import LatLonPath, bounds, sort_times

__all__ = [
    "ALTITUDE_MIN",
    "LATITUDE_LIMIT",
    "PITCH_LIMIT",
    "Segment",
    "SegmentsTrajectory",
    "smoothstep5",
]


#: Number of polynomial coefficients stored per channel (degree ≤ 7).
_NCOEF = 8
#: Channels of a piece: Euler angles, horizontal pair, down velocity, altitude.
_ROLL, _PITCH, _HEAD, _P, _Q, _VD, _ALT = range(7)
_NCHAN = 7
#: Horizontal parametrisation of a piece: (P, Q) = (speed, course) or (v_N, v_E).
_TRACK, _NED = 0, 1

#: Limits of a physically meaningful trajectory (docs/interface.md §5: impossible trajectories are
#rejected).
PITCH_LIMIT = math.radians(89.9)
ALTITUDE_MIN = -10_000.0
LATITUDE_LIMIT = math.radians(89.9)

# Latitude reach (SegmentsTrajectory._check_latitude_reach): meridian radius at the equator and
# the pole, the bound c of |1/(R_N + h) - 1/(R_m + h)| (R_m their mean, h >= ALTITUDE_MIN), the
# largest 1/(R_N + h), and the Gauss-Legendre rules (16 points, 8 for the error estimate).
_R_EQUATOR = float(meridian_radius(0.0))
_R_POLE = float(meridian_radius(math.pi / 2))
_R_MEAN = 0.5 * (_R_EQUATOR + _R_POLE)
_W_BAND = 0.5 * (_R_POLE - _R_EQUATOR) / (_R_EQUATOR + ALTITUDE_MIN) ** 2
_W_MAX = 1.0 / (_R_EQUATOR + ALTITUDE_MIN)
_GL16 = np.polynomial.legendre.leggauss(16)
_GL8 = np.polynomial.legendre.leggauss(8)

# Quintic smoothstep and its integral, ascending powers of x in [0, 1].
_W = np.array([0.0, 0.0, 0.0, 10.0, -15.0, 6.0])
_ONE_MINUS_W = np.array([1.0, 0.0, 0.0, -10.0, 15.0, -6.0])


def smoothstep5(x: ArrayLike) -> F64:
    """C² blending weight ``w(x) = 10x³ - 15x⁴ + 6x⁵`` on [0, 1] (clipped outside).

    ``w(0) = 0``, ``w(1) = 1``, ``w' = w'' = 0`` at both ends, ``∫₀¹ w = 1/2``.
    """
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return x**3 * (10.0 + x * (-15.0 + 6.0 * x))


def _pad(c: ArrayLike) -> F64:
    c = np.trim_zeros(np.atleast_1d(np.asarray(c, dtype=np.float64)), "b")
    if c.size > _NCOEF:
        raise AssertionError("polynomial degree exceeds storage")
    out = np.zeros(_NCOEF)
    out[: c.size] = c
    return out


def _integral(c: F64, length: float, start: float) -> F64:
    """``start + L ∫₀^x c(ξ) dξ`` for a rate polynomial ``c`` in normalised time x = u/L."""
    out = npoly.polyint(c) * length
    out[0] = start
    return out


def _horner(coef: F64, x: F64 | float) -> F64:
    """Evaluate polynomials ``coef[..., k]`` (ascending) at ``x`` (broadcast over ``...``)."""
    out = coef[..., -1].copy()
    for k in range(coef.shape[-1] - 2, -1, -1):
        out = out * x + coef[..., k]
    return out


def _dcm_rph(roll: F64, pitch: F64, heading: F64) -> F64:
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


def _horner_gather(coef: F64, k: F64, x: F64, channels: Sequence[int] | None = None) -> F64:
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
# Segments.


@dataclass(frozen=True)
class Segment:
    """One maneuver segment in SI units (the scenario form: ``config.trajectory.SegmentSpec``).

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


@dataclass
class _Piece:
    t0: float
    length: float
    mode: int
    coef: F64  # (_NCHAN, _NCOEF), ascending powers of x = (t - t0)/length
    segment: int


def _poly_extremes(c: F64) -> tuple[float, float]:
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
    TrajectoryError
        For an impossible trajectory, ``where = ("segments", i, attribute)`` naming the
        :class:`Segment` and its attribute: negative ground speed (``accel``), pitch beyond
        ±89.9° (``pitch_rate``), altitude below -10 km (``climb_rate``/``accel_ned``), a
        climb-rate change with ``transition = 0`` (``climb_rate``), or latitude beyond ±89.9°
        (``("segments", i)``).
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
            raise TrajectoryError(("segments",), "must be a non-empty list")
        if not abs(lat) <= LATITUDE_LIMIT:
            raise TrajectoryError(("lat",), f"must be within ±89.9°, got {math.degrees(lat)}°")
        self.segments = tuple(segments)
        v0 = np.asarray(v_ned, dtype=np.float64).reshape(3)
        rph0 = np.asarray(rph, dtype=np.float64).reshape(3)
        if not abs(rph0[1]) <= PITCH_LIMIT:
            raise TrajectoryError(
                ("rph", 1), f"pitch must be within ±89.9°, got {math.degrees(rph0[1])}°"
            )
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
        self._check_latitude_reach(lat)
        breaks = np.append(self._t0, self._duration)
        self._path = LatLonPath(breaks, lat, lon, self._vn_ve_h)
        bad = np.abs(self._path.node_y[:, 0]) > LATITUDE_LIMIT
        if np.any(bad):
            t_bad = float(self._path.node_t[np.argmax(bad)])
            k = int(np.clip(np.searchsorted(self._t0, t_bad, side="right") - 1, 0, None))
            raise TrajectoryError(
                ("segments", self._pieces[k].segment),
                f"latitude would exceed ±89.9° at t = {t_bad:.3f} s",
            )

    # -- construction ------------------------------------------------------------------------

    def _build(self, alt0: float, v0: F64, rph0: F64) -> list[_Piece]:
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
                raise TrajectoryError(
                    ("segments", k, "climb_rate"),
                    f"changing the vertical speed from {-vel[2]:.6g} to {seg.climb_rate:.6g} "
                    "m/s needs transition_s > 0",
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
    ) -> F64:
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
            raise TrajectoryError(
                ("segments", k, "pitch_rate"),
                f"pitch would reach {math.degrees(bad):.3f}°, beyond ±89.9°",
            )
        if piece.mode == _TRACK:
            lo, _ = _poly_extremes(piece.coef[_P])
            if lo < -1e-9:
                raise TrajectoryError(
                    ("segments", k, "accel"),
                    f"the ground speed would become negative ({lo:.6g} m/s); the segment "
                    "decelerates past standstill",
                )
        lo, _ = _poly_extremes(piece.coef[_ALT])
        if lo < ALTITUDE_MIN:
            key = "accel_ned" if seg.accel_ned is not None else "climb_rate"
            raise TrajectoryError(
                ("segments", k, key), f"altitude would fall to {lo:.1f} m, below -10 km"
            )

    #: Latitude-reach quadrature: longest interval (s), largest course change per interval
    #: (rad), intervals per vectorized chunk.
    REACH_STEP = 20.0
    REACH_TURN = 1.0
    REACH_CHUNK = 4096

    def _check_latitude_reach(self, lat0: float) -> None:
        """Reject a path whose latitude certainly leaves ±89.9°, before it is integrated.

        ``φ(t) - φ0 = ∫ v_N w dt`` with ``w = 1/(R_N(φ) + h)`` (Groves 2013 eq. (2.111)).
        ``R_N`` lies between its equator and pole values and ``h >= -10 km``, so ``|w - 1/(R_m +
        h)| <= c`` (``R_m`` their mean, ``c`` = :data:`_W_BAND`, 0.5 % of ``w``) and ``φ(t) - φ0``
        lies within ``∫ v_N/(R_m + h) dt ± c ∫ |v_H| dt`` (``v_H`` the horizontal speed, ``>=
        |v_N|``). Both integrals are summed piece by piece in time order (Gauss-Legendre, 16
        points on intervals of at most :attr:`REACH_STEP` and :attr:`REACH_TURN` of course
        change, the difference to the 8-point rule added to the band), and the first interval
        end where the whole band lies beyond ±89.9° raises: such a path would otherwise be
        solved over its whole length first (:class:`LatLonPath`, whose cost grows with the
        length and without bound once the latitude passes the pole). Skipped when the largest
        speed of each piece times its length cannot carry the latitude to the limit.

        Raises
        ------
        TrajectoryError
            ``("segments", i)``: latitude would exceed ±89.9° by t = ... s.
        """
        vmax, turn = [], []
        for p in self._pieces:
            lo_p, hi_p = _poly_extremes(p.coef[_P])
            if p.mode == _TRACK:
                vmax.append(max(-lo_p, hi_p))
                lo_r, hi_r = _poly_extremes(npoly.polyder(p.coef[_Q]))
                turn.append(max(-lo_r, hi_r) / p.length)
            else:
                lo_q, hi_q = _poly_extremes(p.coef[_Q])
                vmax.append(math.hypot(max(-lo_p, hi_p), max(-lo_q, hi_q)))
                turn.append(0.0)
        reach = sum(v * p.length for v, p in zip(vmax, self._pieces, strict=True)) * _W_MAX
        if abs(lat0) + reach <= LATITUDE_LIMIT:
            return
        a_sum = b_sum = q_sum = 0.0
        for p, rate in zip(self._pieces, turn, strict=True):
            n = max(
                1,
                math.ceil(p.length / self.REACH_STEP),
                math.ceil(p.length * rate / self.REACH_TURN),
            )
            for j0 in range(0, n, self.REACH_CHUNK):
                j = np.arange(j0, min(n, j0 + self.REACH_CHUNK) + 1, dtype=np.float64)
                edges = p.t0 + p.length * j / n
                lo, hi = edges[:-1], edges[1:]
                mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
                a, b = [], []
                for x, w in (_GL16, _GL8):
                    vn, ve, h = self._vn_ve_h(mid[:, None] + half[:, None] * x)
                    shape = (lo.size, x.size)
                    vn, ve, h = vn.reshape(shape), ve.reshape(shape), h.reshape(shape)
                    a.append(half * ((vn / (_R_MEAN + h)) @ w))
                    b.append(half * (np.hypot(vn, ve) @ w))
                a_cum = a_sum + np.cumsum(a[0])
                b_cum = b_sum + np.cumsum(b[0])
                q_cum = q_sum + np.cumsum(np.abs(a[0] - a[1]) + _W_BAND * np.abs(b[0] - b[1]))
                band = _W_BAND * b_cum + q_cum
                beyond = (lat0 + a_cum - band > LATITUDE_LIMIT) | (
                    lat0 + a_cum + band < -LATITUDE_LIMIT
                )
                if np.any(beyond):
                    t_bad = float(hi[np.argmax(beyond)])
                    raise TrajectoryError(
                        ("segments", p.segment),
                        f"latitude would exceed ±89.9° by t = {t_bad:.3f} s",
                    )
                a_sum, b_sum, q_sum = float(a_cum[-1]), float(b_cum[-1]), float(q_cum[-1])

    # -- evaluation --------------------------------------------------------------------------

    @property
    def duration(self) -> float:
        """Total duration (s): the sum of the segment durations."""
        return self._duration

    def _locate(self, t: F64) -> tuple[F64, F64]:
        k = np.clip(np.searchsorted(self._t0, t, side="right") - 1, 0, self._t0.size - 1)
        x = (t - self._t0[k]) / self._len[k]
        return k, x

    def _channels_sorted(
        self, ts: F64, channels: Sequence[int] = range(_NCHAN)
    ) -> tuple[F64, F64]:
        """Piece index and ``channels`` (N, C) at non-decreasing times ``ts``, piece by piece.

        Same arithmetic per sample as :func:`_horner_gather` (leading zero coefficients
        skipped, which is exact), without the per-coefficient gathers.
        """
        b = bounds(self._t0, ts)
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

    def _velocity_ned(self, k: F64, vals: F64) -> F64:
        track = self._mode[k] == _TRACK
        p, q = vals[:, _P], vals[:, _Q]
        vn = np.where(track, p * np.cos(q), p)
        ve = np.where(track, p * np.sin(q), q)
        return np.stack([vn, ve, vals[:, _VD]], axis=-1)

    def _vn_ve_h(self, t: F64) -> tuple[F64, F64, F64]:
        order, ts = sort_times(np.asarray(t, dtype=np.float64).ravel())
        k, vals = self._channels_sorted(ts, (_P, _Q, _ALT))
        if order is not None:
            k[order], vals[order] = k.copy(), vals.copy()
        p, q, h = vals.T
        track = self._mode[k] == _TRACK
        vn = np.where(track, p * np.cos(q), p)
        ve = np.where(track, p * np.sin(q), q)
        return vn, ve, h

    def _check_times(self, t: F64) -> None:
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
        order, ts = sort_times(t)
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

    def euler_rates(self, t: ArrayLike) -> F64:
        """Euler-angle rates ``(φ', θ', ψ')`` (rad/s) at times ``t``, shape (N, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel()
        k, x = self._locate(t)
        d = np.apply_along_axis(lambda c: _pad(npoly.polyder(c)), -1, self._coef[:, :_P])
        return _horner_gather(d, k, x) / self._len[k][:, None]
