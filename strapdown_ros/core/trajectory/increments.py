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
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from strapdown_ros.core.exact_update import integrate
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.rotations import dcm_from_euler
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.trajectory.base import LocalTruth, local_to_e0
from strapdown_ros.core.trajectory.segments import parse_initial, read_number, read_vector3

__all__ = ["INCREMENT_SEGMENT_KEYS", "generate_increments_stream"]

INCREMENT_SEGMENT_KEYS = ("duration_s", "omega_dps", "specific_force_mps2")


def _period_ns(rate_hz: float) -> int:
    rate = read_number(rate_hz, "rate_hz")
    if rate <= 0.0:
        raise ValueError(f"rate_hz: must be > 0, got {rate}")
    period = 1e9 / rate
    period_ns = round(period)
    if period_ns < 1 or abs(period - period_ns) > 1e-9 * max(1.0, period):
        raise ValueError(
            f"rate_hz: the period 1e9/rate_hz = {period!r} ns is not an integer number of ns"
        )
    return int(period_ns)


def generate_increments_stream(
    initial: Mapping[str, Any],
    segments: Sequence[Mapping[str, Any]],
    rate_hz: float,
    t0_ns: int,
    gravity_model: str = "j2",
) -> Stream:
    """Stream of a sequence of constant angular-rate / specific-force segments (Savage 2020).

    Parameters
    ----------
    initial : mapping
        SPEC §5 ``initial``: ``latitude_deg``, ``longitude_deg``, ``altitude_m``,
        ``velocity_ned_mps`` (relative to the Earth, NED, m/s), ``attitude_rph_deg`` (FRD w.r.t.
        NED, deg). Converted to the E0 state ``C_B^E0, V^E0, R^E0`` at t0 by
        :func:`~strapdown_ros.core.trajectory.base.local_to_e0` (so ``V^E0`` includes
        ``ω_ie × R``).
    segments : sequence of mappings
        Each with ``duration_s`` (s, > 0, a whole number of cycles 1/rate_hz),
        ``omega_dps`` (3 values: inertial body angular rate ``ω_ib^B``, FRD, deg/s, default 0)
        and ``specific_force_mps2`` (3 values: specific force ``f^B``, FRD, m/s², default 0).
    rate_hz : float
        Cycle rate 1/T (Hz); 1e9/rate_hz must be an integer number of ns (SPEC §2).
    t0_ns : int
        Stamp of cycle 0 (ns since the Unix epoch).
    gravity_model : str
        Gravitation model of the stream (SPEC §1), passed to
        :func:`~strapdown_ros.core.gravity.gravitation`.

    Returns
    -------
    Stream
        ``Δα_m = ω T``, ``Δv_m = f T`` for m = 1..M and the E0 truth from eqs. (2)-(4), which
        therefore meets the SPEC §3 exactness rule to float64 rounding.

    Raises
    ------
    ValueError
        Naming the key (``segments[i].key``, ``rate_hz``, ``initial.key``) for a bad value, an
        unknown key, or a segment that is not a whole number of cycles.
    """
    period_ns = _period_ns(rate_hz)
    period = period_ns * 1e-9
    lat, lon, alt, v_ned, rph = parse_initial(initial)
    if isinstance(segments, (str, bytes, Mapping)) or not isinstance(segments, Sequence):
        raise ValueError("segments: must be a list of mappings")
    if len(segments) == 0:
        raise ValueError("segments: must be a non-empty list")
    omegas, forces, counts = [], [], []
    for i, seg in enumerate(segments):
        where = f"segments[{i}]"
        if not isinstance(seg, Mapping):
            raise ValueError(f"{where}: must be a mapping, got {type(seg).__name__}")
        for key in seg:
            if key not in INCREMENT_SEGMENT_KEYS:
                raise ValueError(
                    f"{where}.{key}: unknown key; expected one of "
                    f"{', '.join(INCREMENT_SEGMENT_KEYS)}"
                )
        if "duration_s" not in seg:
            raise ValueError(f"{where}.duration_s: is required")
        duration = read_number(seg["duration_s"], f"{where}.duration_s")
        if duration <= 0.0:
            raise ValueError(f"{where}.duration_s: must be > 0, got {duration}")
        n = round(duration * 1e9 / period_ns)
        if n < 1 or abs(n * period - duration) > 1e-9 * max(1.0, duration):
            raise ValueError(
                f"{where}.duration_s: {duration} s is not a whole number of cycles of "
                f"{period} s (segment boundaries must fall on cycle boundaries)"
            )
        omegas.append(
            np.radians(read_vector3(seg.get("omega_dps", [0.0, 0.0, 0.0]), f"{where}.omega_dps"))
        )
        forces.append(
            read_vector3(
                seg.get("specific_force_mps2", [0.0, 0.0, 0.0]), f"{where}.specific_force_mps2"
            )
        )
        counts.append(n)
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
