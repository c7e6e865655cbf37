"""Error budget of the free-inertial navigator per IMU error source (linear covariance).

The linear covariance model of :mod:`strapdown_ros.core.covariance` is run once per random
source of the IMU error model, all others zeroed: per triad (gyros, accelerometers) the turn-on
bias, the Gauss–Markov bias, the rate random walk, the white noise, the random scale factors and
the random misalignments (the fields of :class:`~strapdown_ros.core.imu_errors.SensorErrors`
that carry a variance; the Gauss–Markov correlation times are kept, they are not a source). The
sources are independent and enter linearly, so their variances add up to the all-sources run's,
which is run too as the check. The fixed terms (fixed bias, scale factor, misalignment, the
gyros' g-sensitivity) carry no variance in the model: they move the mean only, and are listed
apart with the mean they produce alone.

Quantities at the end of the run, from the navigation errors (δr, δv, φ NED): horizontal
position √(σ_N² + σ_E²) (m), vertical position σ_D (m), horizontal and vertical velocity (m/s),
tilt √(σ_φN² + σ_φE²) and heading σ_φD (mrad).

Command line: ``python -m strapdown_ros.analysis.error_budget SCENARIO [--imu-topic T]
[--duration S] [--set KEY=VALUE] [--every K] [--bag BAG]`` (``--help``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from strapdown_ros.analysis.covariance_check import ScenarioModel
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.covariance import CovarianceResult, propagate_covariance
from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors

__all__ = [
    "FIXED_SOURCES",
    "QUANTITIES",
    "RANDOM_SOURCES",
    "Budget",
    "budget_table",
    "error_budget",
    "final_quantities",
    "source_alone",
]

#: Random sources: (label, the SensorErrors field that carries its size).
RANDOM_SOURCES = (("turn-on bias", "turn_on_bias_sigma"), ("Gauss–Markov", "bias_instability"),
                  ("rate random walk", "random_walk"), ("white noise", "white"),
                  ("scale factor", "scale_factor_sigma"),
                  ("misalignment", "misalignment_sigma"))  # fmt: skip
#: Fixed terms (mean only): (label, field).
FIXED_SOURCES = (("fixed bias", "bias"), ("fixed scale factor", "scale_factor"),
                 ("fixed misalignment", "misalignment"),
                 ("g-sensitivity", "g_sensitivity"))  # fmt: skip
#: The budget's quantities (column titles, with units).
QUANTITIES = ("horiz. pos (m)", "vert. pos (m)", "horiz. vel (m/s)", "vert. vel (m/s)",
              "tilt (mrad)", "heading (mrad)")  # fmt: skip
_GROUPS = ((0, 1), (2,), (3, 4), (5,), (6, 7), (8,))
_SCALE = np.array([1.0, 1.0, 1.0, 1.0, 1e3, 1e3])


def source_alone(params: ImuErrorParameters, triad: str, field: str) -> ImuErrorParameters:
    """``params`` with every error zeroed but ``field`` of ``triad`` ("gyro" or "accel").

    The Gauss–Markov correlation times of both triads are kept.
    """
    out = {}
    for name in ("gyro", "accel"):
        own: SensorErrors = getattr(params, name)
        kept = {"correlation_time_s": own.correlation_time_s}
        if name == triad:
            kept[field] = getattr(own, field)
        out[name] = replace(SensorErrors.zero(), **kept)
    return ImuErrorParameters(out["gyro"], out["accel"], params.seed)


def final_quantities(result: CovarianceResult) -> tuple[F64, F64]:
    """(variance, mean) (6,) of :data:`QUANTITIES` at the end, in their units (squared for the
    variance); the mean of a two-axis quantity is the norm of its mean vector."""
    mean, sigma = result.navigation_moments()
    var = np.array([np.sum(sigma[-1, list(g)] ** 2) for g in _GROUPS]) * _SCALE**2
    m = np.array([np.linalg.norm(mean[-1, list(g)]) for g in _GROUPS]) * _SCALE
    return var, m


@dataclass(frozen=True)
class Budget:
    """Final variances (6,) of each random source alone (``random``: label → variances), the
    sum of them (``total_sum``) and the all-sources run's (``total``); the mean of each fixed
    term alone (``fixed``) and the all-sources run's (``mean_total``); the run's length ``t_s``
    (s) and its number of steps; the sources that are zero in the model (``zero``)."""

    random: dict[str, F64]
    total_sum: F64
    total: F64
    fixed: dict[str, F64]
    mean_total: F64
    t_s: float
    steps: int
    zero: tuple[str, ...]


def error_budget(model: ScenarioModel) -> Budget:
    """Run the covariance model per source (module docstring) along ``model``'s steps."""
    params = model.params

    def run(p: ImuErrorParameters) -> tuple[F64, F64]:
        return final_quantities(propagate_covariance(
            model.steps, p, gravity_model=model.gravity_model, damping=model.damping))

    random: dict[str, F64] = {}
    fixed: dict[str, F64] = {}
    zero: list[str] = []
    for triad in ("gyro", "accel"):
        for sources, out, use in ((RANDOM_SOURCES, random, 0), (FIXED_SOURCES, fixed, 1)):
            for label, field in sources:
                name = f"{triad} {label}"
                if not np.any(getattr(getattr(params, triad), field)):
                    zero.append(name)
                    continue
                out[name] = run(source_alone(params, triad, field))[use]
    total, mean_total = run(params)
    total_sum = np.sum(list(random.values()), axis=0) if random else np.zeros(len(QUANTITIES))
    return Budget(random, total_sum, total, fixed, mean_total,
                  float(model.steps.t[-1]), model.steps.t.shape[0] - 1, tuple(zero))  # fmt: skip


def _row(label: str, values: F64) -> str:
    return f"| {label} | " + " | ".join(f"{v:.4g}" for v in values) + " |"


def budget_table(budget: Budget) -> str:
    """The budget as Markdown: final σ per source with its share of the total variance, the
    sum of the variances beside the all-sources run, the fixed terms' means."""
    head = "| source | " + " | ".join(QUANTITIES) + " |"
    rule = "|---" * (len(QUANTITIES) + 1) + "|"
    total = np.where(budget.total > 0, budget.total, np.nan)
    lines = [f"final σ at t = {budget.t_s:g} s ({budget.steps} steps), each random source "
             "alone; in brackets its share of the all-sources variance", "", head,
             rule]  # fmt: skip
    for label, var in sorted(budget.random.items(), key=lambda kv: -np.nansum(kv[1] / total)):
        cells = [f"{np.sqrt(v):.4g}" + (f" ({100 * v / t:.1f} %)" if np.isfinite(t) else "")
                 for v, t in zip(var, total, strict=True)]  # fmt: skip
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines.append(_row("√(Σ variances)", np.sqrt(budget.total_sum)))
    lines.append(_row("all sources, one run", np.sqrt(budget.total)))
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(budget.total_sum - budget.total) / budget.total
    lines.append("| Σ/all − 1 (variance) | " + " | ".join(f"{r:.1e}" for r in rel) + " |")
    if budget.fixed:
        lines += ["", "fixed terms (no variance in the model): |mean| at the end, each alone", "",
                  head, rule]  # fmt: skip
        lines += [_row(label, m) for label, m in budget.fixed.items()]
        lines.append(_row("all sources, one run", budget.mean_total))
    if budget.zero:
        lines += ["", "zero in this IMU's model (not run): " + ", ".join(budget.zero)]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: generate the scenario's truth and ideal IMU (or read ``--bag``), print the
    budget of its navigator."""
    import argparse
    import tempfile
    import time

    from strapdown_ros.analysis.covariance_check import scenario_model
    from strapdown_ros.config import load_scenario
    from strapdown_ros.config.scenario import navigator_spec
    from strapdown_ros.generate import generate_dataset

    ap = argparse.ArgumentParser(prog="python -m strapdown_ros.analysis.error_budget",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--imu-topic", default=None,
                    help="the navigator's (measured) IMU topic (sets navigator.imu_topic)")
    ap.add_argument("--duration", type=float, default=None, metavar="S", help="override duration_s")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--every", type=int, default=1, metavar="K",
                    help="propagation step in navigator periods (default 1)")
    ap.add_argument("--bag", type=Path, default=None,
                    help="the scenario generated already (same overrides); default: generated "
                         "into a temporary directory (truth and ideal IMU only)")  # fmt: skip
    args = ap.parse_args(argv)
    overrides = list(args.overrides)
    if args.imu_topic is not None:
        overrides.append(f"navigator.imu_topic={args.imu_topic}")
    scenario = load_scenario(args.scenario, overrides, args.duration)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        bag = args.bag
        if bag is None:
            nav = navigator_spec(scenario)
            spec = None if nav is None else scenario.imu_errors_of(nav.imu_topic)
            if nav is None or spec is None:
                raise SystemExit("error_budget: the scenario needs a navigator on a measured IMU")
            ideal, _ = spec.topics(scenario.recording.topics)
            topics = f"[{ideal}, {nav.truth_topic}]"
            bag = Path(tmp) / "bag"
            generate_dataset(load_scenario(args.scenario, [*overrides,
                             f"recording.include={topics}"], args.duration), bag)  # fmt: skip
        generated = time.perf_counter() - start
        model = scenario_model(scenario, bag, args.every)
    budget = error_budget(model)
    took = time.perf_counter() - start - generated
    nav = navigator_spec(scenario)
    assert nav is not None
    print(f"{args.scenario.name}: navigator on {nav.imu_topic} ({nav.mode} mode, damping "
          f"{model.damping}), {scenario.duration_s:g} s; bag {generated:.1f} s, budget "
          f"{took:.1f} s")  # fmt: skip
    print(budget_table(budget))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
