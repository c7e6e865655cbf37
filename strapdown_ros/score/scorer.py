"""Score an estimate in a bag against the bag's truth: the steps, in one function.

:func:`score_bag` reads the truth (``/reference/odom``), ``/tf_static`` and the estimate topic,
builds the truth at the estimate's stamps (:mod:`strapdown_ros.score.truth`: the scenario's
trajectory model tied to the published samples), moves it to the estimate's point and frame
(a lever arm and mounting relative to the reference IMU, given or from ``/tf_static``) and
computes the measures of :mod:`strapdown_ros.score.metrics`. Definitions: docs/score.md.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag.reader import BagContents, read_bag
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.rotations import (
    C_FRD_TO_FLU,
    dcm_from_euler,
    euler_from_dcm,
    rotvec_from_dcm,
)
from strapdown_ros.messages import odometry_state
from strapdown_ros.score.estimate import EstimateRows, ScoreError, StaticFrames, read_estimate
from strapdown_ros.score.metrics import (
    NeesSeries,
    OutageDrift,
    along_cross_track,
    nees,
    outage_drift,
    stats,
    time_offset_step,
)
from strapdown_ros.score.truth import PointTruth, ReferenceTruth

__all__ = ["Score", "ScoreError", "score_bag", "score_estimate"]


TRUTH_TOPIC = "/reference/odom"
TF_STATIC = "/tf_static"
#: Largest time offset the fit looks for (s); the stamps within this margin of the truth's
#: ends are left out of the fit.
MAX_OFFSET_S = 0.5
D = C_FRD_TO_FLU


@dataclass
class Score:
    """What :func:`score_bag` found: ``summary`` (the JSON document) and the series."""

    summary: dict[str, Any]
    stamps_ns: NDArray[np.int64]
    position_ned: F64
    along: F64
    cross: F64
    velocity_ned: F64 | None
    attitude_young: F64 | None
    outages: list[OutageDrift] = field(default_factory=list)
    nees: dict[str, NeesSeries] = field(default_factory=dict)
    start_ns: int = 0

    def write_json(self, path: str | os.PathLike[str]) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.summary, indent=2) + "\n")
        return path


@dataclass(frozen=True)
class EstimatePoint:
    """Where the estimate is: lever arm (m, FRD of the reference IMU), ``C_P^B`` and how it was
    found."""

    lever_arm_frd: F64
    c_p_b: F64
    source: str
    frame: str | None


def estimate_point(
    frames: StaticFrames,
    truth_frame: str,
    estimate: EstimateRows,
    frame: str | None,
    lever_arm: Sequence[float] | None,
    mounting_rph_deg: Sequence[float] | None,
) -> EstimatePoint:
    """The estimate's point and axes relative to the truth's body (the reference IMU, FRD).

    ``lever_arm`` (FRD m) and ``mounting_rph_deg`` (roll, pitch, yaw of the estimate's FRD axes
    relative to the IMU's) when given; else the static transform of ``frame`` (default the
    estimate's ``child_frame_id``) relative to ``truth_frame`` on ``/tf_static`` (FLU, turned
    into FRD: ``l = D p``, ``C_P^B = D C D``); else the reference IMU itself.
    """
    if lever_arm is not None or mounting_rph_deg is not None:
        lever = np.asarray(lever_arm if lever_arm is not None else (0, 0, 0), dtype=np.float64)
        rph = np.radians(np.asarray((0, 0, 0) if mounting_rph_deg is None else mounting_rph_deg,
                                    dtype=np.float64))
        if lever.shape != (3,) or rph.shape != (3,):
            raise ScoreError("lever arm and mounting need 3 values each")
        return EstimatePoint(lever, dcm_from_euler(*rph), "given", frame)
    name = frame or estimate.child_frame_id
    if name and name != truth_frame:
        try:
            p, c = frames.relative(name, truth_frame)
        except ScoreError:
            if frame is not None:  # asked for by name: an error, not a guess
                raise
        else:
            return EstimatePoint(D @ p, D @ c @ D, "/tf_static", name)
    return EstimatePoint(np.zeros(3), np.eye(3), "the reference IMU (no lever arm)", name)


def _ned_errors(est: EstimateRows, truth: PointTruth) -> tuple[F64, F64 | None, F64 | None, F64]:
    """Position, velocity, attitude errors (docs/score.md) and the true NED velocity."""
    lat, lon, _ = truth.geodetic
    v_true, c_true = truth.ned()
    dr = position_error_ned(est.r_e, truth.r_e, lat, lon)
    dv = datt = None
    if est.v_e is not None or est.c_b_e is not None:
        lat_e, lon_e, _ = ecef_to_geodetic(est.r_e)
        c_e_n_est = dcm_ecef_to_ned(lat_e, lon_e)
        if est.v_e is not None:
            dv = velocity_error_ned(np.einsum("nij,nj->ni", c_e_n_est, est.v_e), v_true)
        if est.c_b_e is not None:
            datt = attitude_error_young(c_e_n_est @ est.c_b_e, c_true)
    return dr, dv, datt, v_true


def _fit_offset(est: EstimateRows, truth: ReferenceTruth, point: EstimatePoint,
                iterations: int = 8) -> dict[str, Any]:  # fmt: skip
    """Constant time offset δt (s): the estimate stamped t is the truth at t − δt
    (Gauss–Newton on the position error, :func:`~strapdown_ros.score.metrics.time_offset_step`)."""
    margin = int(MAX_OFFSET_S * 1e9)
    keep = (est.stamps_ns >= truth.first_ns + margin) & (est.stamps_ns <= truth.last_ns - margin)
    if keep.sum() < 3:
        return {"offset_s": None, "sigma_s": None, "samples": int(keep.sum()),
                "note": f"fewer than 3 estimates {MAX_OFFSET_S} s inside the truth"}  # fmt: skip
    rows = est.select(keep)
    delta, sigma, done = 0.0, float("inf"), 0
    while done < iterations:
        done += 1
        pt = truth.at(rows.stamps_ns, shift_s=delta).at_lever_arm(point.lever_arm_frd, point.c_p_b)
        lat, lon, _ = pt.geodetic
        dr = position_error_ned(rows.r_e, pt.r_e, lat, lon)
        step, sigma = time_offset_step(dr, pt.ned()[0])
        delta += step
        if abs(delta) > MAX_OFFSET_S:
            return {"offset_s": None, "sigma_s": None, "samples": len(rows),
                    "note": f"no offset within ±{MAX_OFFSET_S} s"}  # fmt: skip
        if abs(step) < 1e-12:
            break
    return {"offset_s": delta, "sigma_s": sigma, "samples": len(rows), "iterations": done}


def _outage_windows(scenario: Any, bag: BagContents, start_ns: int) -> list[tuple[int, int]]:
    """GNSS outages (``[start, end)`` stamps): the scenario's, else the bag's metadata."""
    if scenario is not None:
        gnss = scenario.aiding.gnss if scenario.aiding is not None else None
        return [] if gnss is None or not gnss.enabled else gnss.outage_windows_ns(start_ns)
    aiding = bag.custom_data.get("aiding")
    if not aiding:
        return []
    gnss = json.loads(aiding).get("gnss") or {}
    return [(start_ns + int(round(a * 1e9)), start_ns + int(round(b * 1e9)))
            for a, b in gnss.get("outages", [])]  # fmt: skip


def _nees_all(
    est: EstimateRows, dr: F64, dv: F64 | None, truth: PointTruth
) -> dict[str, NeesSeries]:
    """NEES of position, attitude, pose (6) and velocity where covariances are given; errors and
    covariances in NED of the true position (attitude: the rotation vector of
    ``C_B^N(est) C_B^N(true)ᵀ``)."""
    out: dict[str, NeesSeries] = {}
    lat, lon, _ = truth.geodetic
    c_e_n = dcm_ecef_to_ned(lat, lon)
    ct = np.swapaxes(c_e_n, -1, -2)
    if est.pose_cov_e is not None:
        big = np.zeros((len(est), 6, 6))
        big[:, :3, :3] = big[:, 3:, 3:] = c_e_n
        cov = big @ est.pose_cov_e @ np.swapaxes(big, -1, -2)
        if np.isfinite(cov[:, :3, :3]).all(axis=(1, 2)).any():
            out["position"] = nees("position", dr, cov[:, :3, :3])
        if est.c_b_e is not None and np.isfinite(cov[:, 3:, 3:]).all(axis=(1, 2)).any():
            phi_e = rotvec_from_dcm(est.c_b_e @ np.swapaxes(truth.c_b_e, -1, -2))
            phi = np.einsum("nij,nj->ni", c_e_n, phi_e)
            out["attitude"] = nees("attitude", phi, cov[:, 3:, 3:])
            if np.isfinite(cov).all(axis=(1, 2)).any():
                out["pose"] = nees("pose", np.hstack([dr, phi]), cov)
    if est.vel_cov_e is not None and dv is not None:
        cov_v = c_e_n @ est.vel_cov_e @ ct
        if np.isfinite(cov_v).all(axis=(1, 2)).any():
            out["velocity"] = nees("velocity", dv, cov_v)
    return out


def _axes_stats(x: F64, names: Sequence[str]) -> dict[str, Any]:
    return {n: stats(x[:, i]) for i, n in enumerate(names)}


def score_estimate(
    est: EstimateRows,
    truth: ReferenceTruth,
    point: EstimatePoint,
    outages: list[tuple[int, int]] = (),  # type: ignore[assignment]
    meta: dict[str, Any] | None = None,
) -> Score:
    """Score estimate rows against the truth (the core of :func:`score_bag`)."""
    inside = (est.stamps_ns >= truth.first_ns) & (est.stamps_ns <= truth.last_ns)
    order_ok = bool(np.all(np.diff(est.stamps_ns) > 0))
    if not inside.any():
        raise ScoreError(f"no estimate stamp within the truth ({truth.first_ns} .. "
                         f"{truth.last_ns} ns)")  # fmt: skip
    rows = est.select(inside)
    if not order_ok:  # sort; repeated stamps kept (each scored)
        rows = rows.select(np.argsort(rows.stamps_ns, kind="stable"))
    pt = truth.at(rows.stamps_ns).at_lever_arm(point.lever_arm_frd, point.c_p_b)
    dr, dv, datt, v_true = _ned_errors(rows, pt)
    along, cross = along_cross_track(dr, v_true)
    drifts = outage_drift(rows.stamps_ns, dr, pt.r_e, list(outages))
    nees_all = _nees_all(rows, dr, dv, pt)
    offset = _fit_offset(rows, truth, point)
    summary: dict[str, Any] = dict(meta or {})
    summary.update({
        "estimate_type": rows.msgtype,
        "estimate_frame_id": rows.frame_id,
        "estimate_child_frame_id": rows.child_frame_id,
        "point": {"lever_arm_frd_m": point.lever_arm_frd.tolist(),
                  "mounting_rph_deg": np.degrees(euler_from_dcm(point.c_p_b)).tolist(),
                  "from": point.source, "frame": point.frame},
        "truth_between_samples": "trajectory model" if truth.exact_between_samples
        else "cubic Hermite (no trajectory model: pass --scenario)",
        "samples": len(rows),
        "outside_truth": int((~inside).sum()),
        "stamps_sorted": not order_ok,
        "first_stamp_ns": int(rows.stamps_ns[0]),
        "last_stamp_ns": int(rows.stamps_ns[-1]),
        "position_error_m": {
            **_axes_stats(dr, ("north", "east", "down")),
            "horizontal": stats(np.hypot(dr[:, 0], dr[:, 1])),
            "along_track": stats(along),
            "cross_track": stats(cross),
        },
        "velocity_error_mps": None if dv is None else _axes_stats(dv, ("north", "east", "down")),
        "attitude_error_rad": None if datt is None else _axes_stats(datt, ("up", "east", "north")),
        "outages": [asdict(o) for o in drifts],
        "nees": {k: {"dof": s.dof, "samples": s.count, "mean": s.mean, "inside_95": s.inside_95,
                     "bounds_95": list(s.bounds_95)} for k, s in nees_all.items()},
        "time_offset": offset,
    })  # fmt: skip
    return Score(summary, rows.stamps_ns, dr, along, cross, dv, datt, drifts, nees_all,
                 truth.t0_ns)  # fmt: skip


def _tf_static(bag: BagContents) -> Any:
    tf = bag.topics.get(TF_STATIC)
    return tf.fields if tf is not None and tf.fields is not None else None


def score_bag(
    bag: str | os.PathLike[str],
    topic: str,
    *,
    estimate_bag: str | os.PathLike[str] | None = None,
    scenario: Any = None,
    truth_topic: str = TRUTH_TOPIC,
    frame: str | None = None,
    lever_arm: Sequence[float] | None = None,
    mounting_rph_deg: Sequence[float] | None = None,
    shift_ns: int = 0,
) -> Score:
    """Score the estimate on ``topic`` (in ``estimate_bag``, default ``bag``) against the truth
    of ``bag``.

    ``scenario``: the validated :class:`~strapdown_ros.config.Scenario` the bag was generated
    from (its trajectory model fills the truth between samples; its GNSS outages are scored);
    None: Hermite between samples, outages from the bag's metadata. ``frame``/``lever_arm``/
    ``mounting_rph_deg``: the estimate's point (:func:`estimate_point`). ``shift_ns``: added to
    the estimate's stamps before scoring (studies of the time offset).
    """
    truth_bag = read_bag(bag, None)
    if truth_topic not in truth_bag.topics:
        raise ScoreError(f"truth topic {truth_topic!r} not in bag {bag}")
    est_bag = truth_bag if estimate_bag is None else read_bag(estimate_bag, None)
    frames = StaticFrames(_tf_static(truth_bag))
    if est_bag is not truth_bag and _tf_static(est_bag) is not None:
        frames.add(_tf_static(est_bag))  # the user's frames (e.g. base_link -> antenna)
    odom = truth_bag[truth_topic]
    st = odometry_state(odom)  # type: ignore[arg-type]
    trajectory, t0_ns = None, int(st.stamps_ns[0])
    if scenario is not None:
        from strapdown_ros.plan import resolve_plan

        plan = resolve_plan(scenario, topics=False)
        t0_ns = plan.start_ns
        period = int(st.stamps_ns[1] - st.stamps_ns[0])
        if int(st.stamps_ns[0]) != t0_ns or period != plan.period_ns:
            raise ScoreError(
                f"the scenario {scenario.name!r} does not match the bag's truth (first stamp "
                f"{int(st.stamps_ns[0])} vs {t0_ns} ns, period "
                f"{period} vs {plan.period_ns} ns)"
            )
        if truth_topic == scenario.recording.topics["reference_odom"]:
            trajectory = plan.trajectory
    truth = ReferenceTruth(st.stamps_ns, st.r_e, st.v_e, st.c_b_e, st.omega_eb_b, trajectory,
                           t0_ns)  # fmt: skip
    if trajectory is not None:  # the model must be the bag's: the published samples agree
        dr, dv, _ = truth.deltas()
        worst = float(np.max(np.linalg.norm(dr, axis=1)))
        if worst > 1e-3:
            raise ScoreError(f"the scenario's trajectory is {worst:.3g} m from the bag's truth "
                             "(not the scenario this bag was generated from?)")  # fmt: skip
    est = read_estimate(est_bag, topic, frames)
    if shift_ns:
        est = est.shifted(shift_ns)
    point = estimate_point(frames, odom.child_frame_id, est, frame, lever_arm, mounting_rph_deg)
    meta = {"bag": str(bag), "estimate_bag": str(estimate_bag or bag), "estimate_topic": topic,
            "truth_topic": truth_topic, "scenario": getattr(scenario, "name", None) or
            truth_bag.custom_data.get("scenario"), "shift_ns": int(shift_ns)}  # fmt: skip
    return score_estimate(est, truth, point, _outage_windows(scenario, truth_bag, t0_ns), meta)
