"""A free-inertial solution computed by the report: the package's navigator run on an Imu topic
read back from the bag, initialized from its truth (numpy; no plotting).

For a measured IMU ``P/imu_measured`` with truth ``P/odom`` the report runs the core navigator
(multirate, exact mode, N = 10, p = 2 unless told otherwise; no initial errors, no vertical
damping) on the recorded increments ``Δα = FRD(ω) T``, ``Δv = FRD(f) T`` (docs/interface.md
§2), starting at the first truth message ``s`` whose next IMU message ``s + T`` is in the bag
(the navigator stage's rule, docs/navigator.md). Its errors against the truth follow
docs/interface.md §4 (:mod:`strapdown_ros.core.navigation.errors`): position NED of the true
position, velocity NED, attitude Young 1980 eq. (28) angles (up, east, north). The same run on
the ideal twin ``P/imu`` stays at the round-off of the exact update.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.config.navigator import NavigatorSpec
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic, geodetic_to_ecef
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.messages import imu_increments, odometry_state

__all__ = [
    "ErrorGrowth",
    "FreeInertial",
    "free_inertial",
    "growth_table",
    "plot_free_inertial",
    "report_navigator_spec",
]


@dataclass
class FreeInertial:
    """The report's navigator run on ``imu_topic`` with its errors against ``truth_topic``.

    Rows: the initial state at the start stamp, then one per navigation cycle (N IMU periods).
    """

    imu_topic: str
    truth_topic: str
    kind: str  #: ``measured`` or ``ideal``
    spec: NavigatorSpec
    stamps_ns: NDArray[np.int64]  #: (K,) output stamps
    t: F64  #: (K,) s since the bag start
    r_e: F64  #: (K, 3) ECEF position, m
    v_ned: F64  #: (K, 3) m/s
    c_b_n: F64  #: (K, 3, 3) body FRD to NED
    position: F64  #: (K, 3) NED error, m
    velocity: F64  #: (K, 3) NED error, m/s
    attitude: F64  #: (K, 3) Young θ1, θ2, θ3 (up, east, north), rad
    elapsed_s: float = 0.0  #: wall time of the run (reading excluded)
    note: str = ""  #: a gap or truth lost: where the run stopped

    @property
    def label(self) -> str:
        return f"free-inertial on {self.imu_topic}"


def report_navigator_spec(
    imu_topic: str, truth_topic: str, gravity_model: str, n: int = 10, p: int = 2
) -> NavigatorSpec:
    """The navigator the report runs: multirate, exact mode, no initial errors or damping."""
    return NavigatorSpec(
        algorithm="multirate", mode="exact", n=n, p=p, imu_topic=imu_topic,
        truth_topic=truth_topic, gravity_model=gravity_model,
    )  # fmt: skip


def free_inertial(
    contents: BagContents,
    imu_topic: str,
    truth_topic: str,
    start_ns: int,
    *,
    gravity_model: str = "j2",
    kind: str = "measured",
    n: int = 10,
    p: int = 2,
) -> FreeInertial | str:
    """Run the report's navigator on ``imu_topic`` from truth ``truth_topic`` (a string says
    why not). ``start_ns``: the bag's start (times are seconds since it)."""
    from strapdown_ros.stages.navigator_run import build_navigator
    from strapdown_ros.stages.navigator_truth import initial_state_from_truth

    imu_d, truth_d = contents.topics.get(imu_topic), contents.topics.get(truth_topic)
    if imu_d is None or truth_d is None or imu_d.fields is None or truth_d.fields is None:
        return f"`{imu_topic}` or its truth `{truth_topic}` is missing"
    imu = contents[imu_topic]
    raw = np.asarray(imu.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
    if raw.size < 2 or np.any(np.diff(raw) <= 0):
        return f"`{imu_topic}`: fewer than 2 messages or stamps not increasing"
    # T: the most common spacing (a gap or a lost message does not change it)
    steps, counts = np.unique(np.diff(raw), return_counts=True)
    inc = imu_increments(imu, int(steps[np.argmax(counts)]))  # type: ignore[arg-type]
    truth = odometry_state(contents[truth_topic])  # type: ignore[arg-type]
    stamps = np.asarray(inc.stamps_ns, dtype=np.int64)
    period = int(inc.period_ns)
    t_stamps = np.asarray(truth.stamps_ns, dtype=np.int64)
    hits = np.flatnonzero(np.isin(t_stamps + period, stamps))
    if not hits.size:
        return f"no `{truth_topic}` message is followed by a `{imu_topic}` message one period later"
    row = int(hits[0])
    s0 = int(t_stamps[row])
    i0 = int(np.searchsorted(stamps, s0 + period))
    note = ""
    # contiguous stretch from s0 + T (the navigator integrates nothing across a gap)
    steps = np.diff(stamps[i0:])
    if np.any(steps != period):
        end = i0 + 1 + int(np.argmax(steps != period))
        note = f"`{imu_topic}` has a gap after {(int(stamps[end - 1]) - start_ns) * 1e-9:.3f} s"
    else:
        end = stamps.size
    cycles = (end - i0) // n
    if cycles < 1:
        return f"`{imu_topic}` has fewer than N = {n} messages after the first truth"
    spec = report_navigator_spec(imu_topic, truth_topic, gravity_model, n, p)
    clock = time.perf_counter()
    initial = initial_state_from_truth(truth, row, spec)
    nav = build_navigator(spec, initial, period * 1e-9, n)
    used = slice(i0, i0 + cycles * n)
    sol = nav.run(inc.dalpha[used], inc.dv[used])
    elapsed = time.perf_counter() - clock
    out_stamps = s0 + n * period * np.arange(cycles + 1, dtype=np.int64)
    lat = np.concatenate([[initial.lat], sol.lat])
    lon = np.concatenate([[initial.lon], sol.lon])
    alt = np.concatenate([[initial.alt], sol.alt])
    v_ned = np.concatenate([np.asarray(initial.v_ned, dtype=np.float64)[None], sol.v_ned])
    q = np.concatenate([np.asarray(initial.q_b_n, dtype=np.float64)[None], sol.q_b_n])
    # truth at the output stamps (an output without truth ends the comparison)
    common, i_out, i_tr = np.intersect1d(out_stamps, t_stamps, return_indices=True)
    if common.size < out_stamps.size:
        k = int(np.argmax(~np.isin(out_stamps, t_stamps)))
        note = (note + "; " if note else "") + (
            f"no `{truth_topic}` at {(int(out_stamps[k]) - start_ns) * 1e-9:.3f} s: errors "
            "shown only where the truth is"
        )
    r_e = geodetic_to_ecef(lat, lon, alt)
    c_b_n = dcm_from_quat(q)
    r_true = truth.r_e[i_tr]
    lat_t, lon_t, _ = ecef_to_geodetic(r_true)
    c_e_n = dcm_ecef_to_ned(lat_t, lon_t)
    v_true = np.einsum("kij,kj->ki", c_e_n, truth.v_e[i_tr])
    c_true = c_e_n @ truth.c_b_e[i_tr]
    return FreeInertial(
        imu_topic=imu_topic,
        truth_topic=truth_topic,
        kind=kind,
        spec=spec,
        stamps_ns=common,
        t=(common - start_ns).astype(np.float64) * 1e-9,
        r_e=r_e[i_out],
        v_ned=v_ned[i_out],
        c_b_n=c_b_n[i_out],
        position=position_error_ned(r_e[i_out], r_true, lat_t, lon_t),
        velocity=velocity_error_ned(v_ned[i_out], v_true),
        attitude=attitude_error_young(c_b_n[i_out], c_true),
        elapsed_s=elapsed,
        note=note,
    )


# ------------------------------------------------------------------------------------------
# error growth beside the exact navigator on the ideal IMU: table and plot
# ------------------------------------------------------------------------------------------


@dataclass
class ErrorGrowth:
    """Errors of one solution for the comparison (rows (K, 3) as in :class:`FreeInertial`)."""

    label: str
    t: F64
    position: F64
    velocity: F64
    attitude: F64

    @classmethod
    def of(cls, run: FreeInertial, label: str | None = None) -> ErrorGrowth:
        return cls(label or f"report's navigator on {run.imu_topic} ({run.kind})", run.t,
                   run.position, run.velocity, run.attitude)  # fmt: skip


#: (label, quantity, unit, magnitude of the (K, 3) errors)
GROWTH_QUANTITIES = (
    ("horizontal position (RSS north, east)", "position", "m",
     lambda v: np.hypot(v[:, 0], v[:, 1])),
    ("vertical position (|down|)", "position", "m", lambda v: np.abs(v[:, 2])),
    ("velocity (|NED|)", "velocity", "m/s", lambda v: np.linalg.norm(v, axis=1)),
    ("attitude, heading |θ1|", "attitude", "rad", lambda v: np.abs(v[:, 0])),
    ("attitude, tilt (RSS θ2, θ3)", "attitude", "rad", lambda v: np.hypot(v[:, 1], v[:, 2])),
)  # fmt: skip


def growth_table(series: list[ErrorGrowth]) -> list[str]:
    """Markdown: final and max of each magnitude, one column pair per solution."""

    def e(x: float) -> str:
        return "—" if not np.isfinite(x) else f"{x:.2e}"

    head = ["quantity"]
    for s in series:
        head += [f"{s.label}: final (t = {s.t[-1]:.3f} s)", "max"]
    head.append("unit")
    rows = []
    for label, name, unit, f in GROWTH_QUANTITIES:
        row = [label]
        for s in series:
            v = f(getattr(s, name))
            row += [e(float(v[-1])), e(float(np.max(v)))]
        rows.append(row + [unit])
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    return lines + ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]


def plot_free_inertial(series: list[ErrorGrowth], title: str, path: Path) -> Path:
    """Error magnitudes (log axes) of the solutions: position, velocity, attitude."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 10), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    colors = ("tab:red", "tab:blue", "tab:green", "tab:purple")
    panels = {"position": axes[0], "velocity": axes[1], "attitude": axes[2]}
    styles: dict[str, int] = {}
    for label, name, unit, f in GROWTH_QUANTITIES:
        ax = panels[name]
        ls = ("-", "--")[styles.get(name, 0)]
        styles[name] = styles.get(name, 0) + 1
        for i, s in enumerate(series):
            v = f(getattr(s, name))
            ax.semilogy(s.t, np.maximum(v, 1e-18), color=colors[i % 4], ls=ls, lw=1.0,
                        label=f"{label}: {s.label}")  # fmt: skip
        ax.set_ylabel(f"{name} error [{unit}]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_title("navigation minus truth (log scale; floor 1e-18)")
    axes[-1].set_xlabel("time since start [s]")
    fig.suptitle(title, fontsize=11)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path
