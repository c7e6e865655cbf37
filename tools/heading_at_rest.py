"""The aided filter's heading at rest: its σ and a Monte Carlo set's spread from the draws alone.

Usage: python tools/heading_at_rest.py SCENARIO [--seeds S ...] [--sets M] [--dir SEED=DIR ...]

SCENARIO at rest with a magnetometer (test/data/aided_static_noisy.yaml), read with its modelled
terms only, as ``python -m strapdown_ros.analysis.aided_check SCENARIO --modelled-only`` runs
it. At rest the magnetometer measures the heading error ψ only together with the hard iron
along the horizontal direction the heading turns the field, ``u = C_N^B (Y, −X, 0) / B_H``:
``u·δm̃ = B_H ψ + u·h + noise``; with a hard-iron σ (1 µT) far above ``B_H σ_ψ0`` the mean of
many samples tells the filter almost nothing about ψ (closed form: the variance falls by
``κ = B_H² σ_ψ0² / (σ_h² + B_H² σ_ψ0²)``), but it tracks the heading's *changes* (the hard iron
is constant), so the gyro z bias is estimated and the heading error stays close to the
filter's initial draw from P0. Printed:

* the model's numbers (IGRF field, σ's) and κ;
* the σ of ψ of a reduced filter with the aided filter's model, states [ψ, gyro z turn-on
  bias, gyro z Gauss–Markov bias, hard iron along u], magnetometer at its rate, each minute;
* per base seed (the runs' seeds as ``aided_check --seed S`` gives them,
  ``aided_montecarlo.seed_overrides``): the RMS over the 100 runs of the drawn initial heading
  error, hard iron along u and gyro z turn-on bias, each over its σ, and the reduced filter's
  error RMS over its σ when driven by those draws (its white noises drawn here, seeded by S);
* over ``--sets`` base seeds (0..M−1): the spread of the heading draws' RMS over sets of 100;
* with ``--dir SEED=DIR`` (the runs of ``aided_check --seed SEED --dir DIR``, read back): the
  filter's σ_θ1 of run 0 each minute, σ_ens/σ_pred of θ1 averaged over the epochs from 60 s
  (as aided_check's "mean ratio"), and the correlation over the runs between each run's mean
  θ1 and its initial heading draw.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from strapdown_ros.config.scenario import apply_overrides, parse_scenario
from strapdown_ros.core.aided.initial import initial_error
from strapdown_ros.core.aided.model import SensorModels, build_model
from strapdown_ros.core.aiding.magnetometer import MagnetometerErrorModel, igrf_field_ned
from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef
from strapdown_ros.core.imu_errors import ImuErrorModel
from strapdown_ros.core.rotations import dcm_from_euler
from strapdown_ros.stages.aided import aided_imu_errors
from strapdown_ros.stages.aided_montecarlo import campaign_document, seed_overrides
from strapdown_ros.stages.aiding import igrf_coefficients

RUNS = 100
SKIP_S = 60.0


def _reduced_filter(sig0: np.ndarray, b_h: float, noise: float, tau: float, s_gm: float,
                    q_arw: float, period: float, steps: int):  # fmt: skip
    """Φ, Q_d (Van Loan), the gains and σ_ψ after each step of the reduced filter."""
    fc = np.array([[0, 1, 1, 0], [0, 0, 0, 0], [0, 0, -1 / tau, 0], [0, 0, 0, 0.0]])
    qc = np.diag([q_arw, 0.0, 2 * s_gm**2 / tau, 0.0])
    m = np.zeros((8, 8))
    m[:4, :4], m[:4, 4:], m[4:, 4:] = -fc, qc, fc.T
    e = expm(m * period)
    phi = e[4:, 4:].T
    qd = phi @ e[:4, 4:]
    h = np.array([b_h, 0.0, 0.0, 1.0])
    p = np.diag(sig0**2)
    gains, sig = np.zeros((steps, 4)), np.zeros(steps)
    for k in range(steps):
        p = phi @ p @ phi.T + qd
        gain = p @ h / (h @ p @ h + noise**2)
        ikh = np.eye(4) - np.outer(gain, h)
        p = ikh @ p @ ikh.T + noise**2 * np.outer(gain, gain)
        gains[k], sig[k] = gain, math.sqrt(p[0, 0])
    return phi, 0.5 * (qd + qd.T), h, gains, sig


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 2])
    ap.add_argument("--sets", type=int, default=400)
    ap.add_argument("--dir", action="append", default=[], metavar="SEED=DIR")
    args = ap.parse_args()

    doc, overrides = campaign_document(args.scenario, True, [], None)
    sc = parse_scenario(apply_overrides(doc, overrides))
    ini, mag, spec = sc.initial, sc.aiding.magnetometer, sc.aided  # type: ignore[union-attr]
    lat, lon = math.radians(ini.latitude_deg), math.radians(ini.longitude_deg)
    c_b_n = dcm_from_euler(*np.radians(ini.attitude_rph_deg))
    g, h = igrf_coefficients(mag.year(sc.start_time_ns))
    r_e = np.asarray(geodetic_to_ecef(lat, lon, ini.altitude_m)).reshape(1, 3)
    b_n = igrf_field_ned(r_e, np.array([lat]), g, h)[0] * 1e-9
    b_h = math.hypot(b_n[0], b_n[1])
    u_b = c_b_n.T @ np.array([b_n[1], -b_n[0], 0.0]) / b_h
    errs = mag.errors()
    s_h = math.sqrt(float(np.asarray(errs.hard_iron_sigma) ** 2 @ u_b**2))
    noise = float(errs.white[0])
    params = aided_imu_errors(sc).parameters()
    t_imu = 1.0 / sc.rate_hz
    model = build_model(params, t_imu, SensorModels(mag=errs))
    gy = params.gyro
    att = np.radians(spec.initial_sigma.attitude_deg)  # type: ignore[union-attr]
    s_psi, s_b = float(att[2]), float(gy.turn_on_bias_sigma[2])
    s_gm, tau = float(gy.gauss_markov_sigma[2]), float(gy.correlation_time_s[2])
    q_arw = float(model.q_ins[5])
    kappa = b_h**2 * s_psi**2 / (s_h**2 + b_h**2 * s_psi**2)
    print(f"field NED {np.round(b_n * 1e6, 3)} µT, B_H {b_h * 1e6:.3f} µT; σ_ψ0 {s_psi:.6g} rad, "
          f"hard iron σ {s_h * 1e6:g} µT, noise {noise * 1e6:g} µT at {mag.rate_hz:g} Hz; "
          f"gyro z: turn-on {s_b:.4g} rad/s, GM {s_gm:.4g} rad/s (τ {tau:g} s), "
          f"white PSD {q_arw:.4g} rad²/s")  # fmt: skip
    print(
        f"κ = B_H²σ_ψ0²/(σ_h² + B_H²σ_ψ0²) = {kappa:.5f}: magnetometer alone, "
        f"σ_ψ = σ_ψ0 √(1 − κ) = {s_psi * math.sqrt(1 - kappa):.6g} rad"
    )

    period = 1.0 / mag.rate_hz
    steps = int(round(sc.duration_s / period))
    per_min = int(round(60.0 / period))
    sig0 = np.array([s_psi, s_b, s_gm, s_h])
    phi, qd, hrow, gains, sig = _reduced_filter(sig0, b_h, noise, tau, s_gm, q_arw, period, steps)
    minutes = sig[per_min - 1 :: per_min]
    print("reduced filter σ_ψ (rad) each minute: " + " ".join(f"{s:.6g}" for s in minutes))

    cen = dcm_ecef_to_ned(lat, lon)
    chol = np.linalg.cholesky(qd + 1e-40 * np.eye(4))
    skip = int(round(SKIP_S / period))

    def heading_draw(seeds: dict[str, str]) -> float:
        dx = initial_error(int(seeds["aided.seed"]), lat, lon, [1.0] * 3, [0.1] * 3, att)
        return float((cen @ dx[6:9])[2])

    draws: dict[int, np.ndarray] = {}
    for base in args.seeds:
        x0 = []
        for k in range(RUNS):
            s = dict(o.split("=") for o in seed_overrides(doc, k, base))
            mag_seed = int(s["aiding.magnetometer.seed"])
            hard = MagnetometerErrorModel(errs, period, mag_seed).hard_iron
            run = parse_scenario(apply_overrides(doc, [f"imu_errors.seed={s['imu_errors.seed']}"]))
            imu = ImuErrorModel(aided_imu_errors(run).parameters(), t_imu)  # its drawn constants
            x0.append([heading_draw(s), imu.gyro_bias[2], imu._gyro.gm[2], u_b @ hard])
        x = np.array(x0)
        draws[base] = x[:, 0]
        xh = np.zeros_like(x)
        rng = np.random.default_rng(base)  # the reduced filter's white noises
        ratio = []
        for k in range(steps):
            x = x @ phi.T + rng.standard_normal(x.shape) @ chol.T
            xh = xh @ phi.T
            y = x @ hrow + noise * rng.standard_normal(RUNS)
            xh = xh + np.outer(y - xh @ hrow, gains[k])
            if k >= skip:
                ratio.append(math.sqrt(np.mean((xh[:, 0] - x[:, 0]) ** 2)) / sig[k])
        rms = np.sqrt(np.mean(np.array(x0) ** 2, axis=0)) / sig0
        print(f"seed {base}, {RUNS} runs: RMS/σ of the draws: initial heading {rms[0]:.4f}, "
              f"gyro z turn-on {rms[1]:.4f}, GM start {rms[2]:.4f}, hard iron along u "
              f"{rms[3]:.4f}; reduced filter on them: error RMS/σ_ψ mean from "
              f"{SKIP_S:g} s {np.mean(ratio):.4f}")  # fmt: skip

    if len(args.seeds) > 1:
        pooled = math.sqrt(np.mean(np.concatenate([draws[b] for b in args.seeds]) ** 2)) / s_psi
        print(
            f"seeds {args.seeds} pooled ({RUNS * len(args.seeds)} runs): initial heading "
            f"draws RMS/σ {pooled:.4f}"
        )
    if args.sets:
        sets = []
        for base in range(args.sets):
            z = [heading_draw(dict(o.split("=") for o in seed_overrides(doc, k, base)))
                 for k in range(RUNS)]  # fmt: skip
            sets.append(math.sqrt(np.mean(np.square(z))) / s_psi)
        a = np.array(sets)
        print(
            f"base seeds 0..{args.sets - 1}: initial heading draws RMS/σ over sets of {RUNS}: "
            f"mean {a.mean():.4f}, sd {a.std(ddof=1):.4f} (1/√(2·{RUNS}) = "
            f"{1 / math.sqrt(2 * RUNS):.4f}), min {a.min():.4f}, max {a.max():.4f}"
        )

    for item in args.dir:
        base_s, _, path = item.partition("=")
        base = int(base_s)
        from strapdown_ros.analysis.aided_check import read_aided_run

        runs = [read_aided_run(Path(path) / f"run_{k:03d}", sc) for k in range(RUNS)]
        kk = min(r.stamps.shape[0] for r in runs)
        t = (runs[0].stamps[:kk] - runs[0].stamps[0]) * 1e-9
        late = t >= SKIP_S
        err = np.stack([r.errors[:kk, 6] for r in runs])
        sgm = np.stack([r.sigma[:kk, 6] for r in runs])
        pred = np.sqrt(np.mean(sgm**2, axis=0))
        ratio = np.sqrt(np.mean(err**2, axis=0)) / pred
        idx = [int(np.argmin(np.abs(t - 60.0 * m))) for m in range(1, int(t[-1] // 60) + 1)]
        draw = draws.get(base)
        if draw is None:
            draw = np.array([heading_draw(dict(o.split("=") for o in seed_overrides(doc, k, base)))
                             for k in range(RUNS)])  # fmt: skip
        mean_err = err[:, late].mean(axis=1)
        print(
            f"{path} (seed {base}): filter σ_θ1 of run 0 each minute: "
            + " ".join(f"{sgm[0, i]:.6g}" for i in idx)
        )
        print(f"  σ_ens/σ_pred of θ1, mean over the epochs from {SKIP_S:g} s: "
              f"{ratio[late].mean():.4f}; RMS/σ_ψ0 of the runs' initial heading draws "
              f"{math.sqrt(np.mean(draw**2)) / s_psi:.4f}; correlation of each run's mean θ1 "
              f"with its −ψ draw {np.corrcoef(mean_err, -draw)[0, 1]:.4f}, least-squares "
              f"slope {np.polyfit(-draw, mean_err, 1)[0]:.4f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
