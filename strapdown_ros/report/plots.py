"""The report's figures (matplotlib, Agg canvas, no pyplot state).

Every function draws one PNG from :mod:`strapdown_ros.report.data` objects. Long series are
reduced to at most ~2 x :data:`MAX_BINS` points per line by min/max binning (each bin keeps its
minimum and maximum), so a 120 000-sample stream draws quickly and an oscillation (bending,
Method 1's cycle-to-cycle flip) still shows at its full size instead of aliasing; magnitudes on
log axes keep each bin's maximum.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.report.data import (
    AllanResult,
    BagData,
    Comparison,
    ErrorSet,
    ImuData,
    MeasuredImu,
    StreamData,
    is_navigator,
    is_regenerated,
)

__all__ = [
    "MAX_BINS",
    "eng_scale",
    "minmax_decimate",
    "plot_allan",
    "plot_attitude_velocity",
    "plot_comparison",
    "plot_exactness",
    "plot_imu",
    "plot_navigation_errors",
    "plot_trajectory",
]


#: Bins per line for min/max decimation.
MAX_BINS = 2000
DPI = 100
AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")  # x/N/θ1, y/E/θ2, z/D/θ3
#: (threshold, factor, prefix): values >= threshold are shown times factor with the prefix.
_PREFIXES = (
    (1e3, 1e-3, "k"), (1.0, 1.0, ""), (1e-3, 1e3, "m"), (1e-6, 1e6, "µ"), (1e-9, 1e9, "n"),
    (1e-12, 1e12, "p"), (1e-15, 1e15, "f"),
)  # fmt: skip


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------


def minmax_decimate(t: F64, y: F64, bins: int = MAX_BINS) -> tuple[F64, F64]:
    """At most ``2 * bins`` points of ``(t, y)`` (``y`` (N,) or (N, k)) keeping each bin's
    minimum and maximum (per column), so oscillations keep their envelope."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = t.shape[0]
    if n <= 2 * bins:
        return t, y
    size = int(np.ceil(n / bins))
    m = n // size
    tb = t[: m * size].reshape(m, size)
    yb = y[: m * size].reshape((m, size) + y.shape[1:])
    t2 = np.stack([tb[:, 0], tb[:, -1]], axis=1).reshape(-1)
    y2 = np.stack([np.nanmin(yb, axis=1), np.nanmax(yb, axis=1)], axis=1)
    y2 = y2.reshape((2 * m,) + y.shape[1:])
    if m * size < n:  # the tail
        t2 = np.concatenate([t2, t[m * size :]])
        y2 = np.concatenate([y2, y[m * size :]])
    return t2, y2


def max_decimate(t: F64, y: F64, bins: int = MAX_BINS) -> tuple[F64, F64]:
    """Each bin's maximum of a non-negative series (for log axes), at the bin centres."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = t.shape[0]
    if n <= bins:
        return t, y
    size = int(np.ceil(n / bins))
    m = n // size
    tb = t[: m * size].reshape(m, size).mean(axis=1)
    yb = np.nanmax(y[: m * size].reshape((m, size) + y.shape[1:]), axis=1)
    if m * size < n:
        tb = np.append(tb, t[m * size :].mean())
        yb = np.concatenate([yb, np.nanmax(y[m * size :], axis=0, keepdims=True)])
    return tb, yb


def eng_scale(values: object, unit: str) -> tuple[float, str]:
    """``(factor, unit)`` with an SI prefix so that ``max|values| * factor`` is in [1, 1000).

    Radians become degrees when they exceed 0.01 rad; ``k`` is only used for metres.
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    peak = float(np.max(np.abs(v))) if v.size else 0.0
    if unit == "rad" and peak >= 0.01:
        return float(np.degrees(1.0)), "deg"
    if peak == 0.0:
        return 1.0, unit
    for threshold, factor, p in _PREFIXES:
        if threshold > 1.0 and unit != "m":
            continue
        if peak >= threshold:
            return factor, p + unit
    return 1e15, "f" + unit


def _break_wraps(t: F64, deg: F64, jump: float = 180.0) -> tuple[F64, F64]:
    """Insert NaN where an angle wraps (so the line is not drawn across the plot)."""
    if deg.shape[0] < 2:
        return t, deg
    cut = np.nonzero(np.abs(np.diff(deg)) > jump)[0] + 1
    if cut.size == 0:
        return t, deg
    return np.insert(t, cut, np.nan), np.insert(deg, cut, np.nan)


def _figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    for ax in fig.axes:  # plain tick labels (no "+2.999e2" offsets) on linear axes
        for axis, scale in (("x", ax.get_xscale()), ("y", ax.get_yscale())):
            if scale == "linear":
                try:
                    ax.ticklabel_format(axis=axis, useOffset=False)
                except AttributeError:  # not a ScalarFormatter
                    pass
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    return path


def _style(i: int, prefix: str) -> dict[str, object]:
    """Line style of the i-th stream: navigators dashed on top, the reference solid."""
    colors = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:olive", "tab:cyan")
    if is_navigator(prefix):
        return {"color": "tab:red", "ls": "--", "lw": 1.2, "zorder": 4}
    # the main stream (first) on top of the variations, under the navigators
    return {"color": colors[i % len(colors)], "ls": "-", "lw": 1.1 if i == 0 else 0.9,
            "zorder": 3 if i == 0 else 2}  # fmt: skip


def _plotted_streams(bag: BagData) -> list[StreamData]:
    """Streams worth drawing: everything except regenerated references (they coincide with
    the reference), the reference first."""
    out = [s for p, s in bag.streams.items() if not is_regenerated(p)]
    out.sort(key=lambda s: (s.prefix != "/reference", is_navigator(s.prefix)))
    return out


def _time_label(bag: BagData) -> str:
    return f"time since start [s] (start {bag.start_utc})"


# ------------------------------------------------------------------------------------------
# figures
# ------------------------------------------------------------------------------------------


def plot_trajectory(bag: BagData, path: Path) -> Path:
    """Ground track (north/east of the first position of the main stream) and altitude."""
    streams = _plotted_streams(bag)
    main = streams[0]
    r0 = geodetic_to_ecef(main.lat[0], main.lon[0], main.alt[0])
    c0 = dcm_ecef_to_ned(main.lat[0], main.lon[0])
    tracks = []
    for s in streams:
        r = s.r_e if s.r_e is not None else geodetic_to_ecef(s.lat, s.lon, s.alt)
        tracks.append((r - r0) @ c0.T)
    extent = max(float(np.max(np.abs(n[:, :2]))) for n in tracks)
    k, unit = (1e-3, "km") if extent >= 2000 else (1.0, "m")

    fig = _figure(12, 5.5)
    gs = fig.add_gridspec(1, 2, width_ratios=[1.1, 1])
    ax = fig.add_subplot(gs[0, 0])
    bx = fig.add_subplot(gs[0, 1])
    for i, (s, ned) in enumerate(zip(streams, tracks, strict=True)):
        st = _style(i, s.prefix)
        step = max(1, ned.shape[0] // (4 * MAX_BINS))
        ax.plot(ned[::step, 1] * k, ned[::step, 0] * k, label=s.label, **st)
        tt, alt = minmax_decimate(s.t, s.alt)
        bx.plot(tt, alt, label=s.label, **st)
    ned = tracks[0]
    ax.plot(ned[0, 1] * k, ned[0, 0] * k, "o", color="tab:green", ms=8, label="start", zorder=4)
    ax.plot(ned[-1, 1] * k, ned[-1, 0] * k, "s", color="black", ms=7, label="end", zorder=4)
    ax.set(
        xlabel=f"east [{unit}]",
        ylabel=f"north [{unit}]",
        title=f"ground track (origin: start of {main.label}, "
        f"{np.degrees(main.lat[0]):.5f}°, {np.degrees(main.lon[0]):.5f}°)",
        aspect="equal",
    )
    ax.title.set_fontsize(10)
    ax.legend(fontsize=9, loc="best")
    ax.grid(alpha=0.3)
    bx.set(xlabel=_time_label(bag), ylabel="altitude [m] (ellipsoidal, WGS-84)", title="altitude")
    bx.legend(fontsize=9, loc="best")
    bx.grid(alpha=0.3)
    fig.suptitle(f"{bag.name}: trajectory ({bag.duration_s:g} s)", fontsize=12)
    return _save(fig, path)


def plot_attitude_velocity(bag: BagData, path: Path) -> Path:
    """Roll, pitch, heading (deg) and NED velocity (m/s) of every Odometry stream."""
    streams = [s for s in _plotted_streams(bag) if s.rph is not None and s.v_ned is not None]
    fig = _figure(13, 8.5)
    axes = fig.subplots(3, 2, sharex=True)
    names = (("roll", "pitch", "heading"), ("north", "east", "down"))
    for i, s in enumerate(streams):
        st = _style(i, s.prefix)
        deg = np.degrees(s.rph)  # type: ignore[arg-type]
        deg[:, 2] = np.mod(deg[:, 2], 360.0)
        tt, dd = minmax_decimate(s.t, deg)
        for row in range(3):
            t1, d1 = _break_wraps(tt, dd[:, row])
            axes[row, 0].plot(t1, d1, label=s.label, **st)
        tt, vv = minmax_decimate(s.t, s.v_ned)  # type: ignore[arg-type]
        for row in range(3):
            axes[row, 1].plot(tt, vv[:, row], label=s.label, **st)
    for row in range(3):
        axes[row, 0].set_ylabel(f"{names[0][row]} [deg]")
        axes[row, 1].set_ylabel(f"v {names[1][row]} [m/s]")
        for col in range(2):
            axes[row, col].grid(alpha=0.3)
    axes[2, 0].set_ylim(-5, 365)
    axes[2, 0].set_yticks(range(0, 361, 90))
    axes[0, 0].set_title("attitude of the body (FRD) w.r.t. NED: roll, pitch, heading")
    axes[0, 1].set_title("velocity relative to the Earth, NED")
    axes[0, 0].legend(fontsize=9, loc="best")
    for col in range(2):
        axes[2, col].set_xlabel(_time_label(bag))
    fig.suptitle(f"{bag.name}: attitude and velocity", fontsize=12)
    return _save(fig, path)


def plot_imu(bag: BagData, path: Path) -> Path:
    """Angular rate (deg/s) and specific force (m/s²) of every IMU topic, each in its own FLU
    axes, labelled by the vehicle direction each axis points to as mounted; a measured IMU
    in the column beside its ideal twin."""
    imus = imu_list(bag)
    fig = _figure(6.5 * len(imus) + 0.5, 7)
    axes = fig.subplots(2, len(imus), sharex=True, squeeze=False)
    for col, d in enumerate(imus):
        labels = d.axis_labels
        tt, w = minmax_decimate(d.t, np.degrees(d.gyro))
        tt, f = minmax_decimate(d.t, d.accel)
        for k in range(3):  # z (largest: gravity, bending) behind x and y
            z = 3 - k
            axes[0, col].plot(tt, w[:, k], color=AXIS_COLORS[k], lw=0.7, label=labels[k], zorder=z)
            axes[1, col].plot(tt, f[:, k], color=AXIS_COLORS[k], lw=0.7, label=labels[k], zorder=z)
        kind = "measured" if d.measured else "ideal"
        frame = f", frame {d.frame_id}" if d.frame_id else ""
        axes[0, col].set(title=f"{d.topic} ({kind}{frame}): angular rate Δα/T",
                         ylabel="angular rate [deg/s]")  # fmt: skip
        axes[1, col].set(
            title=f"{d.topic} ({kind}): specific force Δv/T",
            ylabel="specific force [m/s²]",
            xlabel=_time_label(bag),
        )
        for row in range(2):
            axes[row, col].title.set_fontsize(10)
        for row in range(2):
            axes[row, col].grid(alpha=0.3)
            axes[row, col].legend(fontsize=8, loc="best", ncol=3)
    fig.suptitle(f"{bag.name}: IMU increments (each IMU's own FLU axes, named by the vehicle "
                 "direction they point to as mounted)", fontsize=12)  # fmt: skip
    return _save(fig, path)


def plot_exactness(bag: BagData, path: Path) -> Path:
    """One-step residuals of Savage 2020 eqs. (2)-(4) per stream, with interface §3's limits."""
    items = [(p, r) for p, (_, r) in bag.residuals.items() if isinstance(r, Residuals)]
    fig = _figure(12, 6)
    axes = fig.subplots(1, 3)
    quantities = (
        ("attitude", "attitude [rad]", Residuals.TOL_ATTITUDE),
        ("velocity", "velocity [m/s]", Residuals.TOL_VELOCITY),
        ("position", "position [m]", Residuals.TOL_POSITION),
    )
    for ax, (name, label, tol) in zip(axes, quantities, strict=True):
        for i, (prefix, res) in enumerate(items):
            t = bag.imus[prefix].t
            tb, yb = max_decimate(t, np.maximum(getattr(res, name), 1e-20), 300)
            ax.semilogy(tb, yb, lw=0.8, color=_style(i, prefix)["color"], label=prefix)
        ax.axhline(tol, color="black", ls="--", lw=1.2, label=f"docs/interface.md §3 limit {tol:g}")
        ax.set(title=f"{label.split(' ')[0]} residual", xlabel=_time_label(bag).split(" (")[0])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left")
        ax.set_ylim(1e-19, 1e-4)
    fig.suptitle(
        f"{bag.name}: exactness, one-step residuals of eqs. (2)-(4) read back from the bag "
        "(max per bin; below the dashed line = exact)",
        fontsize=11,
    )
    return _save(fig, path)


def plot_navigation_errors(bag: BagData, es: ErrorSet, path: Path) -> Path:
    """Navigation minus truth: NED position (m), NED velocity (m/s), Young angles."""
    rows = [
        (name, getattr(es, name))
        for name in ("position", "velocity", "attitude")
        if getattr(es, name) is not None
    ]
    fig = _figure(12, 3.0 * len(rows) + 1.2)
    axes = fig.subplots(len(rows), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, (t, vec)) in zip(axes, rows, strict=True):
        if name == "attitude":
            f, unit = eng_scale(vec, "rad")
            labels = ("θ1 (about up: heading)", "θ2 (about east)", "θ3 (about north)")
            title = "attitude error: Young 1980 eq. (28) angles, true → computed local level"
        else:
            f, unit = eng_scale(vec, "m" if name == "position" else "m/s")
            labels = ("north", "east", "down")
            title = f"{name} error, NED (navigation minus truth)"
        tt, yy = minmax_decimate(t, vec * f)
        for k in range(3):
            ax.plot(tt, yy[:, k], color=AXIS_COLORS[k], lw=0.9, label=labels[k])
        if name == "position":
            tt, hh = minmax_decimate(t, np.hypot(vec[:, 0], vec[:, 1]) * f)
            ax.plot(tt, hh, color="black", lw=0.9, ls=":", label="horizontal (RSS)")
        ax.axhline(0.0, color="grey", lw=0.5)
        ax.set(title=title, ylabel=f"{name} error [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", ncol=4)
    axes[-1].set_xlabel(_time_label(bag))
    fig.suptitle(f"{bag.name}: navigation errors of {es.prefix}", fontsize=12)
    return _save(fig, path)


def _magnitudes(ax: Axes, series: list[tuple[F64, F64, dict]], unit: str, bins: int) -> None:
    """Draw non-negative series (max per bin): log axis when they span more than 1.5 decades,
    else linear with an SI prefix (a narrow log axis has almost no tick labels)."""
    binned = [(max_decimate(t, y, bins), kw) for t, y, kw in series if t.size]
    values = np.concatenate([yb for (_, yb), _ in binned]) if binned else np.zeros(0)
    positive = values[values > 0]
    log = positive.size > 0 and np.log10(positive.max() / positive.min()) > 1.5
    f, u = (1.0, unit) if log else eng_scale(values, unit)
    for (tb, yb), kw in binned:
        if log:
            ax.semilogy(tb, np.maximum(yb, positive.min()), **kw)
        else:
            ax.plot(tb, yb * f, **kw)
    if not log:
        ax.set_ylim(bottom=0.0)
    ax.set_ylabel(f"{ax.get_ylabel()} [{u}]")


def plot_comparison(cmp: Comparison, title: str, path: Path) -> Path:
    """Two variation streams (e.g. Method 1 and Method 2) of the same reference."""
    fig = _figure(12, 10)
    gs = fig.add_gridspec(3, 2)
    ax = fig.add_subplot(gs[0, 0])
    bx = fig.add_subplot(gs[0, 1], sharex=ax)
    cx = fig.add_subplot(gs[1, :], sharex=ax)
    dx = fig.add_subplot(gs[2, :])
    bins = 400  # envelopes: a few hundred bins read better than per-cycle values
    line = {"color": "black", "lw": 0.9}
    ax.set(title="velocity difference |V_a − V_b| (max per bin)", ylabel="velocity difference",
           xlabel="time since start [s]")  # fmt: skip
    _magnitudes(ax, [(cmp.t, cmp.dv, line)], "m/s", bins)
    bx.set(title=f"|R_a − R_b| at odd cycles (even cycles: max {cmp.even_cycles_dr:.1e} m)",
           ylabel="position difference", xlabel="time since start [s]")  # fmt: skip
    _magnitudes(bx, [(cmp.t[cmp.odd], cmp.dr[cmp.odd], line)], "m", bins)
    colors = ("tab:red", "tab:blue")
    mags = (np.linalg.norm(cmp.alt_a, axis=-1), np.linalg.norm(cmp.alt_b, axis=-1))
    series = []
    for mag, label, c in zip(mags, (cmp.label_a, cmp.label_b), colors, strict=True):
        med = float(np.median(mag)) if mag.size else float("nan")
        series.append((cmp.t_alt, mag, {"color": c, "lw": 1.0,
                                        "label": f"{label} (median {med:.1e} m/s)"}))  # fmt: skip
    cx.set(title="odd/even alternation of the velocity, |Δ⁴V|/16 (max per bin)",
           ylabel="alternation", xlabel="time since start [s]")  # fmt: skip
    _magnitudes(cx, series, "m/s", bins)
    cx.legend(fontsize=9, loc="lower right")
    ax.text(0.01, 0.02, f"a = {cmp.label_a}\nb = {cmp.label_b}", transform=ax.transAxes,
            fontsize=8, va="bottom")  # fmt: skip
    for a in (ax, bx, cx):
        a.grid(alpha=0.3, which="both")

    # zoom: 60 cycles around the largest alternation of either stream, its largest component
    both = np.maximum(mags[0], mags[1]) if mags[0].size else mags[0]
    if both.size:
        centre = int(np.argmax(both))
        sl = slice(max(0, centre - 30), min(both.size, centre + 30))
        k = int(np.argmax(np.abs(cmp.alt_a[centre]) + np.abs(cmp.alt_b[centre])))
        comp = ("north", "east", "down")[k]
        f, unit = eng_scale(np.concatenate([cmp.alt_a[sl, k], cmp.alt_b[sl, k]]), "m/s")
        dx.plot(cmp.t_alt[sl], cmp.alt_a[sl, k] * f, "o-", ms=3, lw=0.8, color=colors[0],
                label=cmp.label_a)  # fmt: skip
        dx.plot(cmp.t_alt[sl], cmp.alt_b[sl, k] * f, "s-", ms=3, lw=0.8, color=colors[1],
                label=cmp.label_b)  # fmt: skip
        dx.axhline(0.0, color="grey", lw=0.5)
        dx.set(
            title=f"zoom on 60 cycles where the alternation is largest: alternating part Δ⁴V/16 "
            f"of V {comp}",
            ylabel=f"Δ⁴V/16, {comp} [{unit}]",
            xlabel="time since start [s]",
        )
        dx.legend(fontsize=9, loc="best")
    dx.grid(alpha=0.3)
    fig.suptitle(title, fontsize=12)
    return _save(fig, path)


def _white_line(ax: Axes, taus: F64, var: F64 | None, period: float, scale: float) -> None:
    if var is None:
        return
    sigma = float(np.sqrt(np.mean(var)))
    ax.loglog(
        taus,
        sigma * np.sqrt(period / taus) * scale,
        color="black",
        ls="--",
        lw=1.0,
        label="white noise of the message covariance: σ√(T/τ)",
    )


def plot_allan(mi: MeasuredImu, bag_name: str, path: Path) -> Path:
    """Overlapping Allan deviation of the measured gyro (deg/h) and accelerometer (m/s²)."""
    fig = _figure(13, 5.8)
    axes = fig.subplots(1, 2)
    labels = ("x", "y", "z")
    period = mi.measured.period_s
    panels = (
        (axes[0], mi.error_gyro, mi.total_gyro, np.degrees(1.0) * 3600.0, "deg/h", "gyro",
         mi.measured.gyro_var),
        (axes[1], mi.error_accel, mi.total_accel, 1.0, "m/s²", "accelerometer",
         mi.measured.accel_var),
    )  # fmt: skip
    for ax, err, total, scale, unit, what, var in panels:
        ref: AllanResult | None = err if err is not None else total
        for k in range(3):
            if err is not None:
                ax.loglog(err.taus, err.adev[:, k] * scale, "-", color=AXIS_COLORS[k], lw=1.4)
            if total is not None:
                ax.loglog(total.taus, total.adev[:, k] * scale, ":", color=AXIS_COLORS[k], lw=1.0)
        # legend: colours are the axes, line styles the signals
        for k in range(3):
            ax.plot([], [], "-", color=AXIS_COLORS[k], lw=3, label=f"{labels[k]} axis")
        if err is not None:
            ax.plot([], [], "-", color="grey", lw=1.4, label="measured − ideal (sensor error)")
        if total is not None:
            ax.plot([], [], ":", color="grey", lw=1.0, label="measured (motion included)")
        if ref is not None:
            _white_line(ax, ref.taus, var, period, scale)
        ax.set(
            xlabel="averaging time τ [s]",
            ylabel=f"Allan deviation [{unit}]",
            title=f"{what} ({mi.measured.topic}, FLU axes)",
        )
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="best")
    note = "" if mi.ideal is not None else " (no ideal twin topic: motion included)"
    fig.suptitle(f"{bag_name}: overlapping Allan deviation of measured increments{note}",
                 fontsize=12)  # fmt: skip
    return _save(fig, path)


def imu_list(bag: BagData) -> list[ImuData]:
    """The IMU topics :func:`plot_imu` draws: each ideal IMU followed by its measured twin,
    measured IMUs without a twin, then Imu topics of other names (another tool's bag)."""
    out: list[ImuData] = []
    for p, d in bag.imus.items():
        if is_regenerated(p) or is_navigator(p):
            continue
        out.append(d)
        if p in bag.measured:
            out.append(bag.measured[p].measured)
    out += [m.measured for p, m in bag.measured.items() if p not in bag.imus]
    return out + list(bag.other_imus.values())
