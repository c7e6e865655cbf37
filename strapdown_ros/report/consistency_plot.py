"""A Monte Carlo campaign's consistency figure: run-average NEES and NIS against their bounds.

One panel per group (NEES of position, velocity, attitude; NIS of each sensor): the average
over N runs of each statistic per epoch (``ε̄ = (1/N) Σ εᵢ``) and the two-sided 95 % interval
of a consistent filter, ``[χ²_{Nd}(0.025), χ²_{Nd}(0.975)] / N`` (Bar-Shalom et al. 2001
§5.4, eqs. (5.4.2-4), (5.4.2-6); :func:`~strapdown_ros.core.aided.consistency.average_interval`).
Matplotlib on the Agg canvas, no pyplot state.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from strapdown_ros.core.aided.consistency import average_interval

__all__ = ["AverageSeries", "plot_consistency"]


@dataclass(frozen=True)
class AverageSeries:
    """The run average of one statistic: ``t_s`` (K,) s since the start, ``mean`` (K,), its
    degrees of freedom and the number of runs averaged."""

    t_s: np.ndarray
    mean: np.ndarray
    dof: int
    runs: int


def _broken_at_gaps(t: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``t, v`` with a NaN after each interval longer than 3 median intervals (an outage is
    not drawn as a line across it)."""
    if len(t) < 3:
        return t, v
    dt = np.diff(t)
    cut = np.flatnonzero(dt > 3.0 * np.median(dt)) + 1
    return np.insert(t.astype(float), cut, np.nan), np.insert(v.astype(float), cut, np.nan)


def plot_consistency(
    panels: Mapping[str, Mapping[str, AverageSeries]], path: Path, title: str,
    convergence_s: float = 0.0,
) -> Path:
    """Draw one panel per entry of ``panels`` (panel title → label → series) into ``path``.

    The bounds of each degree of freedom are drawn once per panel (black, one line style per
    d); the epochs before ``convergence_s`` (left out of the statistics) are shaded.
    """
    fig = Figure(figsize=(9.0, 2.6 * len(panels)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    for ax, (name, series) in zip(axes, panels.items(), strict=True):
        for i, (label, s) in enumerate(series.items()):
            t, m = _broken_at_gaps(s.t_s, s.mean)
            ax.plot(t, m, color=f"C{i}", lw=0.7, label=f"{label} (d = {s.dof})")
        for j, (dof, runs) in enumerate(sorted({(s.dof, s.runs) for s in series.values()})):
            lo, hi = average_interval(dof, runs)
            style = ("--", ":", "-.")[j % 3]
            ax.axhline(lo, color="k", lw=0.8, ls=style, label=f"95 % bounds, d = {dof}")
            ax.axhline(hi, color="k", lw=0.8, ls=style)
        if convergence_s > 0:
            ax.axvspan(0.0, convergence_s, color="0.9", lw=0, zorder=0)
        ax.set_title(name, fontsize=9, loc="left")
        ax.set_ylabel("run average")
        ax.legend(fontsize=7, loc="upper right", ncols=3)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time since start (s)")
    fig.suptitle(title, fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
