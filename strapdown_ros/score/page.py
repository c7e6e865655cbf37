"""The score's report page: ``score.json``, ``score.md`` and its PNG plots (matplotlib, Agg
canvas, no pyplot state) in one directory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from strapdown_ros.score.scorer import Score

__all__ = ["write_page"]

DPI = 110


def _figure(rows: int) -> tuple[Figure, list[Axes]]:
    fig = Figure(figsize=(10, 2.6 * rows), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(rows, 1, i + 1) for i in range(rows)]
    return fig, axes


def _shade(ax: Axes, score: Score) -> None:
    for o in score.outages:
        ax.axvspan((o.start_ns - score.start_ns) * 1e-9, (o.end_ns - score.start_ns) * 1e-9,
                   color="0.85", zorder=0, label="GNSS outage")  # fmt: skip


def _lines(ax: Axes, t: np.ndarray, y: np.ndarray, names: tuple[str, ...], unit: str,
           title: str) -> None:  # fmt: skip
    for i, name in enumerate(names):
        ax.plot(t, y[:, i], lw=1.0, label=name)
    ax.set_ylabel(unit)
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    return path


def write_plots(score: Score, out: Path) -> dict[str, Path]:
    """The plots of a score: errors (position NED, along/cross-track, velocity, attitude) and
    NEES; outages shaded."""
    t = (score.stamps_ns - score.start_ns) * 1e-9
    plots: dict[str, Path] = {}
    rows = 2 + (score.velocity_ned is not None) + (score.attitude_young is not None)
    fig, axes = _figure(rows)
    _lines(axes[0], t, score.position_ned, ("north", "east", "down"), "m",
           "position error (estimate − truth), NED of the true position")  # fmt: skip
    _lines(axes[1], t, np.column_stack([score.along, score.cross]), ("along-track",
           "cross-track (right +)"), "m", "horizontal error along / across the true track")
    i = 2
    if score.velocity_ned is not None:
        _lines(axes[i], t, score.velocity_ned, ("north", "east", "down"), "m/s",
               "velocity error, NED")  # fmt: skip
        i += 1
    if score.attitude_young is not None:
        _lines(axes[i], t, score.attitude_young, ("θ1 up", "θ2 east", "θ3 north"), "rad",
               "attitude error, Young 1980 eq. (28) angles")  # fmt: skip
    for ax in axes:
        _shade(ax, score)
    axes[-1].set_xlabel("time since the start (s)")
    plots["errors"] = _save(fig, out / "errors.png")
    if score.nees:
        fig, axes = _figure(len(score.nees))
        for ax, (name, s) in zip(axes, score.nees.items(), strict=True):
            ax.semilogy(t, s.values, ".", ms=2, label=f"NEES {name} (dof {s.dof})")
            ax.axhline(s.dof, color="k", lw=0.8, label="expected (dof)")
            for b in s.bounds_95:
                ax.axhline(b, color="k", ls=":", lw=0.8)
            ax.set_title(f"NEES {name}: mean {s.mean:.3g}, inside 95 % bounds "
                         f"{100 * (s.inside_95 or 0):.1f} %", fontsize=10)  # fmt: skip
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            _shade(ax, score)
        axes[-1].set_xlabel("time since the start (s)")
        plots["nees"] = _save(fig, out / "nees.png")
    return plots


def _fmt(x: float | None, unit: str) -> str:
    return "—" if x is None else f"{x:.3e} {unit}"


def _markdown(score: Score, plots: dict[str, Path]) -> str:
    s = score.summary
    lines = [
        f"# Score of `{s['estimate_topic']}`",
        "",
        f"Truth: `{s['truth_topic']}` of `{s['bag']}` (scenario `{s['scenario']}`), between "
        f"samples: {s['truth_between_samples']}. Estimate: {s['samples']} messages "
        f"`{s['estimate_type']}` in `{s['estimate_frame_id']}`"
        + (f" ({s['outside_truth']} outside the truth, not scored)" if s["outside_truth"]
           else "") + ".",
        f"Point: lever arm {s['point']['lever_arm_frd_m']} m (FRD of the reference IMU), "
        f"mounting {np.round(s['point']['mounting_rph_deg'], 6).tolist()} deg, from "
        f"{s['point']['from']}. Definitions: docs/score.md.",
        "",
        "| error | RMS | max abs | final |",
        "|---|---|---|---|",
    ]
    groups = [("position", s["position_error_m"], "m"), ("velocity", s["velocity_error_mps"],
              "m/s"), ("attitude", s["attitude_error_rad"], "rad")]  # fmt: skip
    for name, group, unit in groups:
        if not group:
            continue
        for axis, st in group.items():
            lines.append(f"| {name} {axis} | {_fmt(st['rms'], unit)} | "
                         f"{_fmt(st['max_abs'], unit)} | {_fmt(st['final'], unit)} |")  # fmt: skip
    off = s["time_offset"]
    lines += ["", "Time offset (estimate stamps late by δt; v·δt least squares): "
              + ("not found (" + off.get("note", "") + ")" if off["offset_s"] is None else
                 f"δt = {off['offset_s'] * 1e3:.6f} ms ± {off['sigma_s'] * 1e3:.2e} ms "
                 f"({off['samples']} samples)"), ""]  # fmt: skip
    if s["outages"]:
        lines += ["| GNSS outage (s) | drift | max horizontal | distance | drift / distance |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for o in s["outages"]:
            a, b = (o["start_ns"] - score.start_ns) * 1e-9, (o["end_ns"] - score.start_ns) * 1e-9
            pct = "—" if o["drift_percent"] is None else f"{o['drift_percent']:.3g} %"
            lines.append(f"| {a:g} – {b:g} | {_fmt(o['drift_m'], 'm')} | "
                         f"{_fmt(o['max_horizontal_m'], 'm')} | {_fmt(o['distance_m'], 'm')} | "
                         f"{pct} |")  # fmt: skip
        lines.append("")
    if s["nees"]:
        lines += ["| NEES | dof | samples | mean | inside 95 % |", "|---|---|---|---|---|"]
        for name, n in s["nees"].items():
            lines.append(f"| {name} | {n['dof']} | {n['samples']} | {n['mean']:.3g} | "
                         f"{100 * n['inside_95']:.1f} % |")  # fmt: skip
        lines.append("")
    lines += [f"![{name}]({path.name})" for name, path in plots.items()]
    return "\n".join(lines) + "\n"


def write_page(score: Score, out: str | Path) -> dict[str, Path]:
    """Write ``score.json``, ``score.md`` and the plots into ``out``; their paths by name."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {"json": score.write_json(out / "score.json")}
    plots = write_plots(score, out)
    md = out / "score.md"
    md.write_text(_markdown(score, plots))
    return {**files, "markdown": md, **plots}
