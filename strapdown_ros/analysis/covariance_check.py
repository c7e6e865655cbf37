"""Linear covariance prediction against a Monte Carlo campaign's ensemble.

:func:`predict_scenario` propagates the error-state covariance of
:mod:`strapdown_ros.core.covariance` along the truth of a scenario's navigator: the truth
Odometry and the *ideal* IMU increments of the navigator's input are read back from a bag written
by ``generate_dataset`` (the IMU error model's input topic), the error parameters come from the
scenario's ``imu_errors`` section, the damping and gravity model from its ``navigator`` section.
:func:`read_ensemble` reads a ``strapdown-sim campaign`` directory; :func:`compare_ensemble`
computes, per error component, the ensemble σ about the predicted mean (N degrees of freedom),
the χ²(N) 95 % band ``σ_pred √(χ²_{0.025, N}/N) … σ_pred √(χ²_{0.975, N}/N)``, the fraction of
epochs inside it after ``skip_s`` and the time-averaged ratio σ_ens / σ_pred.

:func:`realized_initial_covariance` conditions the prediction on a campaign's draws: N runs
draw N sets of per-run constants (turn-on biases, scale factors, misalignments, the initial
Gauss–Markov biases), whose sample second moment differs from the population variance by about
1/√(2N) (7 % in σ for N = 100); where one constant dominates a component at every epoch (the
vertical accelerometer's turn-on bias for δr_D and δv_D), the ensemble's σ carries that one
sampling error at every epoch, and no time average removes it. The same linear model started
from the drawn constants' sample moments predicts the ensemble of *these* runs; what is left is
the sampling of the noise processes (white, Gauss–Markov, random walk), which decorrelates
over time.

Components, as the navigator's error topics (docs/interface.md §4): position NED (m), velocity
NED (m/s), Young's angles (up, east, north) (rad), which are φ in (up, east, north) to first
order: ``θ = (-φ_D, φ_E, φ_N)``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from strapdown_ros.analysis.navigator_record import local_level_states
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.config import Scenario, load_scenario
from strapdown_ros.config.scenario import navigator_spec
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.covariance import (
    N_STATES,
    STATE_NAMES,
    PropagationSteps,
    VerticalDampingGains,
    initial_moments,
    propagate_covariance,
)
from strapdown_ros.core.earth import radii
from strapdown_ros.core.imu_errors import ImuErrorParameters
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm
from strapdown_ros.messages import imu_increments

__all__ = [
    "COMPONENTS",
    "PLOT_SCALE",
    "PLOT_UNITS",
    "ComponentCheck",
    "Ensemble",
    "Prediction",
    "ScenarioModel",
    "campaign_scenario",
    "compare_ensemble",
    "down_as_height_error",
    "predict_scenario",
    "campaign_seeds",
    "read_ensemble",
    "realized_initial_covariance",
    "scenario_model",
    "steps_from_bag",
]


_PAIRS = ("xy", "xz", "yx", "yz", "zx", "zy")
_OFF_DIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))

#: The 9 error components, as the campaign's ``errors.parquet`` columns.
COMPONENTS = ("pos_n_m", "pos_e_m", "pos_d_m", "vel_n_mps", "vel_e_mps", "vel_d_mps",
              "att_1_rad", "att_2_rad", "att_3_rad")  # fmt: skip
#: Units and scale of each component in figures (attitude in mrad).
PLOT_UNITS = ("m", "m", "m", "m/s", "m/s", "m/s", "mrad", "mrad", "mrad")
PLOT_SCALE = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1e3, 1e3, 1e3)


def steps_from_bag(
    bag: str | Path, imu_topic: str, truth_topic: str, cycles_per_step: int
) -> tuple[int, PropagationSteps]:
    """``(start_ns, steps)``: propagation steps of ``cycles_per_step`` IMU cycles along the truth.

    The truth Odometry (every IMU cycle) and the ideal increments ``imu_topic`` are read from
    ``bag``; the run starts at the first truth stamp that precedes an IMU cycle (as the
    navigator does), the attitude in the middle of a cycle is the geodesic midpoint of the
    truth at its ends. A trailing part step is dropped.
    """
    contents = read_bag(bag, [imu_topic, truth_topic])
    inc = imu_increments(contents[imu_topic])  # type: ignore[arg-type]
    odom = contents[truth_topic]
    t0 = int(np.asarray(odom.stamps_ns)[0])  # type: ignore[attr-defined]
    truth = local_level_states(odom, t0)
    period = int(inc.period_ns)
    imu_stamps = np.asarray(inc.stamps_ns, dtype=np.int64)
    start = int(imu_stamps[0]) - period
    i0 = int(np.searchsorted(truth.stamps_ns, start))
    if i0 >= truth.stamps_ns.shape[0] or truth.stamps_ns[i0] != start:
        raise ValueError(f"{bag}: no {truth_topic} message at the first IMU cycle's start")
    m = min(imu_stamps.shape[0], truth.stamps_ns.shape[0] - 1 - i0)
    m -= m % cycles_per_step
    if m < cycles_per_step:
        raise ValueError(f"{bag}: fewer than {cycles_per_step} IMU cycles")
    rows = np.arange(i0, i0 + m + 1)
    if not np.array_equal(truth.stamps_ns[rows[1:]], imu_stamps[:m]):
        raise ValueError(f"{bag}: {truth_topic} is not at every {imu_topic} cycle")
    c = truth.c_b_n[rows]
    half = 0.5 * rotvec_from_dcm(np.swapaxes(c[:-1], -1, -2) @ c[1:])
    c_mid = c[:-1] @ dcm_from_rotvec(half)
    steps = PropagationSteps.from_cycles(
        truth.t[rows] - truth.t[i0], cycles_per_step, truth.lat[rows], truth.alt[rows],
        truth.v_ned[rows], c_mid, inc.dalpha[:m], inc.dv[:m], period * 1e-9,
    )  # fmt: skip
    return start, steps


@dataclass(frozen=True)
class Prediction:
    """Predicted mean and σ (K, 9) of :data:`COMPONENTS` at ``stamps_ns`` (K,)."""

    stamps_ns: NDArray[np.int64]
    mean: F64
    sigma: F64
    params: ImuErrorParameters


def _to_components(nav: F64, sign: float = -1.0) -> F64:
    """(δr, δv, φ) NED → the error topics' order: θ = (-φ_D, φ_E, φ_N) (``sign`` of φ_D:
    -1 for means, +1 for standard deviations)."""
    out = nav.copy()
    out[:, 6], out[:, 7], out[:, 8] = sign * nav[:, 8], nav[:, 7], nav[:, 6]
    return out


@dataclass(frozen=True)
class ScenarioModel:
    """What the covariance model needs of a scenario's navigator: the first step's stamp
    ``start_ns``, the propagation ``steps``, the navigator IMU's error ``params``, its gravity
    model and vertical damping (None: undamped)."""

    start_ns: int
    steps: PropagationSteps
    params: ImuErrorParameters
    gravity_model: str
    damping: VerticalDampingGains | None


def scenario_model(scenario: Scenario, bag: str | Path, steps_per_output: int = 1) -> ScenarioModel:
    """The scenario's navigator as the covariance model carries it (:func:`predict_scenario`).

    Refuses what the model does not carry: no navigator or no ``imu_errors`` on its input,
    non-zero initial errors, Table 1's unstable damping signs.
    """
    nav = navigator_spec(scenario)
    if nav is None or not scenario.imu_errors:
        raise ValueError("the scenario needs a navigator and an imu_errors section")
    spec = scenario.imu_errors_of(nav.imu_topic)
    if spec is None:
        outputs = ", ".join(out for _, out in scenario.measured_imu_topics())
        raise ValueError(f"navigator.imu_topic: {nav.imu_topic} is not a measured IMU ({outputs})")
    ideal, measured = spec.topics(scenario.recording.topics)
    if nav.initial_errors is not None and any(
        np.any(np.asarray(v) != 0) for v in nav.initial_errors.model_dump().values()
    ):
        raise ValueError("navigator.initial_errors: the prediction starts from zero errors")
    damping = None
    if nav.vertical_damping is not None:
        if nav.vertical_damping.paper_signs:
            raise ValueError("navigator.vertical_damping.paper_signs: the loop is unstable")
        damping = VerticalDampingGains(nav.vertical_damping.k1, nav.vertical_damping.k2)
    start, steps = steps_from_bag(bag, ideal, str(nav.truth_topic), nav.n * steps_per_output)
    return ScenarioModel(start, steps, spec.parameters(), str(nav.gravity_model), damping)


def predict_scenario(
    scenario: Scenario,
    bag: str | Path,
    params: ImuErrorParameters | None = None,
    steps_per_output: int = 1,
    cov0: F64 | None = None,
) -> Prediction:
    """Covariance prediction for the scenario's navigator on its measured IMU.

    ``bag``: the scenario generated (``generate_dataset``; the ideal IMU topic and the truth are
    read). ``params``: the IMU error parameters (default: the scenario's ``imu_errors``).
    ``steps_per_output``: propagation step in navigator output periods (default 1).
    ``cov0`` (54×54): the start covariance (default: the population's,
    :func:`~strapdown_ros.core.covariance.initial_moments`; a campaign's drawn constants:
    :func:`realized_initial_covariance`).
    """
    model = scenario_model(scenario, bag, steps_per_output)
    params = model.params if params is None else params
    steps = model.steps
    result = propagate_covariance(steps, params, cov0=cov0, gravity_model=model.gravity_model,
                                  damping=model.damping)  # fmt: skip
    mean, sigma = result.navigation_moments()
    stamps = model.start_ns + np.round(steps.t * 1e9).astype(np.int64)
    return Prediction(stamps, _to_components(mean), _to_components(sigma, 1.0), params)


def campaign_scenario(out: str | Path) -> Scenario:
    """The scenario of a campaign directory (its file and common overrides; run 0's seeds)."""
    info = json.loads((Path(out) / "campaign.json").read_text(encoding="utf-8"))
    return load_scenario(info["scenario"], list(info["common"]))


def campaign_seeds(out: str | Path, runs: Sequence[int], key: str = "imu_errors.seed") -> list[int]:
    """The ``key`` seed of each of ``runs`` of a campaign directory (``runs/NNNN/summary.json``)."""
    from strapdown_ros.campaign.results import run_dir

    return [int(json.loads((run_dir(Path(out), r) / "summary.json").read_text("utf-8"))
                ["seeds"][key]) for r in runs]  # fmt: skip


def _state_index(name: str) -> int:
    return STATE_NAMES.index(name)


def realized_initial_covariance(params: ImuErrorParameters, seeds: Sequence[int]) -> F64:
    """Start covariance (54×54) of the runs seeded ``seeds``: the sample second moment, about the
    population mean, of their drawn constants and initial Gauss–Markov biases.

    Each run's model (:class:`~strapdown_ros.core.imu_errors.ImuErrorModel`, seed s) draws at
    construction a (2, 15) block of standard normals u from ``PCG64(s)``, per triad (gyros
    first): turn-on bias 3, scale factor 3, misalignment 6 (xy, xz, yx, yz, zx, zy), initial
    Gauss–Markov bias 3 (docs/theory/imu_errors.md); the constant's deviation from its mean is
    its σ times u. ``P0 = (1/N) Σ_runs d dᵀ`` over those deviations d (54,), all other states
    (navigation, random walks, g-sensitivity) as :func:`initial_moments` has them (zero).
    """
    if len(seeds) < 1:
        raise ValueError("realized_initial_covariance: no seeds")
    rows = []
    for seed in seeds:
        u = np.random.Generator(np.random.PCG64(int(seed))).standard_normal((2, 15))
        d = np.zeros(N_STATES)
        for k, (name, s) in enumerate((("gyro", params.gyro), ("accel", params.accel))):
            for i, a in enumerate("xyz"):
                d[_state_index(f"bias_{name}_{a}")] = s.turn_on_bias_sigma[i] * u[k, i]
                d[_state_index(f"sf_{name}_{a}")] = s.scale_factor_sigma[i] * u[k, 3 + i]
                d[_state_index(f"gm_{name}_{a}")] = s.gauss_markov_sigma[i] * u[k, 12 + i]
            for j, (pair, (r, c)) in enumerate(zip(_PAIRS, _OFF_DIAG, strict=True)):
                d[_state_index(f"mis_{name}_{pair}")] = s.misalignment_sigma[r, c] * u[k, 6 + j]
        rows.append(d)
    d = np.array(rows)
    _, p0 = initial_moments(params)
    fixed = ~np.array([n.startswith(("bias_", "sf_", "mis_", "gm_")) for n in STATE_NAMES])
    p = d.T @ d / d.shape[0]
    p[np.ix_(fixed, fixed)] = p0[np.ix_(fixed, fixed)]
    return p


@dataclass(frozen=True)
class Ensemble:
    """A campaign's errors: ``stamps_ns`` (K,), ``errors`` (R, K, 9) in :data:`COMPONENTS`."""

    stamps_ns: NDArray[np.int64]
    errors: F64


def read_ensemble(out: str | Path) -> Ensemble:
    """Every finished run's errors of a campaign directory (same stamps in every run)."""
    from strapdown_ros.campaign.results import finished_runs, read_run_errors

    out = Path(out)
    runs = sorted(finished_runs(out))
    if not runs:
        raise ValueError(f"{out}: no finished run")
    stamps, first = read_run_errors(out, runs[0])
    errors = np.empty((len(runs),) + first.shape)
    errors[0] = first
    for i, r in enumerate(runs[1:], start=1):
        s, e = read_run_errors(out, r)
        if not np.array_equal(s, stamps):
            raise ValueError(f"{out}: run {r} has other stamps than run {runs[0]}")
        errors[i] = e
    return Ensemble(np.asarray(stamps, dtype=np.int64), errors)


def down_as_height_error(ensemble: Ensemble, latitude_rad: float, altitude_m: float) -> Ensemble:
    """The ensemble with its down position error as the linear model's ``δr_D = −δh``.

    The error topic's δr is the NED vector (m) from the true position to the computed one, so a
    computed point at the true height displaced horizontally by (δr_N, δr_E) lies
    ``c = δr_N² / (2 (R_N + h)) + δr_E² / (2 (R_E + h))`` below the tangent plane (R_N, R_E the
    meridian and prime-vertical radii at ``latitude_rad``, the principal radii of curvature of
    the ellipsoid's normal sections): ``δr_D − c = −δh`` to second order in the horizontal
    error, which the linear model (first order) lacks. The radii are taken at one latitude and
    height (the scenario's initial position: for a static or short scenario).
    """
    r_n, r_e = (float(r) + altitude_m for r in radii(latitude_rad))
    errors = ensemble.errors.copy()
    errors[..., 2] -= 0.5 * (errors[..., 0] ** 2 / r_n + errors[..., 1] ** 2 / r_e)
    return Ensemble(ensemble.stamps_ns, errors)


@dataclass(frozen=True)
class ComponentCheck:
    """One component: ``inside`` (fraction of epochs after ``skip_s`` with σ_ens in the χ²(N)
    95 % band), ``ratio_mean`` (time average of σ_ens / σ_pred there), min/max of the ratio,
    final σ_pred and σ_ens."""

    name: str
    inside: float
    ratio_mean: float
    ratio_min: float
    ratio_max: float
    sigma_pred_final: float
    sigma_ens_final: float


def chi2_band(n: int) -> tuple[float, float]:
    """The 95 % band of σ_ens / σ for N samples about the known mean: √(χ²_{.025,N}/N), …"""
    return float(np.sqrt(chi2.ppf(0.025, n) / n)), float(np.sqrt(chi2.ppf(0.975, n) / n))


def compare_ensemble(
    prediction: Prediction, ensemble: Ensemble, skip_s: float = 60.0
) -> tuple[list[ComponentCheck], dict[str, F64]]:
    """Per-component checks and the series (t, σ_pred, σ_ens, mean_pred, mean_ens) at the
    stamps common to both (from the ensemble's first stamp, which must be the prediction's)."""
    if ensemble.stamps_ns[0] != prediction.stamps_ns[0]:
        raise ValueError("the ensemble and the prediction start at different stamps")
    common, i_pred, i_ens = np.intersect1d(
        prediction.stamps_ns, ensemble.stamps_ns, assume_unique=True, return_indices=True
    )
    if common.shape[0] < 2:
        raise ValueError("the ensemble and the prediction have fewer than 2 common stamps")
    mean, sigma = prediction.mean[i_pred], prediction.sigma[i_pred]
    errors = ensemble.errors[:, i_ens]
    n = errors.shape[0]
    s_ens = np.sqrt(np.mean((errors - mean) ** 2, axis=0))
    t = (common - common[0]) * 1e-9
    lo, hi = chi2_band(n)
    late = t >= skip_s
    checks = []
    for j, name in enumerate(COMPONENTS):
        r = s_ens[late, j] / sigma[late, j]
        checks.append(ComponentCheck(
            name, float(np.mean((r >= lo) & (r <= hi))), float(np.mean(r)), float(r.min()),
            float(r.max()), float(sigma[-1, j]), float(s_ens[-1, j]),
        ))  # fmt: skip
    series = {"t": t, "sigma_pred": sigma, "sigma_ens": s_ens, "mean_pred": mean,
              "mean_ens": errors.mean(axis=0)}  # fmt: skip
    return checks, series


def checks_table(checks: list[ComponentCheck], n: int) -> str:
    """The checks as a Markdown table."""
    lo, hi = chi2_band(n)
    lines = [f"N = {n} runs, χ²(N) 95 % band of σ_ens/σ_pred: [{lo:.3f}, {hi:.3f}]", "",
             "| component | σ_pred final | σ_ens final | epochs inside | mean ratio | min | max |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for c in checks:
        lines.append(f"| {c.name} | {c.sigma_pred_final:.4g} | {c.sigma_ens_final:.4g} | "
                     f"{100 * c.inside:.1f} % | {c.ratio_mean:.3f} | {c.ratio_min:.3f} | "
                     f"{c.ratio_max:.3f} |")  # fmt: skip
    return "\n".join(lines)


def summary(checks: list[ComponentCheck]) -> dict[str, Any]:
    """JSON-able form of the checks."""
    return {c.name: c.__dict__ for c in checks}
