"""Transfer-alignment campaigns: alignment time, consistency, bending and resolver sensitivity.

The reference and variation streams of a scenario do not depend on the run's seeds, so they are
made once (:func:`base_batches`: ``generate``'s trajectory and variation stages, serialized as
``generate`` writes them); each run then applies its own IMU errors (the ``imu_errors`` stage)
and runs the ``transfer_alignment`` stage on those messages (:func:`run_transfer`), and its
``/transfer/*`` messages are decoded (:func:`decode_result`). The runs' seeds: IMU errors,
master errors and the mounting error draw (``mounting_error_deg: null``) from
``SeedSequence(base_seed, spawn_key=(run,))``.

Command line (docs/transfer_alignment.md)::

    python -m strapdown_ros.stages.transfer_montecarlo SCENARIO --runs 50 [--straight] [--save DIR]
        [--attitude-jacobian estimate]
    python -m strapdown_ros.stages.transfer_montecarlo SCENARIO --summarize DIR [DIR ...]
    python -m strapdown_ros.stages.transfer_montecarlo SCENARIO --bending 0 1 2 5 10
    python -m strapdown_ros.stages.transfer_montecarlo SCAN_SCENARIO --resolver 0:0 0.1:0.01
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import Scenario, load_scenario
from strapdown_ros.core.aided.consistency import Inside, fraction_inside
from strapdown_ros.core.transfer.convergence import alignment_time
from strapdown_ros.stages.aided_montecarlo import modelled_only

__all__ = [
    "TransferResult",
    "alignment_time",
    "base_batches",
    "decode_result",
    "main",
    "run_transfer",
]

#: Epochs before this time (s) are left out of the consistency statistics.
CONVERGENCE_S = 5.0


@dataclass(frozen=True)
class TransferResult:
    """One run's ``/transfer/*`` series at the K output epochs.

    ``t`` (K,) s since the start; ``attitude`` Young errors (up, east, north) rad; ``mounting``
    error (FLU of the reference body) rad and its σ; ``nees`` (K, 3) position, velocity,
    attitude; ``mounting_nees`` (K,); ``nis`` (K−1, 2) velocity, attitude.
    """

    t: np.ndarray
    attitude: np.ndarray
    velocity: np.ndarray
    mounting: np.ndarray
    mounting_sigma: np.ndarray
    nees: np.ndarray
    mounting_nees: np.ndarray
    nis: np.ndarray


def base_batches(scenario: Scenario) -> tuple[list[Batch], int]:
    """The reference and variation batches the runs read, and the variation's last cycle."""
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import feed_stages, offline_stages
    from strapdown_ros.stages.trajectory import reference_batch_chunks

    plan = resolve_plan(scenario)
    topics = scenario.recording.topics
    keep = {topics["reference_odom"], topics["variation_imu"], topics["variation_odom"]}
    stages = offline_stages(plan, ["variation"])
    out: list[Batch] = []
    for _, batches in reference_batch_chunks(plan):
        out += [b for b in feed_stages(stages, batches) if b.topic in keep]
    return out, plan.variation_cycles


def run_transfer(scenario: Scenario, base: list[Batch], last_cycle: int) -> list[Batch]:
    """One run: the scenario's IMU errors on the variation IMU, then the transfer stage."""
    from strapdown_ros.stages.imu_errors import ImuErrorsStages
    from strapdown_ros.stages.transfer import TransferStage

    batches = list(base)
    batches += ImuErrorsStages(scenario).feed_batches(base)
    return TransferStage(scenario, last_cycle).feed_batches(batches)


def decode_result(batches: Sequence[Batch], scenario: Scenario) -> TransferResult:
    """The run's series from its serialized ``/transfer/*`` batches."""
    from strapdown_ros.config.transfer import transfer_spec

    spec = transfer_spec(scenario)
    assert spec is not None
    topics = spec.output_topics()
    by_topic: dict[str, list[Batch]] = {}
    for b in batches:
        by_topic.setdefault(b.topic, []).append(b)

    def vec(key: str) -> tuple[np.ndarray, np.ndarray]:
        parts = by_topic[topics[key]]
        f = cdr.deserialize(cdr.VECTOR3_STAMPED, [p for b in parts for p in b.payloads])
        return np.asarray(f.stamps_ns, dtype=np.int64), np.asarray(f.vector, dtype=np.float64)

    stamps, att = vec("error_attitude")
    t = (stamps - scenario.start_time_ns) * 1e-9
    _, vel = vec("error_velocity")
    _, mu = vec("mounting_error")
    _, sig = vec("mounting_sigma")
    _, ne = vec("nees")
    _, mn = vec("mounting_nees")
    _, nis = vec("nis")
    return TransferResult(t, att, vel, mu, sig, ne, mn[:, 0], nis[:, :2])


def _seeded(doc: dict[str, Any], run: int, base_seed: int) -> list[str]:
    """Run ``run``'s seeds: the master's, the filter's and every IMU error model's (one
    mapping: ``SeedSequence(base, (run,))``'s first word; a list: one word per model from
    ``SeedSequence(base, (run, 1))``)."""
    seq = np.random.SeedSequence(base_seed, spawn_key=(run,))
    s = seq.generate_state(3, dtype=np.uint32)
    out = [f"transfer_alignment.master.seed={int(s[1])}", f"transfer_alignment.seed={int(s[2])}"]
    imu = doc.get("imu_errors")
    if isinstance(imu, dict):
        out.append(f"imu_errors.seed={int(s[0])}")
    elif isinstance(imu, list) and imu:
        w = np.random.SeedSequence(base_seed, spawn_key=(run, 1)).generate_state(len(imu))
        out += [f"imu_errors.{i}.seed={int(w[i])}"
                for i, m in enumerate(imu) if isinstance(m, dict)]  # fmt: skip
    return out


def _scenario(doc: dict[str, Any], overrides: Sequence[str], duration: float | None,
              directory: Path) -> Scenario:  # fmt: skip
    path = directory / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return load_scenario(path, overrides, duration)


def campaign(doc: dict[str, Any], runs: int, directory: Path, duration: float | None,
             base_seed: int = 0, save: Path | None = None) -> list[TransferResult]:  # fmt: skip
    """``runs`` runs of the scenario document ``doc`` (its streams made once); each run's
    series also written to ``save/run_<k>.npz`` (progress on stderr)."""
    start = time.perf_counter()
    first = _scenario(doc, _seeded(doc, 0, base_seed), duration, directory)
    base, last = base_batches(first)
    print(f"streams made, {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    out = []
    for k in range(runs):
        sc = first if k == 0 else _scenario(doc, _seeded(doc, k, base_seed), duration, directory)
        r = decode_result(run_transfer(sc, base, last), sc)
        out.append(r)
        if save is not None:
            save.mkdir(parents=True, exist_ok=True)
            np.savez(save / f"run_{k:03d}.npz", **r.__dict__)
        print(f"run {k} done, {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    return out


def load_results(directory: Path) -> list[TransferResult]:
    """The runs saved by :func:`campaign` in ``directory``."""
    out = []
    for path in sorted(directory.glob("run_*.npz")):
        with np.load(path) as z:
            out.append(TransferResult(**{k: z[k] for k in z.files}))
    return out


def _inside_line(name: str, v: Inside) -> str:
    lo, hi = v.interval
    return (f"| {name} | {100 * v.fraction:.1f} % | {100 * v.below:.1f} % | "
            f"{100 * v.above:.1f} % | {v.mean:.3f} | [{lo:.3f}, {hi:.3f}] |")  # fmt: skip


def summary(results: list[TransferResult]) -> list[str]:
    """Alignment times and the consistency table of a campaign (markdown lines)."""
    lines = []
    for thr, name in ((1e-3, "1 mrad"), (1e-4, "0.1 mrad")):
        heading = np.array([alignment_time(r.t, r.attitude[:, 0], thr) for r in results])
        mount = np.array([alignment_time(r.t, r.mounting[:, 2], thr) for r in results])
        for what, a in (("slave heading", heading), ("mounting yaw", mount)):
            ok = np.isfinite(a)
            med = np.median(a[ok]) if ok.any() else float("nan")
            p90 = np.percentile(a[ok], 90) if ok.any() else float("nan")
            lines.append(f"{what} to {name}: reached in {int(ok.sum())}/{len(a)} runs, median "
                         f"{med:.1f} s, 90th percentile {p90:.1f} s")  # fmt: skip
    t = results[0].t
    sel = t >= CONVERGENCE_S
    lines.append("| statistic | inside | below | above | mean | interval |")
    lines.append("|---|---|---|---|---|---|")
    ne = np.stack([r.nees[sel] for r in results])
    for i, name in enumerate(("NEES position", "NEES velocity", "NEES attitude")):
        lines.append(_inside_line(name, fraction_inside(ne[:, :, i], 3)))
    mn = np.stack([r.mounting_nees[sel] for r in results])
    lines.append(_inside_line("NEES mounting", fraction_inside(mn, 3)))
    tn = t[1:]
    seln = tn >= CONVERGENCE_S
    nis = np.stack([r.nis[seln] for r in results])
    lines.append(_inside_line("NIS velocity", fraction_inside(nis[:, :, 0], 3)))
    if np.any(nis[:, :, 1] != 0.0):
        lines.append(_inside_line("NIS attitude", fraction_inside(nis[:, :, 1], 3)))
    return lines


def bending_table(doc: dict[str, Any], amplitudes_mm: Sequence[float], directory: Path,
                  duration: float | None) -> list[str]:  # fmt: skip
    """Final mounting error and σ for bending amplitudes, the master exact.

    The 3 Hz mode's vertical amplitude is set to each value (the random part off); the filter
    is told the bending's rms velocity ``2π f A / √2`` as ``tuning.velocity_sigma_mps``. Two
    filters per amplitude: velocity matching alone with the ideal slave IMU (the mounting is
    then estimated only through the slave's attitude, which the bending corrupts), and velocity
    plus attitude matching with the scenario's slave IMU (modelled terms, seed as written).
    """
    lines = ["| bending amplitude (mm) | velocity σ told (m/s) | matching, slave IMU | final "
             "mounting error x, y, z (µrad) | final σ x, y, z (µrad) | max \\|error\\|/σ after "
             "30 s |", "|---|---|---|---|---|---|"]  # fmt: skip
    freq = 3.0
    for a in amplitudes_mm:
        d = copy.deepcopy(modelled_only(doc))
        ta = d["transfer_alignment"]
        ta["master"] = {}
        sig = 2 * np.pi * freq * a * 1e-3 / np.sqrt(2.0)
        ta["tuning"] = {"velocity_sigma_mps": float(sig)}
        d["variation"]["bending"] = {"sinusoids": [
            {"amplitude_m": [0.0, 0.0, a * 1e-3], "frequency_hz": freq, "phase_deg": 0.0}]}
        ideal = copy.deepcopy(d)
        ideal.pop("imu_errors", None)
        ideal["transfer_alignment"]["imu_topic"] = "/variation/imu"
        ideal["transfer_alignment"]["measurements"] = ["velocity"]
        base: tuple[list[Batch], int] | None = None
        for what, dd in (("velocity, ideal", ideal), ("velocity + attitude, tactical", d)):
            sc = _scenario(dd, [], duration, directory)
            if base is None:
                base = base_batches(sc)
            r = decode_result(run_transfer(sc, *base), sc)
            late = r.t >= 30.0
            z = np.max(np.abs(r.mounting[late]) / r.mounting_sigma[late])
            e = ", ".join(f"{1e6 * v:.3g}" for v in r.mounting[-1])
            s = ", ".join(f"{1e6 * v:.3g}" for v in r.mounting_sigma[-1])
            lines.append(f"| {a:g} | {sig:.4g} | {what} | {e} | {s} | {z:.2f} |")
    return lines


def campaign_conditions(doc: dict[str, Any]) -> dict[str, Any]:
    """The campaign's realistic errors, all of which the filter models: the slave IMU's modelled
    terms, the master's white noise (velocity and attitude), the mounting error drawn per run,
    no tuning; no bending (a deterministic motion the filter does not model). A new document."""
    d = modelled_only(doc)
    d["variation"].pop("bending", None)
    ta = d["transfer_alignment"]
    ta["mounting_error_deg"] = None
    ta["master"] = {k: v for k, v in (ta.get("master") or {}).items()
                    if k in ("velocity_noise_mps", "attitude_noise_deg")}  # fmt: skip
    ta["tuning"] = {}
    return d


def _resolver_case(text: str) -> tuple[float, float]:
    """``BIAS:NOISE`` (deg) of ``--resolver``."""
    bias, _, noise = text.partition(":")
    return float(bias), float(noise or 0.0)


def resolver_table(doc: dict[str, Any], cases: Sequence[tuple[float, float]], runs: int,
                   directory: Path, duration: float | None,
                   base_seed: int = 0) -> list[str]:  # fmt: skip
    """The mounting error, σ and NEES against the resolver's bias and noise (a scan scenario).

    The campaign's conditions (the slave IMU's modelled terms, the master's white noise, no
    bending, the mounting error drawn per run) plus a resolver of bias b and noise σ per case,
    ``runs`` runs each (seeds as :func:`campaign`, the resolver's the filter's seed + 1). The
    mounting error is against ``C_mount`` (zero scan): a bias is a mounting error ``−b M a``
    (docs/transfer_alignment.md §5), shown beside; NEES over the epochs after 30 s against the
    95 % χ² interval of the run average.
    """
    d = campaign_conditions(doc)
    lines = ["| resolver bias, noise (deg) | mean final mounting error x, y, z (µrad) | "
             "−b·(M a) x, y, z (µrad) | rms about it x, y, z (µrad) | final σ x, y, z (µrad) | "
             "mounting NEES: mean, inside | slave attitude NEES: mean, inside |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    base: tuple[list[Batch], int] | None = None
    for bias, noise in cases:
        results = []
        for k in range(runs):
            seeds = _seeded(d, k, base_seed)
            rseed = int(seeds[1].split("=")[1]) + 1  # a stream of its own
            res = f"transfer_alignment.resolver={{bias_deg: {bias}, noise_deg: {noise}, " \
                  f"seed: {rseed}}}"  # fmt: skip
            sc = _scenario(d, [*seeds, res], duration, directory)
            if base is None:
                base = base_batches(sc)
            results.append(decode_result(run_transfer(sc, *base), sc))
        assert sc.variation is not None
        om = sc.variation.offset_model()
        axis = np.asarray(getattr(om.scan, "axis", np.zeros(3)))
        expect = -np.radians(bias) * (om.mount @ axis) * np.array([1.0, -1.0, -1.0]) + 0.0  # FLU
        final = np.array([r.mounting[-1] for r in results])
        sig = np.array([r.mounting_sigma[-1] for r in results]).mean(axis=0)
        rms = np.sqrt(np.mean((final - expect) ** 2, axis=0))
        sel = results[0].t >= 30.0
        mn = fraction_inside(np.stack([r.mounting_nees[sel] for r in results]), 3)
        an = fraction_inside(np.stack([r.nees[sel, 2] for r in results]), 3)

        def us(v: np.ndarray) -> str:
            return ", ".join(f"{1e6 * x:.3g}" for x in v)

        lines.append(f"| {bias:g}, {noise:g} | {us(final.mean(axis=0))} | {us(expect)} | "
                     f"{us(rms)} | {us(sig)} | {mn.mean:.3g}, {100 * mn.fraction:.0f} % | "
                     f"{an.mean:.3g}, {100 * an.fraction:.0f} % |")  # fmt: skip
        print(f"resolver {bias:g}, {noise:g} done", file=sys.stderr, flush=True)
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    import tempfile

    ap = argparse.ArgumentParser(prog="transfer_montecarlo", description=__doc__.split("\n")[0])
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--straight", action="store_true",
                    help="replace the trajectory by straight and level flight")
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--bending", type=float, nargs="+", default=None,
                    help="bending amplitudes (mm): the bending table instead of a campaign")
    ap.add_argument("--resolver", type=_resolver_case, nargs="+", default=None,
                    metavar="BIAS:NOISE",
                    help="resolver bias and noise (deg) per case: the resolver table instead "
                    "of a campaign (a scanning-platform scenario; --runs runs per case)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--attitude-jacobian", choices=("measurement", "estimate"), default=None,
                    help="set transfer_alignment.attitude_jacobian (docs/transfer_alignment.md §6)")
    ap.add_argument("--save", type=Path, default=None, help="write each run's series here")
    ap.add_argument("--summarize", type=Path, nargs="+", default=None, metavar="DIR",
                    help="only summarize the runs saved in these directories (pooled)")
    args = ap.parse_args(argv)
    if args.summarize is not None:
        results = [r for d in args.summarize for r in load_results(d)]
        if not results:
            ap.error(f"--summarize: no run_*.npz in {', '.join(map(str, args.summarize))}")
        print(f"{', '.join(map(str, args.summarize))}: {len(results)} runs")
        print("\n".join(summary(results)))
        return 0
    doc = yaml.safe_load(args.scenario.read_text())
    if args.attitude_jacobian is not None:
        doc["transfer_alignment"]["attitude_jacobian"] = args.attitude_jacobian
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        if args.bending is not None:
            lines = bending_table(doc, args.bending, Path(tmp), args.duration)
        elif args.resolver is not None:
            lines = resolver_table(doc, args.resolver, args.runs, Path(tmp), args.duration,
                                   args.seed)  # fmt: skip
        else:
            doc = campaign_conditions(doc)
            if args.straight:
                total = sum(s["duration_s"] for s in doc["trajectory"]["segments"])
                doc["trajectory"]["segments"] = [{"duration_s": total}]
            lines = summary(campaign(doc, args.runs, Path(tmp), args.duration, args.seed,
                                         args.save))
    took = time.perf_counter() - start
    what = "bending table" if args.bending is not None else (
        f"resolver table, {args.runs} runs per case" if args.resolver is not None else
        f"{args.runs} runs, {'straight flight' if args.straight else 'manoeuvre'}")  # fmt: skip
    print(f"{args.scenario.name}: {what}, {took:.0f} s")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
