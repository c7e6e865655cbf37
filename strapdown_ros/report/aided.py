"""The report's aided-filter part: errors against truth with ±3σ, NEES and NIS with χ² bounds.

An aided filter's outputs are found by their names below a prefix ``P`` (default ``/aided``,
:data:`strapdown_ros.config.aided.BASE_OUTPUTS`): ``P/odom`` and ``P/nees``. Everything is
recomputed from the bag's messages, not read from the filter's error topics:

* errors (docs/interface.md §4): ``P/odom`` minus the truth (``/reference/odom``, the only
  truth the filter accepts) at common stamps, position NED of the true position, velocity NED,
  Young 1980 eq. (28) angles (up, east, north);
* covariances of those errors (docs/theory/aided_ins.md §8): position ``C_E^N P_rr C_N^E``
  from the pose covariance of ``P/odom`` (position and rotation about the ECEF axes), velocity
  from ``P/vel`` (NED velocity as ENU), attitude ``J P_pose Jᵀ`` with
  ``J = [C_UEN D C_E^N, −C_UEN C_E^N]`` (``D``: the local level's turn by a position error),
  all at the filter's own position;
* NEES ``eᵀ S⁻¹ e`` per quantity (3 degrees of freedom each), NIS as published per measurement
  (``P/nis/<sensor>``: value, degrees of freedom, accepted).

Bounds: the two-sided 95 % interval of χ² with the degrees of freedom (one run: a consistent
filter has ~95 % of its values inside; NEES samples are correlated in time, so the fraction
is a rough check, not a test).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.config.aided import AIDED_SENSORS, BASE_OUTPUTS
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import A_WGS84, E2_WGS84, dcm_ecef_to_ned, ecef_to_geodetic
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.young import C_NED_TO_UEN
from strapdown_ros.messages import odometry_state

__all__ = [
    "AidedResult",
    "aided_data",
    "aided_prefixes",
    "aided_table",
    "chi2_bounds",
    "plot_aided_consistency",
    "plot_aided_errors",
]

ODOMETRY = "nav_msgs/msg/Odometry"
VECTOR3 = "geometry_msgs/msg/Vector3Stamped"
TWIST = "geometry_msgs/msg/TwistWithCovarianceStamped"
#: The truth the filter is compared with (``aided.truth_topic`` must be the reference Odometry).
TRUTH_TOPIC = "/reference/odom"
_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # NED <-> ENU
QUANTITIES = ("position", "velocity", "attitude")


def chi2_bounds(dof: NDArray[np.float64] | float, level: float = 0.95) -> tuple[F64, F64]:
    """Two-sided ``level`` interval of χ² with ``dof`` degrees of freedom."""
    from scipy.stats import chi2

    a = (1.0 - level) / 2.0
    d = np.asarray(dof, dtype=np.float64)
    return chi2.ppf(a, d), chi2.ppf(1.0 - a, d)


@dataclass
class Nis:
    """One measurement's NIS messages (``P/nis/<sensor>``)."""

    sensor: str
    topic: str
    t: F64
    nis: F64
    dof: F64
    accepted: NDArray[np.bool_]

    def inside(self) -> NDArray[np.bool_]:
        lo, hi = chi2_bounds(np.maximum(self.dof, 1.0))
        return (self.nis >= lo) & (self.nis <= hi)


@dataclass
class AidedResult:
    """The filter under ``prefix`` against truth, at the stamps both have."""

    prefix: str
    truth_topic: str
    stamps_ns: NDArray[np.int64]
    t: F64  #: (K,) s since the bag start
    errors: dict[str, F64]  #: quantity -> (K, 3): NED m, NED m/s, Young (up, east, north) rad
    sigma: dict[str, F64]  #: quantity -> (K, 3) σ of the same components
    nees: F64  #: (K, 3) recomputed NEES of position, velocity, attitude
    #: The filter's own error and NEES topics at the same stamps (None when absent).
    published_errors: dict[str, F64 | None] = field(default_factory=dict)
    published_nees: F64 | None = None
    nis: list[Nis] = field(default_factory=list)

    def inside_3sigma(self, quantity: str) -> F64:
        """(3,) fraction of samples with |error| ≤ 3σ per component."""
        e, s = self.errors[quantity], self.sigma[quantity]
        return np.mean(np.abs(e) <= 3.0 * s, axis=0) if e.size else np.full(3, np.nan)

    def nees_inside(self) -> F64:
        """(3,) fraction of NEES values inside the 95 % χ²(3) interval."""
        lo, hi = chi2_bounds(3.0)
        return np.mean((self.nees >= lo) & (self.nees <= hi), axis=0)


def aided_prefixes(contents: BagContents) -> list[str]:
    """Prefixes with an aided filter's ``odom`` (Odometry) and ``nees`` (Vector3Stamped)."""
    types = {t: d.msgtype for t, d in contents.topics.items() if len(d)}
    out = []
    for topic, ty in types.items():
        if ty != VECTOR3 or not topic.endswith("/" + BASE_OUTPUTS["nees"]):
            continue
        prefix = topic[: -len(BASE_OUTPUTS["nees"]) - 1]
        if types.get(f"{prefix}/{BASE_OUTPUTS['odom']}") == ODOMETRY:
            out.append(prefix)
    return out


def frame_turn(lat: F64, alt: F64) -> F64:
    """``D`` (K, 3, 3), ``δθ^N = D δr^N``: the turn of the local level (NED) by a position
    error, from the meridian and prime-vertical radii (WGS 84)."""
    s = np.sin(lat)
    w = 1.0 - E2_WGS84 * s * s
    r_e = A_WGS84 / np.sqrt(w)  # prime vertical
    r_n = A_WGS84 * (1.0 - E2_WGS84) / w**1.5  # meridian
    d = np.zeros(np.shape(lat) + (3, 3))
    d[:, 0, 1] = 1.0 / (r_e + alt)  # rotation about north by an east displacement
    d[:, 1, 0] = -1.0 / (r_n + alt)  # about east by a north displacement
    d[:, 2, 1] = -np.tan(lat) / (r_e + alt)
    return d


def _sym_sigma(cov: F64) -> F64:
    return np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))


def _nees(e: F64, cov: F64) -> F64:
    return np.einsum("ki,ki->k", e, np.linalg.solve(cov, e[..., None])[..., 0])


def aided_data(contents: BagContents, prefix: str, start_ns: int,
               truth_topic: str = TRUTH_TOPIC) -> AidedResult | str:  # fmt: skip
    """Errors, σ, NEES and NIS of the filter under ``prefix`` (a string says why not)."""
    odom_t, vel_t = f"{prefix}/{BASE_OUTPUTS['odom']}", f"{prefix}/{BASE_OUTPUTS['vel']}"
    if contents.topics.get(truth_topic) is None or not len(contents.topics[truth_topic]):
        return f"no truth `{truth_topic}` for the filter `{prefix}`"
    if contents.topics.get(vel_t) is None or contents.topics[vel_t].msgtype != TWIST:
        return f"no `{vel_t}` (the filter's velocity covariance)"
    nav_f, truth_f, vel_f = contents[odom_t], contents[truth_topic], contents[vel_t]
    nav, truth = odometry_state(nav_f), odometry_state(truth_f)  # type: ignore[arg-type]
    stamps, i, j = np.intersect1d(nav.stamps_ns, truth.stamps_ns, return_indices=True)
    vel_stamps = np.asarray(vel_f.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
    stamps, ii, kv = np.intersect1d(stamps, vel_stamps, return_indices=True)
    i, j = i[ii], j[ii]
    # truth
    r_t = truth.r_e[j]
    lat_t, lon_t, _ = ecef_to_geodetic(r_t)
    c_t = dcm_ecef_to_ned(lat_t, lon_t).reshape(-1, 3, 3)
    # the filter's solution, at its own position
    r_f = nav.r_e[i]
    lat, lon, alt = ecef_to_geodetic(r_f)
    c_f = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
    errors = {
        "position": position_error_ned(r_f, r_t, lat_t, lon_t),
        "velocity": velocity_error_ned(np.einsum("kij,kj->ki", c_f, nav.v_e[i]),
                                       np.einsum("kij,kj->ki", c_t, truth.v_e[j])),
        "attitude": attitude_error_young(c_f @ nav.c_b_e[i], c_t @ truth.c_b_e[j]),
    }  # fmt: skip
    pose = np.asarray(nav_f.pose_covariance, dtype=np.float64).reshape(-1, 6, 6)[i]  # type: ignore[attr-defined]
    vcov = np.asarray(vel_f.covariance, dtype=np.float64).reshape(-1, 6, 6)[kv, :3, :3]  # type: ignore[attr-defined]
    jac = np.concatenate([C_NED_TO_UEN @ frame_turn(lat, alt) @ c_f, -C_NED_TO_UEN @ c_f], axis=2)
    cov = {
        "position": c_f @ pose[:, :3, :3] @ np.swapaxes(c_f, -1, -2),
        "velocity": _ENU @ vcov @ _ENU,
        "attitude": jac @ pose @ np.swapaxes(jac, -1, -2),
    }
    nees = np.stack([_nees(errors[q], cov[q]) for q in QUANTITIES], axis=-1)
    res = AidedResult(
        prefix=prefix, truth_topic=truth_topic, stamps_ns=stamps,
        t=(stamps - start_ns).astype(np.float64) * 1e-9, errors=errors,
        sigma={q: _sym_sigma(c) for q, c in cov.items()}, nees=nees,
    )  # fmt: skip
    published = (("position", "error_position"), ("velocity", "error_velocity"),
                 ("attitude", "error_attitude"), ("nees", "nees"))  # fmt: skip
    for q, key in published:
        topic = f"{prefix}/{BASE_OUTPUTS[key]}"
        d = contents.topics.get(topic)
        value = None
        if d is not None and d.msgtype == VECTOR3 and len(d):
            f = contents[topic]
            st = np.asarray(f.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
            _, a, b = np.intersect1d(stamps, st, return_indices=True)
            value = np.full((stamps.size, 3), np.nan)
            value[a] = np.asarray(f.vector, dtype=np.float64)[b]  # type: ignore[attr-defined]
        if q == "nees":
            res.published_nees = value
        else:
            res.published_errors[q] = value
    for sensor in AIDED_SENSORS:
        topic = f"{prefix}/nis/{sensor}"
        d = contents.topics.get(topic)
        if d is None or d.msgtype != VECTOR3 or not len(d):
            continue
        f = contents[topic]
        v = np.asarray(f.vector, dtype=np.float64)  # type: ignore[attr-defined]
        st = np.asarray(f.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
        res.nis.append(Nis(sensor, topic, (st - start_ns) * 1e-9, v[:, 0], v[:, 1], v[:, 2] > 0.5))
    return res


# ------------------------------------------------------------------------------------------
# tables
# ------------------------------------------------------------------------------------------


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return [line(head), "|" + "|".join("---" for _ in head) + "|"] + [line(r) for r in rows]


def _e(x: float) -> str:
    return "—" if x is None or not np.isfinite(x) else f"{x:.2e}"


def _pct(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{100 * x:.1f} %"


_AXES = {"position": ("north", "east", "down"), "velocity": ("north", "east", "down"),
         "attitude": ("θ1 up", "θ2 east", "θ3 north")}  # fmt: skip
_UNIT = {"position": "m", "velocity": "m/s", "attitude": "rad"}


def aided_table(a: AidedResult) -> list[str]:
    """Errors against ±3σ, NEES and NIS with the fraction inside their bounds."""
    if not a.t.size:
        return [f"`{a.prefix}` and `{a.truth_topic}` share no stamp."]
    rows = []
    for q in QUANTITIES:
        inside = a.inside_3sigma(q)
        for k, axis in enumerate(_AXES[q]):
            e, s = a.errors[q][:, k], a.sigma[q][:, k]
            rows.append([f"{q} {axis}", _e(float(np.abs(e).max())), _e(float(e[-1])),
                         _e(float(s[-1])), _pct(float(inside[k])), _UNIT[q]])  # fmt: skip
    lines = [f"`{a.prefix}` against `{a.truth_topic}`, {a.t.size} epochs "
             f"({a.t[0]:.3f} s to {a.t[-1]:.3f} s):", ""]  # fmt: skip
    lines += _table(["error", "max |e|", f"final e (t = {a.t[-1]:.3f} s)", "final σ",
                     "inside ±3σ", "unit"], rows)  # fmt: skip
    lo, hi = chi2_bounds(3.0)
    inside = a.nees_inside()
    nrows = [[f"NEES {q} (3 dof)", f"{np.mean(a.nees[:, k]):.3g}",
              f"[{lo:.3g}, {hi:.3g}]", _pct(float(inside[k])), str(a.t.size)]
             for k, q in enumerate(QUANTITIES)]  # fmt: skip
    for n in a.nis:
        acc = n.accepted
        dof = np.unique(n.dof[acc]) if acc.any() else np.unique(n.dof)
        lo_n, hi_n = chi2_bounds(np.maximum(dof, 1.0))
        bounds = ", ".join(f"[{x:.3g}, {y:.3g}]" for x, y in zip(lo_n, hi_n, strict=True))
        dofs = "/".join(f"{d:g}" for d in dof)
        frac = float(np.mean(n.inside()[acc])) if acc.any() else float("nan")
        mean = float(np.mean(n.nis[acc])) if acc.any() else float("nan")
        nrows.append([f"NIS {n.sensor} ({dofs} dof)", f"{mean:.3g}", bounds, _pct(frac),
                      f"{int(acc.sum())} of {acc.size} accepted"])  # fmt: skip
    lines += ["", *_table(["statistic", "mean", "95 % χ² interval", "inside", "samples"], nrows)]
    if a.published_nees is not None:
        ok = np.isfinite(a.published_nees[:, 0])
        if ok.any():
            pub = a.published_nees[ok]
            rel = float(np.max(np.abs(a.nees[ok] - pub) / np.maximum(pub, 1e-300)))
            lines += ["", f"NEES recomputed from `{a.prefix}/odom`, `{a.prefix}/vel` and the "
                      f"truth agrees with the filter's `{a.prefix}/nees` to a relative "
                      f"{_e(rel)} (max)."]  # fmt: skip
    lines += ["", "NEES with 3 degrees of freedom per quantity; NIS of the accepted measurements "
              "(a rejected one is outside the gate). One run, correlated samples: the fraction "
              "inside is indicative (a consistent filter: about 95 %)."]  # fmt: skip
    return lines


# ------------------------------------------------------------------------------------------
# plots
# ------------------------------------------------------------------------------------------

_COLORS = ("tab:red", "tab:green", "tab:blue")


def _save(fig: Figure, path: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path


def _scale(values: F64, unit: str) -> tuple[float, str]:
    from strapdown_ros.report.plots import eng_scale

    return eng_scale(values, unit)


def plot_aided_errors(a: AidedResult, bag_name: str, path: Path) -> Path:
    """Errors of the filter (3 × 3 panels: position, velocity, attitude × axes) with ±3σ."""
    fig = Figure(figsize=(13, 9.5), layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    for r, q in enumerate(QUANTITIES):
        f, unit = _scale(np.concatenate([a.errors[q], 3 * a.sigma[q]]), _UNIT[q])
        for k in range(3):
            ax = axes[r, k]
            band = 3.0 * a.sigma[q][:, k] * f
            ax.fill_between(a.t, -band, band, color=_COLORS[k], alpha=0.15, lw=0,
                            label="±3σ (filter covariance)")  # fmt: skip
            ax.plot(a.t, a.errors[q][:, k] * f, color=_COLORS[k], lw=0.9, label="error")
            inside = a.inside_3sigma(q)[k]
            ax.set_title(f"{q} {_AXES[q][k]} ({100 * inside:.0f} % inside ±3σ)", fontsize=9)
            ax.set_ylabel(f"[{unit}]")
            ax.grid(alpha=0.3)
            if r == 0 and k == 0:
                ax.legend(fontsize=8, loc="upper left")
    for ax in axes[-1]:
        ax.set_xlabel("time since start [s]")
    fig.suptitle(f"{bag_name}: {a.prefix} minus truth ({a.truth_topic}) with the filter's ±3σ "
                 "(position, velocity NED; attitude Young angles)", fontsize=11)  # fmt: skip
    return _save(fig, path)


def plot_aided_consistency(a: AidedResult, bag_name: str, path: Path) -> Path:
    """NEES per quantity and NIS per measurement, log axes, with the 95 % χ² interval."""
    n_rows = 1 + (1 if a.nis else 0)
    fig = Figure(figsize=(13, 3.8 * n_rows + 0.6), layout="constrained")
    top = fig.subplots(n_rows, 1, squeeze=False)[:, 0]
    ax = top[0]
    lo, hi = chi2_bounds(3.0)
    inside = a.nees_inside()
    for k, q in enumerate(QUANTITIES):
        ax.semilogy(a.t, np.maximum(a.nees[:, k], 1e-6), color=_COLORS[k], lw=0.9,
                    label=f"{q} ({100 * inside[k]:.0f} % inside)")  # fmt: skip
    for b in (lo, hi):
        ax.axhline(b, color="black", ls="--", lw=1.0)
    ax.set(title=f"NEES (3 dof each; dashed: 95 % χ² interval [{lo:.3g}, {hi:.3g}])",
           ylabel="NEES", xlabel="time since start [s]")  # fmt: skip
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper left", ncol=3)
    if a.nis:
        bx = top[1]
        for i, n in enumerate(a.nis):
            color = f"C{i}"
            acc = n.accepted
            frac = float(np.mean(n.inside()[acc])) if acc.any() else float("nan")
            bx.semilogy(n.t[acc], np.maximum(n.nis[acc], 1e-6), ".", ms=2, color=color,
                        label=f"{n.sensor} ({100 * frac:.0f} % inside)")  # fmt: skip
            if (~acc).any():
                bx.semilogy(n.t[~acc], np.maximum(n.nis[~acc], 1e-6), "x", ms=4, color=color)
            dof = np.unique(n.dof[acc]) if acc.any() else np.unique(n.dof)
            lo_n, hi_n = chi2_bounds(np.maximum(dof, 1.0))
            for x, y in zip(lo_n, hi_n, strict=True):
                bx.axhline(x, color=color, ls="--", lw=0.8)
                bx.axhline(y, color=color, ls="--", lw=0.8)
        bx.set(title="NIS per measurement (dots: accepted, ×: rejected; dashed: 95 % χ² "
               "interval of its dof)", ylabel="NIS", xlabel="time since start [s]")  # fmt: skip
        bx.grid(alpha=0.3, which="both")
        bx.legend(fontsize=8, loc="upper left", ncol=5)
    fig.suptitle(f"{bag_name}: consistency of {a.prefix}", fontsize=11)
    return _save(fig, path)
