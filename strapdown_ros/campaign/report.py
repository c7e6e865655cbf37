"""The campaign report: ensemble plots and ``campaign.md`` with the statistics table.

The bands are empirical quantiles over the runs at each output stamp: the median, the central
68 % (16th–84th percentile) and 95 % (2.5th–97.5th percentile) of each error magnitude.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from strapdown_ros.campaign.results import finished_runs, read_run_errors

__all__ = ["STAT_FIGURES", "ensemble", "write_campaign_report"]

#: Summary figures of the statistics table: key -> (label, unit, scale).
STAT_FIGURES = {
    "final_horizontal_m": ("final horizontal position error", "m", 1.0),
    "max_horizontal_m": ("max horizontal position error", "m", 1.0),
    "final_vertical_m": ("final vertical position error", "m", 1.0),
    "final_velocity_mps": ("final velocity error", "m/s", 1.0),
    "final_attitude_rad": ("final attitude error", "mrad", 1e3),
}

#: Error magnitudes plotted over time: name -> (columns of the error array, unit, scale).
MAGNITUDES = {
    "horizontal position": ((0, 1), "m", 1.0),
    "vertical position": ((2,), "m", 1.0),
    "velocity": ((3, 4, 5), "m/s", 1.0),
    "attitude": ((6, 7, 8), "mrad", 1e3),
}


def ensemble(out: Path, runs: int) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Common output stamps and each finished run's errors on them (runs that end early are
    cut to the common length)."""
    series = {k: read_run_errors(out, k) for k in sorted(finished_runs(out)) if k < runs}
    if not series:
        return np.zeros(0, dtype=np.int64), {}
    n = min(len(s) for s, _ in series.values())
    stamps = next(iter(series.values()))[0][:n]
    return stamps, {k: e[:n] for k, (_, e) in series.items()}


def _magnitude(errors: np.ndarray, cols: tuple[int, ...]) -> np.ndarray:
    return np.sqrt(np.sum(errors[:, list(cols)] ** 2, axis=1))


def _plot(stamps: np.ndarray, runs: dict[int, np.ndarray], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = (stamps - stamps[0]) * 1e-9
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, constrained_layout=True)
    for ax, (name, (cols, unit, scale)) in zip(axes.flat, MAGNITUDES.items(), strict=True):
        mags = np.array([_magnitude(e, cols) for e in runs.values()]) * scale
        lo95, lo68, med, hi68, hi95 = np.percentile(mags, [2.5, 16, 50, 84, 97.5], axis=0)
        ax.fill_between(t, lo95, hi95, color="tab:blue", alpha=0.15, label="95 %")
        ax.fill_between(t, lo68, hi68, color="tab:blue", alpha=0.3, label="68 %")
        ax.plot(t, med, color="tab:blue", lw=1.5, label="median")
        for i, k in enumerate(list(runs)[:3]):
            ax.plot(t, mags[i], lw=0.6, color=f"C{i + 1}", alpha=0.8, label=f"run {k}")
        ax.set_title(f"{name} error ({len(runs)} runs)")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time since start (s)")
    axes[0, 0].legend(fontsize=8, loc="upper left")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _stats_table(summaries: list[dict[str, Any]]) -> list[str]:
    lines = [
        "| figure | mean | median | 68 % | 95 % | max |",
        "|---|---|---|---|---|---|",
    ]
    for key, (label, unit, scale) in STAT_FIGURES.items():
        v = np.array([s[key] for s in summaries]) * scale
        p68, p95 = np.percentile(v, [68, 95])
        lines.append(
            f"| {label} ({unit}) | {v.mean():.4g} | {np.median(v):.4g} | {p68:.4g} | {p95:.4g} "
            f"| {v.max():.4g} |"
        )
    return lines


def write_campaign_report(
    out: Path, runs: int, summaries: list[dict[str, Any]], failed: dict[int, str]
) -> Path:
    """Write ``out/report/campaign.md`` and ``ensemble_errors.png``; return the markdown path."""
    out = Path(out)
    report = out / "report"
    report.mkdir(parents=True, exist_ok=True)
    info = json.loads((out / "campaign.json").read_text())
    lines = [
        f"# Campaign: {info['scenario_name']}",
        "",
        f"{len(summaries)} of {runs} runs finished"
        + (f", {len(failed)} failed" if failed else "")
        + f". Scenario `{info['scenario']}`, campaign seed {info['seed']}.",
        "",
    ]
    if summaries:
        lines += ["## Statistics over the runs", "", *_stats_table(summaries), ""]
        lines += [
            "Percentiles are empirical over the runs (68 %: the 68th percentile of the figure; "
            "in the plot the central 68 % band is the 16th–84th percentile at each stamp).",
            "",
        ]
        stamps, series = ensemble(out, runs)
        if len(stamps):
            _plot(stamps, series, report / "ensemble_errors.png")
            lines += ["![ensemble errors](ensemble_errors.png)", ""]
    if failed:
        lines += ["## Failed runs", ""]
        lines += [f"- run {k:04d}: {why}" for k, why in sorted(failed.items())] + [""]
    seeded = ", ".join(f"`{k}`" for k in info["seed_keys"]) or "none"
    lines += [
        "## How it was made",
        "",
        f"- scenario file: `{info['scenario']}` (name `{info['scenario_name']}`)",
        f"- overrides for every run: {', '.join(f'`{o}`' for o in info['common']) or 'none'}",
        f"- seeded keys (a seed per run): {seeded}",
        f"- varied keys: {', '.join(f'`{v}`' for v in info['vary']) or 'none'}",
        f"- shared between runs (computed once): {info['shared']}",
        f"- campaign seed: {info['seed']}; run k's seeds and draws come from "
        "`SeedSequence(seed, spawn_key=(k, ·))` and are listed in `runs.parquet` "
        "(column `overrides`: the `--set` options that make `strapdown-sim generate` compute "
        "the same run)",
        f"- versions: {', '.join(f'{k} {v}' for k, v in info['versions'].items())}",
        "",
    ]
    path = report / "campaign.md"
    path.write_text("\n".join(lines))
    return path
