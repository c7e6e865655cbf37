"""Covariance prediction against a campaign's ensemble: table and figure.

Usage: python tools/plot_covariance_campaign.py CAMPAIGN_DIR BAG OUT_PREFIX [--every K]
       [--realized] [--skip S] [--height]

CAMPAIGN_DIR: a ``strapdown-sim campaign`` output; BAG: the campaign's scenario generated once
(``strapdown-sim generate SCENARIO --out BAG --set <the campaign's common overrides>``), from
which the truth and the ideal IMU increments are read. Writes OUT_PREFIX.md (the χ² table,
strapdown_ros.analysis.covariance_check) and OUT_PREFIX.png: per component the ensemble's runs,
the predicted mean ± 1σ and ± 3σ, and the ratio σ_ens / σ_pred with the χ²(N) 95 % band.
``--every K``: propagate with steps of K navigator periods (default 1). ``--realized``: also
the prediction started from the campaign's drawn constants (covariance_check.
realized_initial_covariance), written as OUT_PREFIX_realized.md/.png. ``--skip S``: epochs
compared from S s on (default 60). ``--height``: the down position error compared as the
linear model's −δh, the Earth's curvature under the horizontal error removed
(covariance_check.down_as_height_error, at the scenario's initial position).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from strapdown_ros.analysis import covariance_check as cc
from strapdown_ros.config import navigator_spec

UNITS, SCALE = cc.PLOT_UNITS, cc.PLOT_SCALE


def plot(series: dict, errors: np.ndarray, n: int, path: Path) -> None:
    lo, hi = cc.chi2_band(n)
    fig = Figure(figsize=(14, 12), layout="constrained")
    t = series["t"] / 60.0
    axes = fig.subplots(6, 3, sharex=True)
    for j, name in enumerate(cc.COMPONENTS):
        ax = axes[2 * (j // 3), j % 3]
        s, m = SCALE[j], series["mean_pred"][:, j] * SCALE[j]
        sd = series["sigma_pred"][:, j] * s
        for r in range(min(errors.shape[0], 30)):
            ax.plot(t, errors[r, :, j] * s, color="0.75", lw=0.4)
        ax.plot(t, m + sd, "C0", lw=1.2, label="predicted ±1σ")
        ax.plot(t, m - sd, "C0", lw=1.2)
        ax.plot(t, m + 3 * sd, "C0--", lw=1.0, label="±3σ")
        ax.plot(t, m - 3 * sd, "C0--", lw=1.0)
        ax.plot(t, series["mean_ens"][:, j] * s + series["sigma_ens"][:, j] * s, "C3", lw=1.0,
                label="ensemble ±1σ")
        ax.plot(t, series["mean_ens"][:, j] * s - series["sigma_ens"][:, j] * s, "C3", lw=1.0)
        ax.set_title(f"{name} ({UNITS[j]})", fontsize=9)
        if j == 0:
            ax.legend(fontsize=7)
        rax = axes[2 * (j // 3) + 1, j % 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            rax.plot(t, series["sigma_ens"][:, j] / series["sigma_pred"][:, j], "C3", lw=1.0)
        rax.axhspan(lo, hi, color="C0", alpha=0.15, label=f"χ²({n}) 95 %")
        rax.axhline(1.0, color="k", lw=0.5)
        rax.set_ylim(0.6, 1.4)
        rax.set_ylabel("σ_ens/σ_pred", fontsize=8)
        if j == 0:
            rax.legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (min)")
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=90)


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    every = int(argv[argv.index("--every") + 1]) if "--every" in argv else 1
    skip = float(argv[argv.index("--skip") + 1]) if "--skip" in argv else 60.0
    out, bag, prefix = Path(argv[0]), Path(argv[1]), Path(argv[2])
    scenario = cc.campaign_scenario(out)
    ensemble = cc.read_ensemble(out)
    if "--height" in argv:
        ensemble = cc.down_as_height_error(
            ensemble, np.radians(scenario.initial.latitude_deg), scenario.initial.altitude_m
        )
    n = ensemble.errors.shape[0]
    variants = [(prefix, None, "population (the error model's variances)")]
    if "--realized" in argv:
        from strapdown_ros.campaign.results import finished_runs

        nav = navigator_spec(scenario)
        assert nav is not None
        spec = scenario.imu_errors_of(nav.imu_topic)  # the navigator's model
        assert spec is not None
        index = scenario.imu_errors.index(spec)
        key = "imu_errors.seed" if len(scenario.imu_errors) == 1 else f"imu_errors.{index}.seed"
        seeds = cc.campaign_seeds(out, sorted(finished_runs(out)), key)
        cov0 = cc.realized_initial_covariance(spec.parameters(), seeds)
        variants.append((prefix.with_name(prefix.name + "_realized"), cov0,
                         "started from the campaign's drawn constants"))  # fmt: skip
    prefix.parent.mkdir(parents=True, exist_ok=True)
    for path, cov0, what in variants:
        start = time.perf_counter()
        prediction = cc.predict_scenario(scenario, bag, steps_per_output=every, cov0=cov0)
        elapsed = time.perf_counter() - start
        checks, series = cc.compare_ensemble(prediction, ensemble, skip_s=skip)
        table = cc.checks_table(checks, n)
        text = (f"prediction {what}; epochs from {skip:g} s\n\n{table}\n\nprediction: "
                f"{prediction.stamps_ns.shape[0] - 1} steps in {elapsed:.1f} s; command: "
                f"python tools/plot_covariance_campaign.py {' '.join(argv)}\n")  # fmt: skip
        path.with_suffix(".md").write_text(text, encoding="utf-8")
        _, i_pred, i_ens = np.intersect1d(prediction.stamps_ns, ensemble.stamps_ns,
                                          return_indices=True)  # fmt: skip
        plot(series, ensemble.errors[:, i_ens], n, path.with_suffix(".png"))
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
