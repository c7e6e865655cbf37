"""Savage's constant-rate segments: the ``increments`` trajectory kind (exact by construction).

Savage 2020 Appendix A derives the exact update of eqs. (2)-(4) for a body whose angular rate
``ω_ib^B`` and specific force ``f^B`` are constant over a cycle (gravity linear in time). A
trajectory made of segments of constant ``ω`` and ``f`` therefore has the exact increments

    Δα_m = ω T,    Δv_m = f T        (body FRD axes, rad and m/s)

for every cycle inside a segment, and its truth is the recursion of eqs. (2)-(4) from the initial
state with gravity ``g_m = g(R_m)`` of the stream's model at the published positions
(:func:`strapdown_ros.core.exact_update.integrate`). Segment durations must be whole numbers of
cycles: a boundary inside a cycle would need the two constant-rate sub-cycles composed into one
increment pair, which this module deliberately does not do (it raises instead).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.exact_update import integrate
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.rotations import dcm_from_euler
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.trajectory.base import LocalTruth, TrajectoryError, local_to_e0

__all__ = ["IncrementSegment", "generate_increments_stream", "whole_cycles"]


@dataclass(frozen=True)
class IncrementSegment:
    """One constant-rate segment (Savage 2020 Appendix A), body FRD axes.

    Attributes
    ----------
    duration : float
        Length (s), > 0, a whole number of cycles.
    omega : tuple of 3 floats
        Inertial body angular rate ``ω_ib^B`` (rad/s).
    specific_force : tuple of 3 floats
        Specific force ``f^B`` (m/s²).
    """

    duration: float
    omega: tuple[float, float, float] = (0.0, 0.0, 0.0)
    specific_force: tuple[float, float, float] = (0.0, 0.0, 0.0)


def whole_cycles(duration: float, period_ns: int) -> int | None:
    """Cycles of ``period_ns`` in ``duration`` (s), None unless a whole number (to 1e-9 rel.)."""
    n = round(duration * 1e9 / period_ns)
    if n < 1 or abs(n * (period_ns * 1e-9) - duration) > 1e-9 * max(1.0, duration):
        return None
    return int(n)


def generate_increments_stream(
    lat: float,
    lon: float,
    alt: float,
    v_ned: ArrayLike,
    rph: ArrayLike,
    segments: Sequence[IncrementSegment],
    period_ns: int,
    t0_ns: int,
    gravity_model: str = "j2",
) -> Stream:
    """Stream of a sequence of constant angular-rate / specific-force segments (Savage 2020).

    Parameters
    ----------
    lat, lon, alt : float
        Initial geodetic latitude, longitude (rad) and ellipsoidal altitude (m), WGS-84.
    v_ned : array (3,)
        Initial velocity relative to the Earth, NED (m/s).
    rph : array (3,)
        Initial roll, pitch, heading of FRD w.r.t. NED (rad). The initial state is converted to
        the E0 state ``C_B^E0, V^E0, R^E0`` at t0 by
        :func:`~strapdown_ros.core.trajectory.base.local_to_e0` (so ``V^E0`` includes
        ``ω_ie × R``).
    segments : sequence of IncrementSegment
        The segments in order; each a whole number of cycles.
    period_ns : int
        Cycle period T (ns).
    t0_ns : int
        Stamp of cycle 0 (ns since the Unix epoch).
    gravity_model : str
        Gravitation model of the stream (docs/interface.md §1), passed to
        :func:`~strapdown_ros.core.gravity.gravitation`.

    Returns
    -------
    Stream
        ``Δα_m = ω T``, ``Δv_m = f T`` for m = 1..M and the E0 truth from eqs. (2)-(4), which
        therefore meets the docs/interface.md §3 exactness rule to float64 rounding.

    Raises
    ------
    TrajectoryError
        ``("segments",)`` when there is none, ``("segments", i, "duration")`` for a segment that
        is not a whole number of cycles.
    """
    period_ns = int(period_ns)
    if period_ns < 1:
        raise ValueError(f"period_ns: must be >= 1, got {period_ns}")
    period = period_ns * 1e-9
    if len(segments) == 0:
        raise TrajectoryError(("segments",), "must be a non-empty list")
    omegas, forces, counts = [], [], []
    for i, seg in enumerate(segments):
        n = whole_cycles(seg.duration, period_ns)
        if n is None:
            raise TrajectoryError(
                ("segments", i, "duration"),
                f"{seg.duration} s is not a whole number of cycles of {period} s (segment "
                "boundaries must fall on cycle boundaries)",
            )
        omegas.append(np.asarray(seg.omega, dtype=np.float64).reshape(3))
        forces.append(np.asarray(seg.specific_force, dtype=np.float64).reshape(3))
        counts.append(n)
    v_ned = np.asarray(v_ned, dtype=np.float64).reshape(3)
    rph = np.asarray(rph, dtype=np.float64).reshape(3)
    counts_arr = np.asarray(counts)
    dalpha = np.repeat(np.asarray(omegas), counts_arr, axis=0) * period
    dv = np.repeat(np.asarray(forces), counts_arr, axis=0) * period

    zero = np.zeros(1)
    truth0 = local_to_e0(
        LocalTruth(
            t=zero,
            lat=np.full(1, lat),
            lon=np.full(1, lon),
            alt=np.full(1, alt),
            v_ned=v_ned[None, :],
            c_b_n=dcm_from_euler(*rph)[None, :, :],
        )
    )
    gravitation(truth0.r_e0, gravity_model)  # an unknown model fails here, before the loop
    c, v, r = integrate(
        truth0.c_b_e0[0],
        truth0.v_e0[0],
        truth0.r_e0[0],
        dalpha,
        dv,
        period,
        lambda x: gravitation(x, gravity_model),
    )
    if not math.isfinite(float(np.abs(r).max())):  # pragma: no cover - defensive
        raise ValueError("segments: the integrated trajectory is not finite")
    return Stream(
        t0_ns=int(t0_ns),
        period_ns=period_ns,
        dalpha=dalpha,
        dv=dv,
        c_b_e0=c,
        v_e0=v,
        r_e0=r,
        gravity_model=gravity_model,
    )
