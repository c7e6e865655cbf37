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
:func:`outage_drift` the drift over GNSS outages as KF-GINS reports it; :func:`main` the
command line (``python -m strapdown_ros.stages.aided_montecarlo --help``).
"""

from __future__ import annotations

import copy
import math
import shutil
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import Scenario
from strapdown_ros.config.scenario import apply_overrides, parse_scenario, read_document
from strapdown_ros.core.aided.consistency import Inside, fraction_inside, normalized_squares
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters, SensorErrors

__all__ = [
    "RunResult",
    "average_series",
    "bag_result",
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

    ``stamps`` (K,) ns; ``nees`` (K, 3) position, velocity, attitude (recomputed from the
    messages, :func:`bag_result`); ``error_*`` (K, 3) position and velocity errors in NED, the
    attitude error's rotation vector in NED; ``sigma_*`` predicted σ: ``sigma_h``, ``sigma_v``
    of the horizontal and vertical position, ``sigma_level``, ``sigma_heading`` of the
    attitude about the level axes (rss) and about down (rad); ``bias_*_error`` (K, 3) estimate
    minus truth (FRD) with ``bias_*_sigma``; ``nis``: sensor → (stamps, nis, dof, accepted);
    ``published_nees``: ``/aided/nees`` at the same epochs.
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
    published_nees: np.ndarray | None = None
    rejections: int = 0


def modelled_only(document: dict[str, Any]) -> dict[str, Any]:
    """A copy of a scenario document with the error terms the filter does not model removed.

    IMU (applied after the preset): misalignments (fixed and σ), g-sensitivity, saturation,
    fixed bias and scale factor → 0; aiding: GNSS offsets, magnetometer soft iron, fixed
    barometer bias and wheel scale factor → none. Quantization stays (modelled as white noise).
    """
    doc = copy.deepcopy(document)
    imu = doc.get("imu_errors")
    for model in [imu] if isinstance(imu, dict) else imu or []:
        if not isinstance(model, dict):
            continue
        for key in ("gyro_misalignment_sigma_mrad", "accel_misalignment_sigma_mrad",
                    "gyro_g_sensitivity_dphpg", "gyro_range_dps", "accel_range_g",
                    "gyro_bias_dph", "accel_bias_mg", "gyro_scale_factor_ppm",
                    "accel_scale_factor_ppm"):  # fmt: skip
            model[key] = 0.0
        for key in ("gyro_misalignment_mrad", "accel_misalignment_mrad"):
            model[key] = [0.0] * 6
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


def campaign_document(path: Path, modelled: bool, overrides: Sequence[str],
                      duration_s: float | None) -> tuple[dict[str, Any], list[str]]:
    """A campaign's scenario document (``modelled_only`` if asked) and its ``--set`` overrides,
    ``duration_s`` appended when given: what the command lines of this module and
    ``analysis.aided_check`` share."""
    doc = read_document(path)
    if modelled:
        doc = modelled_only(doc)
    extra = [f"duration_s={duration_s:g}"] if duration_s is not None else []
    return doc, [*overrides, *extra]


def seed_overrides(document: dict[str, Any], run: int, base_seed: int = 0) -> list[str]:
    """``--set`` overrides giving run ``run`` its own seeds (IMU errors, sensors, filter)."""
    keys = []
    imu = document.get("imu_errors")
    if isinstance(imu, dict):
        keys.append("imu_errors.seed")
    elif isinstance(imu, list):
        keys += [f"imu_errors.{i}.seed" for i, m in enumerate(imu) if isinstance(m, dict)]
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


def run_aided(scenario: Scenario, bag: Path, pieces: Iterable[list[Batch]] | None = None,
              *, keep: bool = False) -> RunResult:  # fmt: skip
    """One run (see the module docstring): the ``/aided/*`` outputs and the truth at the output
    epochs written to the bag ``bag``, read back and evaluated by :func:`bag_result`; the bag
    is removed afterwards unless ``keep``."""
    from strapdown_ros.bag.writer import BagWriter
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import feed_stages, offline_stages
    from strapdown_ros.stages.aided import AidedStage

    if pieces is None:
        pieces = reference_pieces(scenario)
    upstream = offline_stages(resolve_plan(scenario), ["imu_errors", "aiding"])
    stage = AidedStage(scenario)
    truth = stage.truth_topic
    with BagWriter(bag, force=True) as writer:
        for batches in [*pieces, None]:
            if batches is None:
                out = stage.flush()
            else:
                out = stage.feed_batches(feed_stages(upstream, batches))
                out += [_on_epochs(b, stage.out_period) for b in batches if b.topic == truth]
            writer.write_batches(out)
    result = bag_result(bag, scenario)
    result.rejections = len(stage.rejections)
    if not keep:
        shutil.rmtree(bag)
    return result


def _on_epochs(b: Batch, period_ns: int) -> Batch:
    """The messages of a batch whose log time is on the output grid."""
    t = np.asarray(b.stamps_ns, dtype=np.int64)
    keep = np.flatnonzero(t % period_ns == 0)
    return Batch(b.topic, b.msgtype, t[keep], [b.payloads[i] for i in keep])


def _nees(e: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.einsum("ki,ki->k", e, np.linalg.solve(p, e[..., None])[..., 0])


_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def bag_result(path: Path, scenario: Scenario) -> RunResult:
    """A run's :class:`RunResult` recomputed from a bag holding its ``/aided/*`` topics and the
    truth (``aided.truth_topic``) at the output epochs.

    Errors and NEES are derived here from the published messages, not taken from
    ``/aided/nees``: position ``r̂ - r`` (ECEF) against the Odometry pose covariance; velocity
    (NED of each position) from ``/aided/vel`` and the truth twist against the ``/aided/vel``
    covariance; attitude the rotation vector of ``Ĉ Cᵀ`` (about the ECEF axes, the ROS pose
    covariance convention) against the pose covariance's rotation block. Errors are reported
    in NED at the true position (attitude: the rotation vector's NED components).
    """
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.messages import odometry_state
    from strapdown_ros.stages.aided import aided_imu_errors, aided_output_topics, aided_sensors

    topics = aided_output_topics(scenario)
    sensors = aided_sensors(scenario)
    truth_topic = scenario.aided.truth_topic  # type: ignore[union-attr]
    nis_topics = [topics[f"nis_{s}"] for s in sensors]
    wanted = [topics[k] for k in ("odom", "vel", "bias_gyro", "bias_accel", "bias_gyro_sigma",
                                  "bias_accel_sigma", "nees")]  # fmt: skip
    bag = read_bag(path, [*wanted, truth_topic, *nis_topics])
    odom = bag[topics["odom"]]
    vel = bag[topics["vel"]]
    truth = bag[truth_topic]
    t_est = np.asarray(odom.stamps_ns, dtype=np.int64)
    t_true = np.asarray(truth.stamps_ns, dtype=np.int64)
    stamps, ie, it = np.intersect1d(t_est, t_true, return_indices=True)
    iv = np.searchsorted(np.asarray(vel.stamps_ns), stamps)
    st = odometry_state(truth)
    r_true, v_true_e, c_true = st.r_e[it], st.v_e[it], st.c_b_e[it]
    est = odometry_state(odom)
    r_est, c_est = est.r_e[ie], est.c_b_e[ie]
    lat, lon, _ = ecef_to_geodetic(r_true)
    cen = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
    cne = np.swapaxes(cen, -1, -2)
    pose = np.asarray(odom.pose_covariance)[ie].reshape(-1, 6, 6)
    dr_e = r_est - r_true
    p_pos = pose[:, :3, :3]
    v_est_ned = np.asarray(vel.linear)[iv] @ _ENU
    dv = v_est_ned - np.einsum("kij,kj->ki", cen, v_true_e)
    p_vel = _ENU @ np.asarray(vel.covariance)[iv].reshape(-1, 6, 6)[:, :3, :3] @ _ENU
    phi_e = Rotation.from_matrix(c_est @ np.swapaxes(c_true, -1, -2)).as_rotvec()
    p_att = pose[:, 3:, 3:]
    nees = np.stack([_nees(dr_e, p_pos), _nees(dv, p_vel), _nees(phi_e, p_att)], axis=-1)
    pos_ned = cen @ p_pos @ cne
    att_ned = cen @ p_att @ cne
    # bias estimates against the run's true biases
    period_s = scenario.period_ns * 1e-9
    m = (stamps - scenario.start_time_ns) // scenario.period_ns
    cycles = max(int(m.max()) + 1, 2)
    g_true, a_true = _true_bias(aided_imu_errors(scenario).parameters(), period_s, cycles)
    idx = np.clip(m - 1, 0, None)  # the cycle ending at the epoch (cycle 1 at the start)

    def vec(key: str) -> np.ndarray:
        f = bag[topics[key]]
        sel = np.searchsorted(np.asarray(f.stamps_ns), stamps)
        return np.asarray(f.vector)[sel]

    nis = {}
    for s, topic in zip(sensors, nis_topics, strict=True):
        f = bag[topic]
        v = np.asarray(f.vector)
        nis[s] = (np.asarray(f.stamps_ns, dtype=np.int64), v[:, 0], v[:, 1].astype(int),
                  v[:, 2] != 0)  # fmt: skip
    return RunResult(
        stamps=stamps,
        nees=nees,
        error_position=np.einsum("kij,kj->ki", cen, dr_e),
        error_velocity=dv,
        error_attitude=np.einsum("kij,kj->ki", cen, phi_e),
        sigma_h=np.sqrt(pos_ned[:, 0, 0] + pos_ned[:, 1, 1]),
        sigma_v=np.sqrt(pos_ned[:, 2, 2]),
        sigma_level=np.sqrt(att_ned[:, 0, 0] + att_ned[:, 1, 1]),
        sigma_heading=np.sqrt(att_ned[:, 2, 2]),
        bias_gyro_error=vec("bias_gyro") * _FLU - g_true[idx],
        bias_accel_error=vec("bias_accel") * _FLU - a_true[idx],
        bias_gyro_sigma=vec("bias_gyro_sigma"),
        bias_accel_sigma=vec("bias_accel_sigma"),
        nis=nis,
        published_nees=vec("nees"),
    )


def _one(args: tuple[dict[str, Any], list[str], list[list[Batch]] | None, Path, bool]
         ) -> RunResult:  # fmt: skip
    document, overrides, pieces, bag, keep = args
    return run_aided(parse_scenario(apply_overrides(document, overrides)), bag, pieces, keep=keep)


def monte_carlo(document: dict[str, Any], runs: int, directory: Path, base_seed: int = 0,
                overrides: Sequence[str] = (), workers: int = 1,
                keep: bool = False) -> list[RunResult]:  # fmt: skip
    """``runs`` runs of a scenario document (``overrides`` applied to all, then each run's
    seeds), run k's outputs in the bag ``directory/run_<k>`` (removed after it is read back
    unless ``keep``); the reference pieces are computed once and shared."""
    base = apply_overrides(document, list(overrides))
    scenario = parse_scenario(base)
    pieces = reference_pieces(scenario) if scenario.variation is None else None
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [(base, seed_overrides(base, k, base_seed), pieces, directory / f"run_{k:03d}", keep)
            for k in range(runs)]  # fmt: skip
    if workers <= 1:
        return [_one(j) for j in jobs]
    with ProcessPoolExecutor(workers) as pool:
        return list(pool.map(_one, jobs))


def _stack(arrays: list[np.ndarray]) -> np.ndarray:
    k = min(len(a) for a in arrays)
    return np.stack([a[:k] for a in arrays])


#: The NEES components of a run, in ``RunResult.nees``' column order.
_NEES = ("position", "velocity", "attitude")


def _nis_stack(results: list[RunResult], sensor: str) -> tuple[np.ndarray, np.ndarray, int]:
    """One sensor's NIS over the runs: the first run's stamps (K,) ns, the values (runs, K)
    cut to the shortest run, the degrees of freedom."""
    values = _stack([r.nis[sensor][1] for r in results])
    first = results[0].nis[sensor]
    return first[0][: values.shape[1]], values, int(first[2][0])


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
    out_nees = {n: fraction_inside(nees[:, :, i], 3) for i, n in enumerate(_NEES)}
    out_nis = {}
    for s in results[0].nis:
        st, v, dof = _nis_stack(results, s)
        out_nis[s] = fraction_inside(v[:, st - t0 >= convergence_s * 1e9], dof)
    out_bias = {}
    for name, err, sig in (("gyro", "bias_gyro_error", "bias_gyro_sigma"),
                           ("accel", "bias_accel_error", "bias_accel_sigma")):  # fmt: skip
        e = _stack([getattr(r, err) for r in results])
        s = _stack([getattr(r, sig) for r in results])
        q = normalized_squares(e, s)[:, keep[: e.shape[1]]]
        for i, axis in enumerate("xyz"):
            out_bias[f"{name}_{axis}"] = fraction_inside(q[:, :, i], 1)
    return Consistency(len(results), convergence_s, out_nees, out_nis, out_bias)


def average_series(results: list[RunResult]) -> dict[str, dict[str, Any]]:
    """The run averages per epoch, ``{"NEES": {position, velocity, attitude}, "NIS": {sensor:
    ...}}``, for :func:`strapdown_ros.report.consistency_plot.plot_consistency`."""
    from strapdown_ros.report.consistency_plot import AverageSeries

    t0 = results[0].stamps[0]
    nees = _stack([r.nees for r in results])
    t = (results[0].stamps[: nees.shape[1]] - t0) * 1e-9
    out: dict[str, dict[str, Any]] = {"NEES": {
        n: AverageSeries(t, nees[:, :, i].mean(axis=0), 3, len(results))
        for i, n in enumerate(_NEES)}}  # fmt: skip
    nis: dict[str, Any] = {}
    for s in results[0].nis:
        st, v, dof = _nis_stack(results, s)
        nis[s] = AverageSeries((st - t0) * 1e-9, v.mean(axis=0), dof, len(results))
    if nis:
        out["NIS"] = nis
    return out


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
            att = r.error_attitude[sel]  # rotation about north, east, down
            h = np.hypot(e[:, 0], e[:, 1])
            v = np.abs(e[:, 2])
            lvl = np.hypot(att[:, 0], att[:, 1])
            hdg = np.abs(att[:, 2])
            pick = [int(np.argmax(x)) for x in (h, v, lvl, hdg)]
            sig = [r.sigma_h[sel], r.sigma_v[sel], r.sigma_level[sel], r.sigma_heading[sel]]
            rows.append([h[pick[0]], v[pick[1]], lvl[pick[2]], hdg[pick[3]],
                         *(s[p] for s, p in zip(sig, pick, strict=True))])  # fmt: skip
    a = np.array(rows)
    rms = np.sqrt(np.mean(a**2, axis=0)) if len(a) else np.full(8, math.nan)
    return OutageDrift(len(a), *(float(x) for x in rms))


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: a campaign of runs, its consistency table or its outage drift."""
    import argparse
    import tempfile
    import time

    ap = argparse.ArgumentParser(prog="python -m strapdown_ros.stages.aided_montecarlo",
                                 description="Monte Carlo runs of the aided filter")  # fmt: skip
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--duration", type=float, default=None, help="duration_s of every run")
    ap.add_argument("--modelled-only", action="store_true",
                    help="strip the error terms the filter does not model")  # fmt: skip
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="KEY=VALUE")  # fmt: skip
    ap.add_argument("--convergence", type=float, default=60.0, help="s after the start")
    ap.add_argument("--outage-drift", action="store_true",
                    help="print the drift over the GNSS outages instead")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0, help="base seed of the runs")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--dir", type=Path, default=None, help="where the run bags go (temporary)")
    ap.add_argument("--plot", type=Path, default=None, metavar="PNG",
                    help="draw the run-average NEES and NIS and their 95 %% bounds")  # fmt: skip
    args = ap.parse_args(argv)
    if args.dir is not None and not args.dir.is_dir():
        ap.error(f"--dir {args.dir}: not a directory")
    doc, overrides = campaign_document(args.scenario, args.modelled_only, args.overrides,
                                       args.duration)  # fmt: skip
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        results = monte_carlo(doc, args.runs, Path(tmp), args.seed, overrides, args.workers)
    took = time.perf_counter() - start
    scenario = parse_scenario(apply_overrides(doc, overrides))
    print(f"{args.scenario.name}: {args.runs} runs of {scenario.duration_s:g} s"
          f"{' (modelled terms only)' if args.modelled_only else ''}, {took:.0f} s; gate "
          f"rejections {sum(r.rejections for r in results)}")  # fmt: skip
    if args.outage_drift:
        assert scenario.aiding is not None and scenario.aiding.gnss is not None
        d = outage_drift(results, scenario.aiding.gnss.outage_windows_ns(scenario.start_time_ns))
        print(f"{d.outages} outages; RMS of the largest drift (filter σ beside it):")
        print(f"  horizontal {d.horizontal:.3f} m ({d.sigma_horizontal:.3f}), vertical "
              f"{d.vertical:.3f} m ({d.sigma_vertical:.3f}), roll/pitch "
              f"{math.degrees(d.level):.4f} deg ({math.degrees(d.sigma_level):.4f}), heading "
              f"{math.degrees(d.heading):.4f} deg ({math.degrees(d.sigma_heading):.4f})")
        return 0
    print("\n".join(consistency(results, args.convergence).lines()))
    if args.plot is not None:
        from strapdown_ros.report.consistency_plot import plot_consistency

        panels = average_series(results)
        terms = "modelled terms only" if args.modelled_only else "full presets"
        title = f"{args.scenario.name}: {args.runs} runs, {terms}"
        print(f"plot: {plot_consistency(panels, args.plot, title, args.convergence)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
