"""Benchmark: the aided filter side by side with pyins' feedback filter; cost and memory.

**Side by side** (skip with ``--no-pyins``): one run of test/data/aided_car_noisy.yaml's drive
(``--compare`` s, default 300; the tunnel outage kept) with the IMU errors both filters model
(turn-on biases, angle/velocity random walk; everything else off) and GNSS position and
velocity with white errors only (no Gauss–Markov part, no latency); the wheel is not used. The
chain makes the measured IMU and the GNSS messages once; then, in this process, our
:class:`AidedStage` and pyins' ``filters.run_feedback_filter`` (python-ins 1.0.1) take the same
increments (pyins' Δv resolved at the start of the interval, ``G_V(Δα) Δv``, Savage 2020
eq. (3)) and the same fixes (pyins ``Position`` and ``NedVelocity`` with the lever arm and the
per-axis R of the messages), the same initial σ, covariance step 0.1 s and IMU error model.
pyins starts at the truth, ours at truth plus a draw from P0. Timed: each filter's call only,
as process CPU time (both are single-threaded; CPU time is robust to a shared machine's load);
our JIT warmed by a first run, pyins' numba kernels by a 10 s run. Printed: time of each and
``speedup_vs_pyins``, position RMS (3-D, at the 10 Hz epochs) of each and
``position_rms_ratio`` (ours / pyins). pyins uses its own gravity model (Somigliana normal
gravity) on increments made with J2 gravitation; its filter absorbs the difference.

**Cost and memory** (ours only, skip with ``--no-cost``): the filter of
test/data/aided_car_noisy.yaml (100 Hz industrial IMU, 1 Hz GNSS position and velocity, 10 Hz
wheel speed; 10 Hz outputs) on a cruise of ``--short`` and ``--long`` seconds (a single
10 m/s segment turning at 0.2 °/s, trajectory replaced). The inputs are made piece by piece by
the chain (trajectory, imu_errors, aiding); only the :class:`AidedStage` calls are timed
(process CPU time; JIT warmed by a 10 s run first). Printed per duration: stage seconds, µs
per IMU cycle, the process's resident memory after the first piece and at the end; then
``cost_ratio`` = (µs/cycle long) / (µs/cycle short) (1 = linear) and the RSS growth of the
long run.

Run: ``.venv/bin/python bench/bench_aided.py [--compare 300] [--short 600] [--long 3600]``.
"""

from __future__ import annotations

import argparse
import gc
import resource
import time
from pathlib import Path

import numpy as np

from strapdown_ros.config.scenario import apply_overrides, parse_scenario, read_document
from strapdown_ros.plan import resolve_plan
from strapdown_ros.plan.chain import feed_stages, offline_stages
from strapdown_ros.stages.aided import AidedStage
from strapdown_ros.stages.trajectory import reference_batch_chunks

SCENARIO = Path(__file__).resolve().parents[1] / "test" / "data" / "aided_car_noisy.yaml"


def _rss_mib() -> float:
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def run(duration_s: float) -> dict[str, float]:
    """One run: stage time, cycles, RSS after the first piece and at the end."""
    doc = read_document(SCENARIO)
    doc["trajectory"] = {"kind": "segments", "segments": [
        {"duration_s": duration_s, "heading_rate_dps": 0.2}]}  # fmt: skip
    doc["initial"]["velocity_ned_mps"] = [0.0, 10.0, 0.0]
    doc["aiding"]["gnss"]["outages"] = []
    doc = apply_overrides(doc, [f"duration_s={duration_s:g}"])
    scenario = parse_scenario(doc)
    upstream = offline_stages(resolve_plan(scenario), ["imu_errors", "aiding"])
    stage = AidedStage(scenario)
    spent = 0.0
    rss_first = None
    for _, batches in reference_batch_chunks(scenario):
        batches = feed_stages(upstream, batches)
        t = time.process_time()
        stage.feed_batches(batches)
        spent += time.process_time() - t
        if rss_first is None:
            gc.collect()
            rss_first = _rss_mib()
    t = time.process_time()
    stage.flush()
    spent += time.process_time() - t
    gc.collect()
    cycles = duration_s * 1e9 / scenario.period_ns
    return {"seconds": spent, "us_per_cycle": 1e6 * spent / cycles, "cycles": cycles,
            "rss_first": float(rss_first or 0.0), "rss_end": _rss_mib()}  # fmt: skip


#: IMU errors both filters model (industrial-grade values, docs/imu_errors.md).
GYRO_BIAS_DPH, ARW_DPSH, ACCEL_BIAS_MG, VRW_MPSPH = 20.0, 0.2, 2.0, 0.04
GNSS_POS_M, GNSS_VEL_MPS = [0.5, 0.5, 1.0], [0.05, 0.05, 0.1]


def compare_document(duration_s: float) -> dict:
    doc = read_document(SCENARIO)
    doc["duration_s"] = duration_s
    doc["imu_errors"] = {
        "seed": 3, "input_topic": "/reference/imu", "output_topic": "/reference/imu_measured",
        "gyro_turn_on_bias_sigma_dph": GYRO_BIAS_DPH, "gyro_arw_dpsh": ARW_DPSH,
        "accel_turn_on_bias_sigma_mg": ACCEL_BIAS_MG, "accel_vrw_mpsph": VRW_MPSPH,
    }  # fmt: skip
    g = doc["aiding"]["gnss"]
    doc["aiding"] = {"gnss": {"rate_hz": g["rate_hz"], "lever_arm_m": g["lever_arm_m"],
                              "outages": g.get("outages", []), "seed": 1,
                              "position_white_m": GNSS_POS_M,
                              "velocity_white_mps": GNSS_VEL_MPS}}  # fmt: skip
    doc["aided"] = {"seed": 4, "sensors": ["gnss_position", "gnss_velocity"],
                    "initial_sigma": {"position_m": 1.0, "velocity_mps": 0.1,
                                      "attitude_deg": [0.05, 0.05, 0.2]}}  # fmt: skip
    return doc


def compare(duration_s: float) -> None:
    """Ours and pyins on the same data (see the module docstring)."""
    import pandas as pd
    from pyins import filters, inertial_sensor, measurements

    from strapdown_ros.bag import cdr
    from strapdown_ros.bag.batches import Batch
    from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic, geodetic_to_ecef
    from strapdown_ros.core.exact_update import g_v
    from strapdown_ros.core.rotations import euler_from_dcm
    from strapdown_ros.messages import imu_increments, odometry_state

    scenario = parse_scenario(compare_document(duration_s))
    upstream = offline_stages(resolve_plan(scenario), ["imu_errors", "aiding"])
    pieces = [feed_stages(upstream, b) for _, b in reference_batch_chunks(scenario)]
    t0, T = scenario.start_time_ns, scenario.period_ns

    def ours() -> tuple[float, dict[str, list]]:
        stage = AidedStage(scenario)
        out: dict[str, list] = {}
        t = time.process_time()
        res = [b for p in pieces for b in stage.feed_batches(p)] + stage.flush()
        spent = time.process_time() - t
        for b in res:
            out.setdefault(b.topic, []).extend(b.payloads)
        return spent, out

    ours()  # JIT (cache) warm-up
    t_ours, out = ours()
    # the same inputs, decoded for pyins (not timed)
    by_topic: dict[str, list[Batch]] = {}
    for p in pieces:
        for b in p:
            by_topic.setdefault(b.topic, []).append(b)

    def fields(topic: str, msgtype: str):
        return cdr.deserialize(msgtype, [x for b in by_topic[topic] for x in b.payloads])

    imu = imu_increments(fields("/reference/imu_measured", cdr.IMU), T)
    truth = odometry_state(fields("/reference/odom", cdr.ODOMETRY))
    fix = fields("/gnss/fix", cdr.NAVSATFIX)
    vel = fields("/gnss/vel", cdr.TWIST_WITH_COVARIANCE_STAMPED)
    m_imu = (np.asarray(imu.stamps_ns) - t0) // T
    inc = pd.DataFrame(
        np.hstack([np.full((len(m_imu), 1), T * 1e-9), imu.dalpha,
                   (g_v(imu.dalpha) @ imu.dv[..., None])[..., 0]]),
        index=pd.Index(m_imu * (T * 1e-9), name="time"),
        columns=["dt", "theta_x", "theta_y", "theta_z", "dv_x", "dv_y", "dv_z"])  # fmt: skip
    m_fix = (np.asarray(fix.stamps_ns) - t0) // T
    pos = pd.DataFrame({"lat": fix.latitude, "lon": fix.longitude, "alt": fix.altitude},
                       index=m_fix * (T * 1e-9))  # fmt: skip
    m_vel = (np.asarray(vel.stamps_ns) - t0) // T
    v_enu = np.asarray(vel.linear)
    vdf = pd.DataFrame({"VN": v_enu[:, 1], "VE": v_enu[:, 0], "VD": -v_enu[:, 2]},
                       index=m_vel * (T * 1e-9))  # fmt: skip
    lever = np.array(scenario.aiding.gnss.lever_arm_m)  # type: ignore[union-attr]
    p_meas = measurements.Position(pos, 1.0, lever)
    p_meas.R = np.diag(np.square(GNSS_POS_M))
    v_meas = measurements.NedVelocity(vdf, 1.0, lever)
    v_meas.R = np.diag(np.square(GNSS_VEL_MPS))
    lat0, lon0, alt0 = (float(x[0]) for x in ecef_to_geodetic(truth.r_e[:1]))
    c_en0 = dcm_ecef_to_ned(lat0, lon0)
    v0 = c_en0 @ truth.v_e[0]
    rph = np.degrees(euler_from_dcm(c_en0 @ truth.c_b_e[0]))
    pva0 = pd.Series([np.degrees(lat0), np.degrees(lon0), alt0, *v0, *rph],
                     index=["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch", "heading"],
                     name=0.0)  # fmt: skip
    d2r = np.pi / 180.0

    def models():
        g = inertial_sensor.EstimationModel(bias_sd=GYRO_BIAS_DPH * d2r / 3600,
                                            noise=ARW_DPSH * d2r / 60)  # fmt: skip
        a = inertial_sensor.EstimationModel(bias_sd=ACCEL_BIAS_MG * 1e-3 * 9.80665,
                                            noise=VRW_MPSPH / 60)  # fmt: skip
        return g, a

    def pyins_run(increments):
        g, a = models()
        return filters.run_feedback_filter(pva0, 1.0, 0.1, 0.05, 0.2, increments, g, a,
                                           [p_meas, v_meas], time_step=0.1)  # fmt: skip

    pyins_run(inc.iloc[: int(10e9 // T)])  # numba warm-up
    t = time.process_time()
    res = pyins_run(inc)
    t_pyins = time.process_time() - t
    # position RMS at the 10 Hz epochs against the truth
    m_truth = (np.asarray(truth.stamps_ns) - t0) // T
    epochs = m_truth[m_truth % (int(1e8) // T) == 0]
    r_true = truth.r_e[np.searchsorted(m_truth, epochs)]
    lat, lon, _ = ecef_to_geodetic(r_true)
    cen = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
    odom = odometry_state(cdr.deserialize(cdr.ODOMETRY, out["/aided/odom"]))
    m_ours = (np.asarray(odom.stamps_ns) - t0) // T
    e_ours = np.einsum("kij,kj->ki", cen,
                       odom.r_e[np.searchsorted(m_ours, epochs)] - r_true)  # fmt: skip
    trj = res.trajectory.loc[epochs * (T * 1e-9)]
    r_py = geodetic_to_ecef(np.radians(trj["lat"].to_numpy()), np.radians(trj["lon"].to_numpy()),
                            trj["alt"].to_numpy())  # fmt: skip
    e_py = np.einsum("kij,kj->ki", cen, r_py - r_true)
    rms_ours = float(np.sqrt(np.mean(np.sum(e_ours**2, axis=1))))
    rms_py = float(np.sqrt(np.mean(np.sum(e_py**2, axis=1))))
    n = len(m_imu)
    print(f"side by side: {duration_s:g} s at {1e9 / T:g} Hz ({n} increments), GNSS position + "
          f"velocity at {scenario.aiding.gnss.rate_hz:g} Hz")  # type: ignore[union-attr]
    print(f"  ours  {t_ours:8.3f} s ({1e6 * t_ours / n:7.2f} µs/cycle), position RMS "
          f"{rms_ours:.4f} m")
    print(f"  pyins {t_pyins:8.3f} s ({1e6 * t_pyins / n:7.2f} µs/cycle), position RMS "
          f"{rms_py:.4f} m")
    print(f"speedup_vs_pyins: {t_pyins / t_ours:.1f} x")
    print(f"position_rms_ratio (ours / pyins): {rms_ours / rms_py:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare", type=float, default=300.0, help="side-by-side duration (s)")
    ap.add_argument("--no-pyins", action="store_true", help="cost and memory only")
    ap.add_argument("--no-cost", action="store_true", help="side by side only")
    ap.add_argument("--short", type=float, default=600.0)
    ap.add_argument("--long", type=float, default=3600.0)
    args = ap.parse_args()
    if not args.no_pyins:
        compare(args.compare)
    if args.no_cost:
        return
    run(10.0)  # JIT (cache) warm-up
    out = {}
    for d in (args.short, args.long):
        r = out[d] = run(d)
        print(f"{d:7.0f} s: stage {r['seconds']:7.2f} s, {r['us_per_cycle']:6.2f} µs/cycle, "
              f"RSS after first piece {r['rss_first']:7.1f} MiB, at end {r['rss_end']:7.1f} MiB")
    s, lg = out[args.short], out[args.long]
    print(f"cost_ratio (µs/cycle {args.long:g} s / {args.short:g} s): "
          f"{lg['us_per_cycle'] / s['us_per_cycle']:.3f} x")
    print(f"rss_growth_long: {lg['rss_end'] - lg['rss_first']:.1f} MiB over {args.long:g} s")


if __name__ == "__main__":
    main()
