"""The aided filter's own covariance against a Monte Carlo ensemble of its errors.

A loosely coupled error-state Kalman filter carries its linear covariance P along its nominal
state (docs/aided.md); with the nominal state within its errors of the truth, that P is the
linearized prediction of its error's spread, and it changes between runs only through what the
runs measure (gate rejections, the nominal state). So the comparison is the free-inertial one of
:mod:`strapdown_ros.analysis.covariance_check` with σ_pred the filter's published σ (the RMS over
the runs of each run's σ, its spread over the runs reported beside it) and the predicted mean
zero (a consistent filter is unbiased).

Per run (bags written by :func:`~strapdown_ros.stages.aided_montecarlo.monte_carlo` with
``keep=True`` and read back): the errors of
:func:`~strapdown_ros.stages.aided_montecarlo.bag_result` (position and velocity NED at the true
position, attitude error rotation vector φ in NED) and the σ of the same components from the
published covariances (``/aided/odom`` pose covariance, ECEF, rotated to NED; ``/aided/vel``
covariance, ENU). Components in :data:`~strapdown_ros.analysis.covariance_check.COMPONENTS`'
order and units, the attitude as Young's angles to first order: ``θ = (-φ_D, φ_E, φ_N)``.

Command line: ``python -m strapdown_ros.analysis.aided_check SCENARIO --runs N ...`` (``--help``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from strapdown_ros.analysis import covariance_check as cc
from strapdown_ros.config import Scenario
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic

__all__ = ["AidedRun", "aided_prediction", "plot_checks", "read_aided_run"]

_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class AidedRun:
    """One run at its output epochs: ``stamps`` (K,) ns, ``errors`` and ``sigma`` (K, 9)."""

    stamps: np.ndarray
    errors: F64
    sigma: F64


def _young_order(ned: F64, sign: float = -1.0) -> F64:
    """(δr, δv, φ) NED → :data:`~strapdown_ros.analysis.covariance_check.COMPONENTS`' order,
    θ = (sign·φ_D, φ_E, φ_N): ``sign`` −1 for errors, +1 for variances."""
    out = ned.copy()
    out[:, 6], out[:, 7], out[:, 8] = sign * ned[:, 8], ned[:, 7], ned[:, 6]
    return out


def read_aided_run(bag: str | Path, scenario: Scenario) -> AidedRun:
    """Errors and the filter's σ of one run's bag (module docstring)."""
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.messages import odometry_state
    from strapdown_ros.stages.aided import aided_output_topics
    from strapdown_ros.stages.aided_montecarlo import bag_result

    result = bag_result(Path(bag), scenario)
    topics = aided_output_topics(scenario)
    truth_topic = scenario.aided.truth_topic  # type: ignore[union-attr]
    contents = read_bag(bag, [topics["odom"], topics["vel"], truth_topic])
    odom, vel, truth = contents[topics["odom"]], contents[topics["vel"]], contents[truth_topic]
    ie = np.searchsorted(np.asarray(odom.stamps_ns), result.stamps)
    it = np.searchsorted(np.asarray(truth.stamps_ns), result.stamps)
    iv = np.searchsorted(np.asarray(vel.stamps_ns), result.stamps)
    r_true = odometry_state(truth).r_e[it]
    lat, lon, _ = ecef_to_geodetic(r_true)
    cen = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
    cne = np.swapaxes(cen, -1, -2)
    pose = np.asarray(odom.pose_covariance)[ie].reshape(-1, 6, 6)
    p_pos = cen @ pose[:, :3, :3] @ cne
    p_att = cen @ pose[:, 3:, 3:] @ cne
    p_vel = _ENU @ np.asarray(vel.covariance)[iv].reshape(-1, 6, 6)[:, :3, :3] @ _ENU
    var = np.concatenate([np.einsum("kii->ki", p) for p in (p_pos, p_vel, p_att)], axis=1)
    err = np.concatenate([result.error_position, result.error_velocity, result.error_attitude],
                         axis=1)  # fmt: skip
    return AidedRun(result.stamps, _young_order(err), np.sqrt(_young_order(var, 1.0)))


def aided_prediction(runs: Sequence[AidedRun], params: object) -> tuple[cc.Prediction, F64]:
    """The prediction (zero mean, σ the RMS over the runs of the filter's σ) at the epochs
    common to all runs, and the spread (max/min − 1, (K, 9)) of the runs' σ about it."""
    k = min(r.stamps.shape[0] for r in runs)
    stamps = runs[0].stamps[:k]
    for r in runs:
        if not np.array_equal(r.stamps[:k], stamps):
            raise ValueError("the runs have different output epochs")
    sig = np.stack([r.sigma[:k] for r in runs])
    sigma = np.sqrt(np.mean(sig**2, axis=0))
    spread = sig.max(axis=0) / sig.min(axis=0) - 1.0
    return cc.Prediction(stamps, np.zeros_like(sigma), sigma, params), spread  # type: ignore[arg-type]


def plot_checks(series: dict[str, F64], n: int, path: Path, skip_s: float, title: str) -> Path:
    """PNG of :func:`~strapdown_ros.analysis.covariance_check.compare_ensemble`'s ``series``:
    per component σ_pred with its χ²(N) 95 % band and σ_ens (log axis), below it the ratio
    σ_ens / σ_pred with the band; epochs before ``skip_s`` (s) shaded. Agg canvas, no pyplot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    lo, hi = cc.chi2_band(n)
    t = series["t"] / 60.0
    fig = Figure(figsize=(12, 10), layout="constrained")
    fig.suptitle(title, fontsize=10)
    axes = fig.subplots(6, 3, sharex=True)
    for j, name in enumerate(cc.COMPONENTS):
        ax, rax = axes[2 * (j // 3), j % 3], axes[2 * (j // 3) + 1, j % 3]
        scale = cc.PLOT_SCALE[j]
        pred, ens = series["sigma_pred"][:, j] * scale, series["sigma_ens"][:, j] * scale
        ax.fill_between(t, pred * lo, pred * hi, color="C0", alpha=0.2, lw=0,
                        label=f"χ²({n}) 95 %")  # fmt: skip
        ax.plot(t, pred, "C0", lw=1.0, label="σ_pred (filter)")
        ax.plot(t, ens, "C3", lw=0.6, label=f"σ_ens ({n} runs)")
        ax.set_yscale("log")
        ax.set_title(f"{name} ({cc.PLOT_UNITS[j]})", fontsize=9)
        with np.errstate(invalid="ignore", divide="ignore"):
            rax.plot(t, ens / pred, "C3", lw=0.6)
        rax.axhspan(lo, hi, color="C0", alpha=0.2)
        rax.axhline(1.0, color="k", lw=0.5)
        rax.set_ylim(0.5, 1.5)
        rax.set_ylabel("σ_ens/σ_pred", fontsize=8)
        for a in (ax, rax):
            a.axvspan(t[0], skip_s / 60.0, color="0.85", lw=0)
            a.tick_params(labelsize=7)
        if j == 0:
            ax.legend(fontsize=7)
    for a in axes[-1]:
        a.set_xlabel("time (min)")
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run (or reuse) the runs' bags, print the χ² table."""
    import argparse
    import time

    from strapdown_ros.config.scenario import apply_overrides, parse_scenario
    from strapdown_ros.stages.aided import aided_imu_errors
    from strapdown_ros.stages.aided_montecarlo import campaign_document, monte_carlo

    ap = argparse.ArgumentParser(prog="python -m strapdown_ros.analysis.aided_check",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--duration", type=float, default=None, help="duration_s of every run")
    ap.add_argument("--modelled-only", action="store_true",
                    help="strip the error terms the filter does not model")  # fmt: skip
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--skip", type=float, default=60.0, help="epochs compared from S s on")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--plot", type=Path, default=None, metavar="PNG",
                    help="also draw σ_ens against σ_pred with the χ²(N) band into PNG")  # fmt: skip
    ap.add_argument("--dir", type=Path, required=True,
                    help="the runs' bags (kept; runs already there are read, not rerun)")
    ap.add_argument("--also", type=Path, action="append", default=[], metavar="DIR",
                    help="more runs' bags (--runs of them, read only: another --seed's runs of "
                         "the same scenario) pooled with --dir's")  # fmt: skip
    args = ap.parse_args(argv)
    doc, overrides = campaign_document(args.scenario, args.modelled_only, args.overrides,
                                       args.duration)  # fmt: skip
    scenario = parse_scenario(apply_overrides(doc, overrides))
    start = time.perf_counter()
    if not all((args.dir / f"run_{k:03d}").is_dir() for k in range(args.runs)):
        monte_carlo(doc, args.runs, args.dir, args.seed, overrides, args.workers, keep=True)
    took = time.perf_counter() - start
    runs = [read_aided_run(d / f"run_{k:03d}", scenario)
            for d in [args.dir, *args.also] for k in range(args.runs)]  # fmt: skip
    n = len(runs)
    prediction, spread = aided_prediction(runs, aided_imu_errors(scenario).parameters())
    k = prediction.stamps_ns.shape[0]
    ensemble = cc.Ensemble(prediction.stamps_ns, np.stack([r.errors[:k] for r in runs]))
    checks, series = cc.compare_ensemble(prediction, ensemble, skip_s=args.skip)
    what = (f"{args.scenario.name}: {n} runs of {scenario.duration_s:g} s"
            f"{' (modelled terms only)' if args.modelled_only else ''}")  # fmt: skip
    print(f"{what}, runs {took:.0f} s; epochs from {args.skip:g} s; "
          f"σ_pred = the filter's σ (RMS over the runs)")  # fmt: skip
    print(cc.checks_table(checks, n))
    late = (prediction.stamps_ns - prediction.stamps_ns[0]) * 1e-9 >= args.skip
    worst = ", ".join(f"{n} {100 * s:.1f} %" for n, s in
                      zip(cc.COMPONENTS, spread[late].max(axis=0), strict=True))  # fmt: skip
    print(f"\nspread of the runs' own σ (max/min − 1) over the epochs compared: {worst}")
    if args.plot is not None:
        plot_checks(series, n, args.plot, args.skip, f"aided filter: {what}")
        print(f"figure: {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
