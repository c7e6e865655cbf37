"""Monte Carlo runs of the aided filter, driven in-process like a campaign run.

A run is ``generate``'s chain restricted to what the filter needs — reference batches → the
measurement stage (``imu_errors`` on ``/reference/imu``) → the aiding stage → the
:class:`~strapdown_ros.stages.aided.AidedStage` — fed the same pieces in the same order, so run
k equals ``strapdown-sim generate`` with run k's overrides. Run k sets every ``seed`` of the
scenario (IMU errors, each aiding sensor, the filter's initial draw) from
``SeedSequence(base_seed, spawn_key=(k,))``; the reference pieces are computed once.

:func:`modelled_only` strips from a scenario document the error terms the filter does not model
(docs/aided.md): IMU misalignments, g-sensitivity, saturation and fixed terms, GNSS offsets,
soft iron, fixed barometer bias and wheel scale factor. :func:`consistency` gives the NEES, NIS
and bias-error statistics over the runs (:mod:`strapdown_ros.core.aided.consistency`);
:func:`outage_drift` the drift over GNSS outages as KF-GINS reports it. ``tools/aided_study.py``
is the command line.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import Scenario
from strapdown_ros.config.scenario import apply_overrides, parse_scenario
from strapdown_ros.core.aided.consistency import Inside, fraction_inside, normalized_squares
from strapdown_ros.core.earth import dcm_ecef_to_ned
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters, SensorErrors
from strapdown_ros.messages import dcm_from_quat_ros

__all__ = [
    "RunResult",
    "consistency",
    "modelled_only",
    "monte_carlo",
    "outage_drift",
    "reference_pieces",
    "run_aided",
    "seed_overrides",
]

_FLU = np.array([1.0, -1.0, -1.0])


@dataclass
class RunResult:
    """What one run gives at the output epochs (and per measurement).

    ``stamps`` (K,) ns; ``nees`` (K, 3) position, velocity, attitude; ``error_*`` (K, 3) the
    navigator's error definitions; ``sigma_*`` predicted σ: ``sigma_h``, ``sigma_v`` of the
    horizontal and vertical position, ``sigma_level``, ``sigma_heading`` of the attitude about
    the level axes (rss) and about down (rad); ``bias_*_error`` (K, 3) estimate minus truth
    (FRD) with ``bias_*_sigma``; ``nis``: sensor → (stamps, nis, dof, accepted).
    """

    stamps: np.ndarray
    nees: np.ndarray
    error_position: np.ndarray
    error_velocity: np.ndarray
    error_attitude: np.ndarray
    sigma_h: np.ndarray
    sigma_v: np.ndarray
    sigma_level: np.ndarray
    sigma_heading: np.ndarray
    bias_gyro_error: np.ndarray
    bias_accel_error: np.ndarray
    bias_gyro_sigma: np.ndarray
    bias_accel_sigma: np.ndarray
    nis: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict)
    rejections: int = 0


def modelled_only(document: dict[str, Any]) -> dict[str, Any]:
    """A copy of a scenario document with the error terms the filter does not model removed.

    IMU (applied after the preset): misalignments (fixed and σ), g-sensitivity, saturation,
    fixed bias and scale factor → 0; aiding: GNSS offsets, magnetometer soft iron, fixed
    barometer bias and wheel scale factor → none. Quantization stays (modelled as white noise).
    """
    doc = copy.deepcopy(document)
    imu = doc.get("imu_errors")
    if isinstance(imu, dict):
        for key in ("gyro_misalignment_sigma_mrad", "accel_misalignment_sigma_mrad",
                    "gyro_g_sensitivity_dphpg", "gyro_range_dps", "accel_range_g",
                    "gyro_bias_dph", "accel_bias_mg", "gyro_scale_factor_ppm",
                    "accel_scale_factor_ppm"):  # fmt: skip
            imu[key] = 0.0
        for key in ("gyro_misalignment_mrad", "accel_misalignment_mrad"):
            imu[key] = [0.0] * 6
    aiding = doc.get("aiding") or {}
    zero = {
        "gnss": ("position_offset_m", "velocity_offset_mps"),
        "barometer": ("bias_pa",),
        "wheel_odometer": ("scale_factor_ppm",),
    }
    for sensor, keys in zero.items():
        if isinstance(aiding.get(sensor), dict):
            for key in keys:
                aiding[sensor][key] = 0.0
    if isinstance(aiding.get("magnetometer"), dict):
        aiding["magnetometer"].pop("soft_iron", None)
    return doc


def seed_overrides(document: dict[str, Any], run: int, base_seed: int = 0) -> list[str]:
    """``--set`` overrides giving run ``run`` its own seeds (IMU errors, sensors, filter)."""
    keys = []
    if isinstance(document.get("imu_errors"), dict):
        keys.append("imu_errors.seed")
    for sensor, body in (document.get("aiding") or {}).items():
        if isinstance(body, dict):
            keys.append(f"aiding.{sensor}.seed")
    keys.append("aided.seed")
    seq = np.random.SeedSequence(base_seed, spawn_key=(run,))
    seeds = seq.generate_state(len(keys), dtype=np.uint32)
    return [f"{k}={int(s)}" for k, s in zip(keys, seeds, strict=True)]


def reference_pieces(scenario: Scenario) -> list[list[Batch]]:
    """The reference batches of ``generate``'s pieces (only what the runs read)."""
    from strapdown_ros.stages.trajectory import reference_batch_chunks

    keep = {scenario.recording.topics["reference_imu"], scenario.recording.topics["reference_odom"]}
    return [[b for b in batches if b.topic in keep]
            for _, batches in reference_batch_chunks(scenario)]


def _true_bias(params: ImuErrorParameters, period_s: float, cycles: int) -> tuple[np.ndarray, ...]:
    """The run's true total biases (mean of each cycle, FRD): the same model and seed with the
    white noise, quantization and saturation off, applied to zero increments (the random draws
    are laid out whatever the parameters, docs/theory/imu_errors.md)."""

    def quiet(s: SensorErrors) -> SensorErrors:
        z = np.zeros(3)
        return SensorErrors(s.bias, s.turn_on_bias_sigma, s.bias_instability,
                            s.correlation_time_s, z, s.random_walk, s.scale_factor,
                            s.scale_factor_sigma, s.misalignment, s.misalignment_sigma, z, z,
                            np.zeros((3, 3)))  # fmt: skip

    model = ImuErrorModel(ImuErrorParameters(quiet(params.gyro), quiet(params.accel),
                                             params.seed), period_s)  # fmt: skip
    g, a = model.apply(np.zeros((cycles, 3)), np.zeros((cycles, 3)))
    return g / period_s, a / period_s


def run_aided(scenario: Scenario, pieces: Iterable[list[Batch]] | None = None) -> RunResult:
    """One run (see the module docstring)."""
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import feed_stages, offline_stages
    from strapdown_ros.stages.aided import AidedStage

    if pieces is None:
        pieces = reference_pieces(scenario)
    upstream = offline_stages(resolve_plan(scenario), ["imu_errors", "aiding"])
    stage = AidedStage(scenario)
    wanted = {t for k, t in stage.topics.items() if k in (
        "odom", "fix", "nees", "error_position", "error_velocity", "error_attitude",
        "bias_gyro", "bias_accel", "bias_gyro_sigma", "bias_accel_sigma",
    ) or k.startswith("nis_")}  # fmt: skip
    out: dict[str, list] = {}
    for batches in pieces:
        for b in stage.feed_batches(feed_stages(upstream, batches)):
            if b.topic in wanted:
                out.setdefault(b.topic, []).extend(b.payloads)
    for b in stage.flush():
        if b.topic in wanted:
            out.setdefault(b.topic, []).extend(b.payloads)
    return _result(scenario, stage, out)


def _vec(out: dict[str, list], topic: str) -> Any:
    return cdr.deserialize(cdr.VECTOR3_STAMPED, out[topic])


def _result(scenario: Scenario, stage: Any, out: dict[str, list]) -> RunResult:
    t = stage.topics
    nees = _vec(out, t["nees"])
    stamps = np.asarray(nees.stamps_ns, dtype=np.int64)
    fix = cdr.deserialize(cdr.NAVSATFIX, out[t["fix"]])
    odom = cdr.deserialize(cdr.ODOMETRY, out[t["odom"]])
    sel = np.isin(np.asarray(fix.stamps_ns), stamps)
    cov = np.asarray(fix.position_covariance)[sel].reshape(-1, 3, 3)  # ENU
    pose = np.asarray(odom.pose_covariance)[sel].reshape(-1, 6, 6)
    lat = np.radians(np.asarray(fix.latitude)[sel])
    lon = np.radians(np.asarray(fix.longitude)[sel])
    cen = dcm_ecef_to_ned(lat, lon)
    att = cen @ pose[:, 3:, 3:] @ np.swapaxes(cen, -1, -2)  # rotation about NED axes
    _ = dcm_from_quat_ros
    period_s = scenario.period_ns * 1e-9
    assert scenario.imu_errors is not None
    m = (stamps - scenario.start_time_ns) // scenario.period_ns
    cycles = int(m.max()) + 1
    g_true, a_true = _true_bias(scenario.imu_errors.parameters(), period_s, max(cycles, 2))
    idx = np.clip(m - 1, 0, None)  # the cycle ending at the epoch (cycle 1 at the start)
    bg = _vec(out, t["bias_gyro"]).vector * _FLU
    ba = _vec(out, t["bias_accel"]).vector * _FLU
    bsel = np.isin(np.asarray(_vec(out, t["bias_gyro"]).stamps_ns), stamps)
    nis = {}
    for s in stage.sensors:
        topic = t[f"nis_{s}"]
        if topic in out:
            f = _vec(out, topic)
            v = np.asarray(f.vector)
            nis[s] = (np.asarray(f.stamps_ns, dtype=np.int64), v[:, 0], v[:, 1].astype(int),
                      v[:, 2] != 0)  # fmt: skip
    return RunResult(
        stamps=stamps,
        nees=np.asarray(nees.vector),
        error_position=np.asarray(_vec(out, t["error_position"]).vector),
        error_velocity=np.asarray(_vec(out, t["error_velocity"]).vector),
        error_attitude=np.asarray(_vec(out, t["error_attitude"]).vector),
        sigma_h=np.sqrt(cov[:, 0, 0] + cov[:, 1, 1]),
        sigma_v=np.sqrt(cov[:, 2, 2]),
        sigma_level=np.sqrt(att[:, 0, 0] + att[:, 1, 1]),
        sigma_heading=np.sqrt(att[:, 2, 2]),
        bias_gyro_error=bg[bsel] - g_true[idx],
        bias_accel_error=ba[bsel] - a_true[idx],
        bias_gyro_sigma=np.asarray(_vec(out, t["bias_gyro_sigma"]).vector)[bsel],
        bias_accel_sigma=np.asarray(_vec(out, t["bias_accel_sigma"]).vector)[bsel],
        nis=nis,
        rejections=len(stage.rejections),
    )


def _one(args: tuple[dict[str, Any], list[str], list[list[Batch]] | None]) -> RunResult:
    document, overrides, pieces = args
    return run_aided(parse_scenario(apply_overrides(document, overrides)), pieces)


def monte_carlo(document: dict[str, Any], runs: int, base_seed: int = 0,
                overrides: Sequence[str] = (), workers: int = 1) -> list[RunResult]:  # fmt: skip
    """``runs`` runs of a scenario document (``overrides`` applied to all, then each run's
    seeds); the reference pieces are computed once and shared."""
    base = apply_overrides(document, list(overrides))
    scenario = parse_scenario(base)
    pieces = reference_pieces(scenario) if scenario.variation is None else None
    jobs = [(base, seed_overrides(base, k, base_seed), pieces) for k in range(runs)]
    if workers <= 1:
        return [_one(j) for j in jobs]
    with ProcessPoolExecutor(workers) as pool:
        return list(pool.map(_one, jobs))


def _stack(arrays: list[np.ndarray]) -> np.ndarray:
    k = min(len(a) for a in arrays)
    return np.stack([a[:k] for a in arrays])


@dataclass(frozen=True)
class Consistency:
    """NEES (position, velocity, attitude), NIS per sensor and bias checks over the runs."""

    runs: int
    convergence_s: float
    nees: dict[str, Inside]
    nis: dict[str, Inside]
    bias: dict[str, Inside]

    def lines(self) -> list[str]:
        """A table of the results, one line per statistic."""
        out = [f"{self.runs} runs, epochs after {self.convergence_s:g} s; two-sided 95 % "
               "interval of the run average"]  # fmt: skip
        for group, items in (("NEES", self.nees), ("NIS", self.nis), ("bias", self.bias)):
            for name, r in items.items():
                out.append(
                    f"{group:4s} {name:22s} inside {100 * r.fraction:5.1f} % (below "
                    f"{100 * r.below:4.1f} %, above {100 * r.above:4.1f} %), mean "
                    f"{r.mean:.3f} in [{r.interval[0]:.3f}, {r.interval[1]:.3f}], "
                    f"{r.epochs} epochs"
                )  # fmt: skip
        return out


def consistency(results: list[RunResult], convergence_s: float = 0.0) -> Consistency:
    """The consistency statistics of runs (epochs after ``convergence_s`` since the start)."""
    t0 = results[0].stamps[0]
    keep = results[0].stamps - t0 >= convergence_s * 1e9
    nees = _stack([r.nees for r in results])[:, keep[: min(len(r.nees) for r in results)]]
    out_nees = {n: fraction_inside(nees[:, :, i], 3) for i, n in
                enumerate(("position", "velocity", "attitude"))}  # fmt: skip
    out_nis = {}
    for s in results[0].nis:
        st = results[0].nis[s][0]
        k = min(len(r.nis[s][1]) for r in results)
        v = np.stack([r.nis[s][1][:k] for r in results])
        dof = int(results[0].nis[s][2][0])
        sel = st[:k] - t0 >= convergence_s * 1e9
        out_nis[s] = fraction_inside(v[:, sel], dof)
    out_bias = {}
    for name, err, sig in (("gyro", "bias_gyro_error", "bias_gyro_sigma"),
                           ("accel", "bias_accel_error", "bias_accel_sigma")):  # fmt: skip
        e = _stack([getattr(r, err) for r in results])
        s = _stack([getattr(r, sig) for r in results])
        q = normalized_squares(e, s)[:, keep[: e.shape[1]]]
        for i, axis in enumerate("xyz"):
            out_bias[f"{name}_{axis}"] = fraction_inside(q[:, :, i], 1)
    return Consistency(len(results), convergence_s, out_nees, out_nis, out_bias)


@dataclass(frozen=True)
class OutageDrift:
    """RMS over the outages of each outage's largest drift, and the filter's σ at that epoch
    (its RMS over the outages): horizontal, vertical (m), level and heading (rad)."""

    outages: int
    horizontal: float
    vertical: float
    level: float
    heading: float
    sigma_horizontal: float
    sigma_vertical: float
    sigma_level: float
    sigma_heading: float


def outage_drift(results: list[RunResult], windows_ns: Sequence[tuple[int, int]]) -> OutageDrift:
    """KF-GINS's outage statistic over runs and GNSS outage windows ``[a, b)`` (ns): in each
    outage the maximum of the horizontal and vertical position error, the level attitude error
    (rss of the two level Young angles) and the heading error; their RMS over all outages of all
    runs; beside it, the filter's own σ at the same epochs."""
    rows = []
    for r in results:
        for a, b in windows_ns:
            sel = (r.stamps >= a) & (r.stamps <= b)
            if not sel.any():
                continue
            e = r.error_position[sel]
            att = r.error_attitude[sel]  # (up, east, north)
            h = np.hypot(e[:, 0], e[:, 1])
            v = np.abs(e[:, 2])
            lvl = np.hypot(att[:, 1], att[:, 2])
            hdg = np.abs(att[:, 0])
            pick = [int(np.argmax(x)) for x in (h, v, lvl, hdg)]
            sig = [r.sigma_h[sel], r.sigma_v[sel], r.sigma_level[sel], r.sigma_heading[sel]]
            rows.append([h[pick[0]], v[pick[1]], lvl[pick[2]], hdg[pick[3]],
                         *(s[p] for s, p in zip(sig, pick, strict=True))])  # fmt: skip
    a = np.array(rows)
    rms = np.sqrt(np.mean(a**2, axis=0)) if len(a) else np.full(8, math.nan)
    return OutageDrift(len(a), *(float(x) for x in rms))
