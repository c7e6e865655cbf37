"""Error measures of an estimate against truth: NED errors, along/cross-track, outage drift,
NEES and the time-offset fit. Numpy and scipy only; definitions: docs/score.md.

Errors (the navigator's, docs/interface.md §4, so that scoring its output gives back its
``/navigator/error/*``):

* position: ``C_E^N(true) (r_est − r_true)``, NED of the true position (m);
* velocity: ``v_est^N(est) − v_true^N(true)``, each ground velocity in its own NED frame (m/s);
* attitude: Young 1980 eq. (28) angles of ``C_B^N(est) C_B^N(true)ᵀ`` about (up, east, north)
  of the true local level (rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from strapdown_ros.core.array_types import F64, I64

__all__ = [
    "NeesSeries",
    "OutageDrift",
    "along_cross_track",
    "nees",
    "outage_drift",
    "stats",
    "time_offset_step",
]


#: Below this horizontal truth speed (m/s) along/cross-track are undefined (NaN).
MIN_TRACK_SPEED = 0.1


def along_cross_track(dr_ned: F64, v_true_ned: F64) -> tuple[F64, F64]:
    """Horizontal position error along the true horizontal velocity and across it (positive to
    the right of travel: ``u = (v_N, v_E)/|v_h|``, ``along = e·u``, ``cross = e·(−u_E, u_N)``);
    NaN where ``|v_h| <`` :data:`MIN_TRACK_SPEED`."""
    vh = v_true_ned[:, :2]
    speed = np.hypot(vh[:, 0], vh[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = vh / speed[:, None]
    u[speed < MIN_TRACK_SPEED] = np.nan
    e = dr_ned[:, :2]
    along = e[:, 0] * u[:, 0] + e[:, 1] * u[:, 1]
    cross = -e[:, 0] * u[:, 1] + e[:, 1] * u[:, 0]
    return along, cross


def stats(x: F64) -> dict[str, float | None]:
    """RMS, max |x|, mean and final value of a series (NaN ignored; None when empty)."""
    x = np.asarray(x, dtype=np.float64)
    ok = x[np.isfinite(x)]
    if not ok.size:
        return {"rms": None, "max_abs": None, "mean": None, "final": None}
    return {"rms": float(np.sqrt(np.mean(ok**2))), "max_abs": float(np.max(np.abs(ok))),
            "mean": float(np.mean(ok)), "final": float(ok[-1])}  # fmt: skip


@dataclass(frozen=True)
class OutageDrift:
    """Drift of the estimate over one GNSS outage ``[start, end)`` (stamps, ns).

    ``start_error``/``end_error``: horizontal NED error (m) at the last estimate at or before
    the start and the last one before the end; ``drift_m`` the norm of their difference,
    ``max_horizontal_m`` the largest horizontal error in the window, ``distance_m`` the true
    path length between the two estimates and ``drift_percent`` = 100 drift / distance.
    """

    start_ns: int
    end_ns: int
    first_stamp_ns: int | None
    last_stamp_ns: int | None
    start_error: tuple[float, float] | None
    end_error: tuple[float, float] | None
    drift_m: float | None
    max_horizontal_m: float | None
    distance_m: float | None
    drift_percent: float | None


def outage_drift(
    stamps_ns: I64, dr_ned: F64, r_true_e: F64, windows: list[tuple[int, int]]
) -> list[OutageDrift]:
    """:class:`OutageDrift` of each window (``[start, end)`` ns)."""
    out = []
    for a, b in windows:
        i0 = int(np.searchsorted(stamps_ns, a, side="right")) - 1
        i1 = int(np.searchsorted(stamps_ns, b, side="left")) - 1
        if i0 < 0 or i1 <= i0:
            out.append(OutageDrift(a, b, None, None, None, None, None, None, None, None))
            continue
        e0, e1 = dr_ned[i0, :2], dr_ned[i1, :2]
        drift = float(np.hypot(*(e1 - e0)))
        dist = float(np.sum(np.linalg.norm(np.diff(r_true_e[i0 : i1 + 1], axis=0), axis=1)))
        horiz = np.hypot(dr_ned[i0 : i1 + 1, 0], dr_ned[i0 : i1 + 1, 1])
        out.append(OutageDrift(
            a, b, int(stamps_ns[i0]), int(stamps_ns[i1]), (float(e0[0]), float(e0[1])),
            (float(e1[0]), float(e1[1])), drift, float(horiz.max()), dist,
            100.0 * drift / dist if dist > 0 else None,
        ))  # fmt: skip
    return out


@dataclass(frozen=True)
class NeesSeries:
    """Normalized estimation error squared ``εᵀ P⁻¹ ε`` per sample (NaN: no covariance).

    ``dof``: degrees of freedom; ``mean``: average over the samples with a covariance (a
    consistent filter gives ``dof``); ``inside_95``: fraction of samples inside the two-sided
    95 % χ² interval of ``dof``.
    """

    name: str
    dof: int
    values: F64
    count: int
    mean: float | None
    inside_95: float | None
    bounds_95: tuple[float, float]


def nees(name: str, err: F64, cov: F64) -> NeesSeries:
    """NEES of errors ``err`` (K, n) with covariances ``cov`` (K, n, n), both in the same axes;
    rows whose covariance is NaN or not positive definite get NaN."""
    k, n = err.shape
    values = np.full(k, np.nan)
    ok = np.isfinite(cov).all(axis=(1, 2)) & np.isfinite(err).all(axis=1)
    if np.any(ok):
        c = cov[ok]
        e = err[ok]
        try:
            chol = np.linalg.cholesky(c)
            y = np.linalg.solve(chol, e[..., None])[..., 0]
            values[np.flatnonzero(ok)] = np.sum(y**2, axis=1)
        except np.linalg.LinAlgError:  # some row not positive definite: one by one
            for i in np.flatnonzero(ok):
                try:
                    y = np.linalg.solve(np.linalg.cholesky(cov[i]), err[i])
                    values[i] = float(y @ y)
                except np.linalg.LinAlgError:
                    pass
    lo, hi = float(chi2.ppf(0.025, n)), float(chi2.ppf(0.975, n))
    good = values[np.isfinite(values)]
    return NeesSeries(
        name, n, values, int(good.size), float(good.mean()) if good.size else None,
        float(np.mean((good >= lo) & (good <= hi))) if good.size else None, (lo, hi),
    )  # fmt: skip


def time_offset_step(dr_ned: F64, v_true_ned: F64) -> tuple[float, float]:
    """One Gauss–Newton step of the constant time offset δt (s): the estimate stamped ``t``
    is the truth at ``t − δt``; with the truth taken at ``t − δt_k``, ``dr ≈ −v (δt − δt_k)``;
    returns ``(dδt, σ)`` with ``dδt = −Σ v·dr / Σ v·v`` and σ from the residual scatter."""
    vv = float(np.sum(v_true_ned**2))
    if vv <= 0.0:
        return 0.0, float("inf")
    d = -float(np.sum(v_true_ned * dr_ned)) / vv
    res = dr_ned + v_true_ned * d
    dof = max(dr_ned.size - 1, 1)
    sigma = float(np.sqrt(np.sum(res**2) / dof / vv))
    return d, sigma
