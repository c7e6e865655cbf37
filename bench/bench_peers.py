"""Benchmark: this project side by side with pyins (python-ins 1.0.1) on the same motion.

pyins (github.com/nmayorov/pyins) generates IMU readings from splines of a trajectory and
integrates them with a single-rate Savage-style NED integrator. In one process:

1. **pyins generation**: ``sim.generate_sine_velocity_motion(0.01, 3600, [55, 37, 1500],
   [5, -3, 0.2], velocity_change_amplitude=1, sensor_type='increment')``: its truth (time,
   lat/lon/alt, roll/pitch/heading, NED velocity) and its increment readings.
2. **our generation** from pyins' truth: the truth DataFrame → ``samples_from_arrays`` → a
   ``samples`` trajectory (Giribet B-spline fit, options from an in-memory scenario) →
   ``generate_reference`` (Method 2 regeneration; docs/interface.md §3 exact). Timed from the
   DataFrame.
3. **navigation**, each tool with its own navigator on its own data: pyins
   ``compute_increments_from_imu`` + ``Integrator.integrate``; ours ``navigate_multirate``
   (``mode="exact"``, N = T_nav/T_gyr, P = T_nav/T_int). The first call in this process includes
   each navigator's one-time numba JIT compile (numba's cache points to an empty directory for
   this run); navigation times are the best of the calls after it. All times are best-of
   ``--repeats`` with the tools called in turn (load changes on a shared machine hit both).
4. **cross runs**, to separate data quality from navigator quality, each against the truth of
   the data navigated:

   * A: our navigator on pyins' readings as given (A'), gravity-matched, and (A") after pyins'
     own two-sample coning/sculling compensation (``compute_increments_from_imu``), mapped to
     constant-rate increments (θ, ``Δv = G_V(θ)⁻¹ Δv_start``: pyins' Δv is resolved in the
     body axes at the start of the interval, ours in the Savage 2020 eq. (3) form);
   * B: pyins' integrator on our increments through ``compute_increments_from_imu`` (B'),
     gravity-matched, and (B") as the exact increments of the constant-rate model
     (``θ = Δα``, ``Δv_start = G_V(Δα) Δv``), gravity-matched.

   *Gravity-matched*: the tools use different gravity models (pyins: Somigliana normal
   gravity along the ellipsoid normal with a ``1 - 2h/a`` height factor; ours: the docs/interface.md
   §1 J2
   gravitation plus the centrifugal term), so the increments are moved to the navigator's
   model, ``Δv' = Δv ± ∫ C_N^B (g_pyins − g_ours)^N dt`` (trapezoid at the truth samples; the
   term is ~1e-7 m/s per step and the trapezoid's error ~1e-15 m/s).

Closure errors are taken at our navigator's last output (``t = (M // N) N T``) in every row:
horizontal and down position error (NED of the true position, from ECEF differences), the
attitude error angle (norm of Young's error angles, docs/interface.md §4) and the velocity error
norm.

Usage: python bench/bench_peers.py [--duration-s 3600] [--n 10] [--p 10] [--repeats 3]
       [--every 1] [--coarse 10]
``--every K`` feeds every K-th pyins truth sample to our fit (1 = all of them, the default);
``--coarse K`` adds a row fed every K-th sample (0: no such row).
Last line: ``speedup_vs_pyins: X x`` = (pyins generation + navigation) / (ours), best-of times,
JIT compilation excluded, our reference fitted to the ``--every`` feed. The line before,
``speedup_vs_pyins_fresh_process``: the same ratio for each tool's first generation +
navigation in a fresh process (JIT included; our numba cache warm, pyins has none), best of
four child processes per tool (the tools in either order, twice).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PERIOD = 0.01  # s, pyins' dt (100 Hz)
LLA0 = [55.0, 37.0, 1500.0]  # deg, deg, m
VELOCITY_MEAN = [5.0, -3.0, 0.2]  # m/s NED
#: Giribet fit of the ``samples`` trajectory (a scenario's ``trajectory`` mapping). pyins' truth
#: is noise-free: weights 1/(1 mm)² for position, 1/(1 mm/s)² for velocity, 1/(10 µrad)² for
#: attitude; knots at the default spacing (8 sample intervals).
FIT_CONFIG = {
    "kind": "samples",
    "file": "pyins_truth.csv",  # never read: the samples are handed over as arrays
    "weights": {"position": 1.0e6, "velocity": 1.0e6, "attitude": 1.0e10},
}
TRUTH_COLS = ["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch", "heading"]


@dataclass
class Closure:
    """Errors at the closure instant (navigation minus truth)."""

    horizontal: float  # m
    down: float  # m, NED down component
    attitude: float  # rad, norm of Young's (θ1, θ2, θ3)
    velocity: float  # m/s, norm


def interleaved(fns: dict, repeats: int) -> dict:
    """Best time and last result of each function, the functions called in turn.

    Alternating the tools (pyins, ours, pyins, ours, ...) makes load changes on a shared
    machine hit both alike; the best of ``repeats`` is kept for each.
    """
    best = {k: (np.inf, None) for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            out = fn()
            best[k] = (min(best[k][0], time.perf_counter() - t0), out)
    return best


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def fresh_process_child(order: str, truth_file: str, every: int, n: int, p: int) -> None:
    """One fresh process: each tool's *first* generation + navigation, the JIT included.

    Our numba cache (``NUMBA_CACHE_DIR``, inherited from the parent) is warm; pyins' kernels
    are not cached by pyins (``numba.njit()`` without ``cache``), so it compiles in every new
    process. Imports are not timed. Prints one JSON line ``{"pyins": s, "ours": s}``.
    """
    import json
    import pickle

    from pyins import sim, strapdown

    from strapdown_ros.config import parse_scenario
    from strapdown_ros.core.navigation import NavState, navigate_multirate, truth_navigation
    from strapdown_ros.core.trajectory.samples import SamplesTrajectory, samples_from_arrays
    from strapdown_ros.stages.trajectory import generate_reference

    with open(truth_file, "rb") as fh:
        duration_s, ref = pickle.load(fh)
    d2r = np.pi / 180.0
    scenario = parse_scenario(
        {"name": "pyins_sine_velocity", "rate_hz": round(1.0 / PERIOD), "trajectory": FIT_CONFIG}
    )

    def pyins_run() -> None:
        truth, imu = sim.generate_sine_velocity_motion(
            PERIOD, duration_s, LLA0, VELOCITY_MEAN,
            velocity_change_amplitude=1, sensor_type="increment",
        )  # fmt: skip
        increments = strapdown.compute_increments_from_imu(imu, "increment")
        strapdown.Integrator(truth.iloc[0]).integrate(increments)

    def ours_run() -> None:
        truth = ref.iloc[::every] if every > 1 else ref
        t = truth.index.to_numpy(dtype=np.float64)
        a = truth[TRUTH_COLS].to_numpy()
        samples = samples_from_arrays(
            t - t[0],
            lat=a[:, 0] * d2r, lon=a[:, 1] * d2r, alt=a[:, 2], v_ned=a[:, 3:6],
            roll=a[:, 6] * d2r, pitch=a[:, 7] * d2r, heading=a[:, 8] * d2r,
        )  # fmt: skip
        stream = generate_reference(
            scenario, SamplesTrajectory(samples, scenario.trajectory.fit_options())
        )
        _, lat, lon, alt, v, q = truth_navigation(stream, np.array([0]))  # start: the truth
        st0 = NavState(0.0, float(lat[0]), float(lon[0]), float(alt[0]), v[0].copy(), q[0])
        navigate_multirate(
            st0, stream.dalpha, stream.dv, PERIOD, n, p, gravity_model="j2", mode="exact"
        )

    runs = {"pyins": pyins_run, "ours": ours_run}
    out = {}
    for name in order.split(","):
        t0 = time.perf_counter()
        runs[name]()
        out[name] = time.perf_counter() - t0
    print(json.dumps(out))


def fresh_process_ratio(
    duration_s: float, ref, every: int, n: int, p: int, cache_dir: str, rounds: int = 2
) -> list[dict[str, float]]:
    """:func:`fresh_process_child` in 2 x ``rounds`` fresh processes (both orders), warm cache."""
    import json
    import pickle
    import subprocess

    times = []
    with tempfile.TemporaryDirectory(prefix="bench_peers_truth_") as tmp:
        truth_file = str(Path(tmp) / "truth.pkl")
        with open(truth_file, "wb") as fh:
            pickle.dump((duration_s, ref), fh)
        for order in ("pyins,ours", "ours,pyins") * rounds:
            cmd = [sys.executable, __file__, "--fresh-child", order, truth_file,
                   "--every", str(every), "--n", str(n), "--p", str(p)]  # fmt: skip
            env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
            res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            times.append(json.loads(res.stdout.strip().splitlines()[-1]))
    return times


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration-s", type=float, default=3600.0)
    parser.add_argument("--n", type=int, default=10, help="N = T_nav / T_gyr of our navigator")
    parser.add_argument("--p", type=int, default=10, help="P = T_nav / T_int of our navigator")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (best of)")
    parser.add_argument("--every", type=int, default=1, help="feed every K-th truth sample")
    parser.add_argument("--coarse", type=int, default=10, help="extra row: every K-th sample")
    parser.add_argument(
        "--fresh-child", nargs=2, metavar=("ORDER", "TRUTH"), help=argparse.SUPPRESS
    )
    args = parser.parse_args(argv)
    if args.fresh_child:
        fresh_process_child(*args.fresh_child, args.every, args.n, args.p)
        return 0.0
    if args.every < 1 or args.coarse < 0 or args.n < 1 or args.p < 1:
        parser.error("--every, --n and --p must be >= 1, --coarse >= 0")

    # Cold JIT for both navigators: numba reads its cache directory when it is first imported.
    cache = tempfile.TemporaryDirectory(prefix="bench_peers_numba_")
    os.environ["NUMBA_CACHE_DIR"] = cache.name
    try:
        import pandas as pd
        from pyins import earth as pyins_earth
        from pyins import sim, strapdown
    except ImportError as exc:
        raise SystemExit(
            f"bench_peers: {exc}. pyins is a benchmark-only dependency: `make bench` installs "
            "requirements/bench.txt (or: pip install -r requirements/bench.txt "
            "-c requirements/constraints.txt)"
        ) from None
    import numba

    from strapdown_ros.config import parse_scenario
    from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef
    from strapdown_ros.core.exact_update import g_v
    from strapdown_ros.core.gravity import gravity_ned
    from strapdown_ros.core.navigation import NavState, navigate_multirate, truth_navigation
    from strapdown_ros.core.navigation.errors import navigation_errors
    from strapdown_ros.core.rotations import (
        dcm_from_euler,
        dcm_from_quat,
        euler_from_dcm,
        quat_from_dcm,
    )
    from strapdown_ros.core.trajectory.samples import SamplesTrajectory, samples_from_arrays
    from strapdown_ros.core.young import young_error_angles
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.trajectory import generate_reference

    d2r, r2d = np.pi / 180.0, 180.0 / np.pi
    n_nav, p_nav, reps = args.n, args.p, max(1, args.repeats)
    print(f"machine: {machine()}")
    print(
        f"versions: python-ins {metadata.version('python-ins')}, numpy {np.__version__}, "
        f"scipy {metadata.version('scipy')}, numba {numba.__version__}, pandas {pd.__version__}"
    )

    # ---------------------------------------------------------------------------------------
    # Generation.
    def pyins_generate():
        return sim.generate_sine_velocity_motion(
            PERIOD, args.duration_s, LLA0, VELOCITY_MEAN,
            velocity_change_amplitude=1, sensor_type="increment",
        )  # fmt: skip

    t_gen_p_first, (ref, imu) = timed(pyins_generate)
    scenario = parse_scenario(
        {"name": "pyins_sine_velocity", "rate_hz": round(1.0 / PERIOD), "trajectory": FIT_CONFIG}
    )

    def ours_generate(every: int):
        truth = ref
        if every > 1:
            truth = ref.iloc[::every]
            if truth.index[-1] != ref.index[-1]:
                truth = pd.concat([truth, ref.iloc[-1:]])  # the whole span
        t = truth.index.to_numpy(dtype=np.float64)
        a = truth[TRUTH_COLS].to_numpy()
        samples = samples_from_arrays(
            t - t[0],
            lat=a[:, 0] * d2r, lon=a[:, 1] * d2r, alt=a[:, 2], v_ned=a[:, 3:6],
            roll=a[:, 6] * d2r, pitch=a[:, 7] * d2r, heading=a[:, 8] * d2r,
        )  # fmt: skip
        traj = SamplesTrajectory(samples, scenario.trajectory.fit_options())
        return traj, generate_reference(resolve_plan(scenario, traj))

    coarse_on = args.coarse > 1 and args.coarse != args.every
    gen = {"pyins": pyins_generate, "ours": lambda: ours_generate(args.every)}
    if coarse_on:
        gen["coarse"] = lambda: ours_generate(args.coarse)
    gen = interleaved(gen, reps)
    t_gen_p = min(t_gen_p_first, gen["pyins"][0])
    t_gen_o, (traj, stream) = gen["ours"]
    m_inc = stream.cycles
    if imu.shape[0] != m_inc + 1:
        raise SystemExit(f"pyins gave {imu.shape[0] - 1} increments, ours {m_inc}")
    k_end = (m_inc // n_nav) * n_nav  # truth sample of the closure instant (our last output)

    # Truth of both data sets in navigation terms (rad, m, m/s, C_B^N); not timed.
    a_p = ref[TRUTH_COLS].to_numpy()
    lat_p, lon_p, alt_p, v_p = a_p[:, 0] * d2r, a_p[:, 1] * d2r, a_p[:, 2], a_p[:, 3:6]
    c_p = dcm_from_euler(a_p[:, 6] * d2r, a_p[:, 7] * d2r, a_p[:, 8] * d2r)
    truth_p = (lat_p, lon_p, alt_p, v_p, c_p)

    def stream_truth(st):
        _, lat, lon, alt, v, q = truth_navigation(st)
        return lat, lon, alt, v, dcm_from_quat(q)

    truth_o = stream_truth(stream)

    def closure(lat, lon, alt, v, c, k: int, truth) -> Closure:
        lat_t, lon_t, alt_t, v_t, c_t = (x[k] for x in truth)
        dr = dcm_ecef_to_ned(lat_t, lon_t) @ (
            geodetic_to_ecef(lat, lon, alt) - geodetic_to_ecef(lat_t, lon_t, alt_t)
        )
        return Closure(
            float(np.hypot(dr[0], dr[1])),
            float(dr[2]),
            float(np.linalg.norm(young_error_angles(c, c_t))),
            float(np.linalg.norm(np.asarray(v, dtype=np.float64) - v_t)),
        )

    def same_motion(truth) -> tuple[float, float, float]:
        """Max deviation of a truth from pyins' truth over all samples (m, m/s, rad)."""
        lat, lon, alt, v, c = truth
        dr = geodetic_to_ecef(lat, lon, alt) - geodetic_to_ecef(lat_p, lon_p, alt_p)
        return (
            float(np.max(np.linalg.norm(dr, axis=1))),
            float(np.max(np.linalg.norm(v - v_p, axis=1))),
            float(np.max(np.linalg.norm(young_error_angles(c, c_p), axis=1))),
        )

    # ---------------------------------------------------------------------------------------
    # Navigation, each tool on its own data.
    def pyins_navigate(imu_df, pva):
        increments = strapdown.compute_increments_from_imu(imu_df, "increment")
        return strapdown.Integrator(pva).integrate(increments)

    def pyins_closure(result, truth) -> Closure:
        row = result.iloc[k_end]
        c = dcm_from_euler(row.roll * d2r, row.pitch * d2r, row.heading * d2r)
        v = row[["VN", "VE", "VD"]].to_numpy(dtype=np.float64)
        return closure(row.lat * d2r, row.lon * d2r, row.alt, v, c, k_end, truth)

    def ours_navigate(da, dv, truth, n=n_nav, p=p_nav):
        lat, lon, alt, v, c = (x[0] for x in truth)
        st0 = NavState(0.0, float(lat), float(lon), float(alt), v.copy(), quat_from_dcm(c))
        return navigate_multirate(st0, da, dv, PERIOD, n, p, gravity_model="j2", mode="exact")

    def sol_closure(sol, truth) -> Closure:
        j = k_end // sol.n
        c = dcm_from_quat(sol.q_b_n[j])
        return closure(sol.lat[j], sol.lon[j], sol.alt[j], sol.v_ned[j], c, k_end, truth)

    da_o, dv_o = stream.dalpha, stream.dv
    # First calls: the one-time JIT compile of each navigator (numba's cache dir is empty).
    t_nav_p_first, _ = timed(lambda: pyins_navigate(imu, ref.iloc[0]))
    t_nav_o_first, _ = timed(lambda: ours_navigate(da_o, dv_o, truth_o))
    nav = {
        "pyins": lambda: pyins_navigate(imu, ref.iloc[0]),
        "ours": lambda: ours_navigate(da_o, dv_o, truth_o),
    }
    if n_nav != 1 or p_nav != 1:
        nav["ours_n1"] = lambda: ours_navigate(da_o, dv_o, truth_o, 1, 1)
    if coarse_on:
        t_gen_c, (_, stream_c) = gen["coarse"]
        truth_c = stream_truth(stream_c)
        nav["coarse"] = lambda: ours_navigate(stream_c.dalpha, stream_c.dv, truth_c)
    nav = interleaved(nav, reps + 1)
    t_nav_p, res_p = nav["pyins"]
    t_nav_o, sol_o = nav["ours"]
    assert abs(res_p.index[k_end] - k_end * PERIOD) < 1e-9
    own_p = pyins_closure(res_p, truth_p)
    own_o = sol_closure(sol_o, truth_o)
    check = navigation_errors(sol_o, stream)  # the project's own error definition agrees
    assert abs(check.horizontal[-1] - own_o.horizontal) <= 1e-9 + 1e-6 * own_o.horizontal
    rows_extra = []
    if "ours_n1" in nav:
        t1, sol1 = nav["ours_n1"]
        rows_extra.append(("ours: our data, exact navigator N=1 P=1", sol_closure(sol1, truth_o),
                           None, t1))  # fmt: skip
    coarse = None
    if coarse_on:
        t_nav_c, sol_c = nav["coarse"]
        coarse = (t_gen_c, t_nav_c, same_motion(truth_c))
        rows_extra.append((
            f"ours: fit to every {args.coarse}th truth sample, N={n_nav} P={p_nav}",
            sol_closure(sol_c, truth_c), t_gen_c, t_nav_c,
        ))  # fmt: skip

    # ---------------------------------------------------------------------------------------
    # Cross runs. δg = g_pyins − g_ours (plumb-bob gravity, NED) along each truth.
    def delta_g(lat, alt):
        g = -gravity_ned(lat, alt, "j2")
        g[:, 2] += pyins_earth.gravity(lat * r2d, alt)
        return g

    def gravity_term(lat, alt, c):
        """∫ C_N^B δg^N dt over each cycle (trapezoid at the truth samples), (M, 3)."""
        w = np.einsum("nji,nj->ni", c, delta_g(lat, alt))  # (C_B^N)ᵀ δg^N
        return 0.5 * PERIOD * (w[:-1] + w[1:])

    corr_p = gravity_term(lat_p, alt_p, c_p)
    corr_o = gravity_term(truth_o[0], truth_o[2], truth_o[4])
    dg_o = delta_g(truth_o[0], truth_o[2])

    # A: our navigator on pyins' readings.
    da_p = imu[["gyro_x", "gyro_y", "gyro_z"]].to_numpy()[1:]
    dv_p = imu[["accel_x", "accel_y", "accel_z"]].to_numpy()[1:]
    cross_a = sol_closure(ours_navigate(da_p, dv_p, truth_p), truth_p)
    cross_a1 = sol_closure(ours_navigate(da_p, dv_p + corr_p, truth_p), truth_p)
    inc_p = strapdown.compute_increments_from_imu(imu, "increment")
    th_p = inc_p[["theta_x", "theta_y", "theta_z"]].to_numpy()
    dv_c = np.linalg.solve(g_v(th_p), inc_p[["dv_x", "dv_y", "dv_z"]].to_numpy()[..., None])
    cross_a2 = sol_closure(ours_navigate(th_p, dv_c[..., 0] + corr_p, truth_p), truth_p)

    # B: pyins' integrator on our increments.
    lat0, lon0, alt0, v0, c0 = (x[0] for x in truth_o)
    pva_o = pd.Series(
        np.concatenate([[lat0 * r2d, lon0 * r2d, alt0], v0, np.array(euler_from_dcm(c0)) * r2d]),
        index=TRUTH_COLS,
    )
    time_o = np.arange(m_inc + 1) * PERIOD

    def our_readings(dv):
        data = np.hstack([da_o, dv])
        return pd.DataFrame(
            np.vstack([data[:1], data]),  # pyins' convention: the first reading duplicated
            index=pd.Index(time_o, name="time"),
            columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"],
        )

    cross_b = pyins_closure(pyins_navigate(our_readings(dv_o), pva_o), truth_o)
    cross_b1 = pyins_closure(pyins_navigate(our_readings(dv_o - corr_o), pva_o), truth_o)
    dv_start = (g_v(da_o) @ (dv_o - corr_o)[..., None])[..., 0]
    exact_increments = pd.DataFrame(
        np.hstack([np.full((m_inc, 1), PERIOD), da_o, dv_start]),
        index=pd.Index(time_o[1:], name="time"),
        columns=["dt", "theta_x", "theta_y", "theta_z", "dv_x", "dv_y", "dv_z"],
    )
    cross_b2 = pyins_closure(strapdown.Integrator(pva_o).integrate(exact_increments), truth_o)

    # ---------------------------------------------------------------------------------------
    # Report.
    fit = traj.residuals()
    same = same_motion(truth_o)
    feed = f"every {args.every}th sample" if args.every > 1 else "all samples"
    print(
        f"motion: pyins sine velocity, {args.duration_s:g} s at {1 / PERIOD:g} Hz ({m_inc} "
        f"increments); our reference fitted to pyins' truth ({feed}, knots "
        f"{np.median(np.diff(traj.position_breakpoints)):.3g} s)"
    )
    print(
        f"fit residuals (RMS): position {fit['position']:.1e} m, velocity {fit['velocity']:.1e} "
        f"m/s, attitude {fit['attitude']:.1e} rad; our truth vs pyins' truth, max over all "
        f"samples: {same[0]:.1e} m, {same[1]:.1e} m/s, {same[2]:.1e} rad"
    )
    if coarse is not None:
        print(
            f"  fed every {args.coarse}th sample: our truth vs pyins' truth, max: "
            f"{coarse[2][0]:.1e} m, {coarse[2][1]:.1e} m/s, {coarse[2][2]:.1e} rad"
        )
    print(
        f"gravity pyins - ours along the motion: down {dg_o[:, 2].min():+.2e} .. "
        f"{dg_o[:, 2].max():+.2e} m/s^2, north {dg_o[:, 0].min():+.2e} .. "
        f"{dg_o[:, 0].max():+.2e} m/s^2"
    )
    print(
        f"our navigator: mode='exact', N={n_nav} (T_nav = {n_nav * PERIOD:g} s), P={p_nav}; "
        f"closure at t = {k_end * PERIOD:.2f} s; times: best of {reps} (navigation "
        f"{reps + 1}), the tools in turn; +JIT = first navigation call in this process "
        "(one-time numba compile)"
    )
    print()
    head = (
        f"{'run':<58} {'gen s':>6} {'nav s':>6} {'+JIT s':>6} "
        f"{'horiz m':>8} {'down m':>9} {'att rad':>8} {'vel m/s':>8}"
    )
    print(head)
    print("-" * len(head))

    def row(name: str, c: Closure, gen=None, nav=None, jit=None) -> None:
        def f(x):
            return f"{x:>6.3f}" if x is not None else " " * 6

        print(
            f"{name:<58} {f(gen)} {f(nav)} {f(jit)} {c.horizontal:>8.1e} {c.down:>+9.1e} "
            f"{c.attitude:>8.1e} {c.velocity:>8.1e}"
        )

    row("pyins: its data, its integrator", own_p, t_gen_p, t_nav_p, t_nav_p_first)
    row(f"ours: our data, exact navigator N={n_nav} P={p_nav}", own_o, t_gen_o, t_nav_o,
        t_nav_o_first)  # fmt: skip
    for name, c, gen, nav in rows_extra:
        row(name, c, gen, nav)
    print("our exact navigator on pyins' data:")
    row("  A  readings as given", cross_a)
    row("  A' readings as given, gravity-matched", cross_a1)
    row("  A\" after pyins' coning/sculling, gravity-matched", cross_a2)
    print("pyins' integrator on our data:")
    row("  B  via compute_increments_from_imu", cross_b)
    row("  B' via compute_increments_from_imu, gravity-matched", cross_b1)
    row('  B" as exact increments, gravity-matched', cross_b2)
    print("-" * len(head))

    total_p, total_o = t_gen_p + t_nav_p, t_gen_o + t_nav_o
    jit_p, jit_o = t_gen_p + t_nav_p_first, t_gen_o + t_nav_o_first
    print(
        f"end to end (generation + navigation, JIT excluded): pyins {total_p:.3f} s, ours "
        f"{total_o:.3f} s; with the one-time JIT: pyins {jit_p:.3f} s, ours {jit_o:.3f} s "
        f"({jit_p / jit_o:.2f} x)"
    )
    if coarse is not None:
        print(
            f"fed every {args.coarse}th truth sample: ours {coarse[0] + coarse[1]:.3f} s, "
            f"{total_p / (coarse[0] + coarse[1]):.2f} x faster than pyins"
        )
    print(
        "closure error pyins / ours, each on its own data: horizontal "
        f"{own_p.horizontal / max(own_o.horizontal, 1e-300):.1e} x, vertical "
        f"{abs(own_p.down) / max(abs(own_o.down), 1e-300):.1e} x"
    )
    speedup = total_p / total_o
    # Fresh processes, JIT included, our numba cache warm (filled by this process above).
    fresh = fresh_process_ratio(args.duration_s, ref, args.every, n_nav, p_nav, cache.name)
    best_p, best_o = min(f["pyins"] for f in fresh), min(f["ours"] for f in fresh)
    print(
        "fresh processes, first generation + navigation incl. JIT, our numba cache warm: "
        + "; ".join(
            f"{' then '.join(f)}: pyins {f['pyins']:.3f} s, ours {f['ours']:.3f} s"
            for f in fresh
        )
    )
    print(
        f"speedup_vs_pyins_fresh_process: {best_p / best_o:.2f} x (best of {len(fresh)} fresh "
        f"processes each: pyins {best_p:.3f} s, ours {best_o:.3f} s)"
    )
    print(f"speedup_vs_pyins: {speedup:.2f} x")
    sys.stdout.flush()
    cache.cleanup()
    return speedup


if __name__ == "__main__":
    main()
