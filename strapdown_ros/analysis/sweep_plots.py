"""Figures of an orientation sweep (``sweep.json`` and ``series/*.npz`` of
:func:`~strapdown_ros.analysis.orientation_sweep.sweep_orientation`), matplotlib Agg canvas.

* ``summary.png``: max over the span of |θ_pred - θ_actual| against the initial azimuth error,
  eq. (51) and the linear (phi-angle) model, one line per tilt, log scale;
* ``series_<case>.png``: the change of each angle from its initial value, navigator, eq. (51)
  and linear, and |θ_pred - θ_actual| (log scale).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from strapdown_ros.core.young_nonlinear import wrap_angle

__all__ = ["plot_case", "plot_summary", "plot_sweep"]

_LABELS = ("θ1 (up)", "θ2 (east)", "θ3 (north)")


def _save(fig: Figure, path: Path) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)
    return path


def plot_summary(table: dict[str, Any], path: Path) -> Path:
    """Max error of eq. (51) and of the linear model against the initial azimuth error."""
    fig = Figure(figsize=(7.5, 4.5), layout="constrained")
    ax = fig.add_subplot()
    tilts = sorted({row["tilt_deg"] for row in table["cases"]})
    for k, tilt in enumerate(tilts):
        rows = sorted((r for r in table["cases"] if r["tilt_deg"] == tilt),
                      key=lambda r: r["azimuth_deg"])  # fmt: skip
        az = [r["azimuth_deg"] for r in rows]
        color = f"C{k}"
        ax.semilogy(az, [r["nonlinear"]["max_norm"] for r in rows], "o-", color=color,
                    label=f"eq. (51), tilt {tilt:g}°")  # fmt: skip
        ax.semilogy(az, [r["linear"]["max_norm"] for r in rows], "s--", color=color,
                    label=f"linear, tilt {tilt:g}°")  # fmt: skip
    ax.set_xlabel("initial azimuth error (deg)")
    ax.set_ylabel("max |θ_pred − θ_navigator| (rad)")
    ax.set_title(f"{Path(table['scenario']).name}, {table['setup']} navigator")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return _save(fig, path)


def plot_case(series: dict[str, np.ndarray], title: str, path: Path) -> Path:
    """The three angles' changes and the prediction errors of one case."""
    t = series["t"] / 60.0
    act = series["actual"]
    fig = Figure(figsize=(8, 9), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    for i in range(3):
        ax = axes[i]
        for key, style, label in (("actual", "-", "navigator"), ("nonlinear", "--", "eq. (51)"),
                                  ("linear", ":", "linear (phi-angle)")):  # fmt: skip
            ax.plot(t, np.degrees(wrap_angle(series[key][:, i] - act[0, i])), style, label=label)
        ax.set_ylabel(f"Δ{_LABELS[i]} (deg)")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    ax = axes[3]
    for key, label in (("nonlinear", "eq. (51)"), ("linear", "linear")):
        err = np.linalg.norm(wrap_angle(series[key] - act), axis=1)
        ax.semilogy(t, np.maximum(err, 1e-16), label=label)
    ax.set_ylabel("|θ_pred − θ_nav| (rad)")
    ax.set_xlabel("time (min)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(title)
    return _save(fig, path)


def plot_sweep(out: str | Path, cases: list[str] | None = None) -> list[Path]:
    """All figures of the sweep in directory ``out`` (``cases``: only these case series)."""
    out = Path(out)
    table = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    paths = [plot_summary(table, out / "summary.png")]
    for row in table["cases"]:
        if cases is not None and row["name"] not in cases:
            continue
        with np.load(out / "series" / f"{row['name']}.npz") as data:
            series = {k: data[k] for k in data.files}
        th0 = ", ".join(f"{x:.1f}" for x in row["theta0_deg"])
        title = f"{Path(table['scenario']).name}: {row['name']} (θ0 = {th0} deg)"
        paths.append(plot_case(series, title, out / f"series_{row['name']}.png"))
    return paths
