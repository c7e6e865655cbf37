"""Benchmark: highest IMU rate the live pipeline records with zero loss in real time, reproducibly.

Runs the whole live pipeline (``strapdown-sim run``: trajectory, variation, imu_model, navigator
and aiding nodes + bag_recorder, separate processes, real DDS over loopback, ``rate_factor`` 1 =
real time, so no flow control) on ``default.yaml`` shortened to ``--duration`` seconds, at each
IMU rate ``--repeats`` times (default 3), and checks each recording against the message counts
the scenario produces and, payload for payload, against ``strapdown-sim generate``'s bag of the
same scenario. A rate counts only if **every** run of it had zero loss and identical payloads;
the worst run of each rate is reported. The machine load (1-minute load average, as ``uptime``
prints it) is sampled before and after every run: figures taken under load from other jobs are
not those of an idle machine.

Also printed per run: the CPU time of each process (user + system, start-up included) and the
total CPU per recorded message. ``--profile DIR`` writes a cProfile of every node process of the
extra first run of each rate into ``DIR/<rate>/<node>.prof`` (profiling slows the nodes down:
that run is not counted).

Usage: python bench/bench_live.py [--rates 1000 2000 2500 4000] [--duration 20] [--repeats 3]
Last line: ``live_zero_loss_max_rate_hz: X Hz``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.pipeline import PROFILE_ENV, PipelineError, run_pipeline

SCENARIO = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"
TARGET_HZ = 1000.0
NODES = (
    "trajectory_node", "variation_node", "imu_model_node", "navigator_node", "aiding_node",
    "bag_recorder",
)  # fmt: skip


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def _one_run(rate: float, duration: float, gen: Path, live: Path) -> dict:
    load0 = os.getloadavg()[0]
    t0 = time.monotonic()
    result = run_pipeline(
        SCENARIO, live, overrides=[f"rate_hz={rate:g}"], duration_s=duration, progress=False
    )
    wall = time.monotonic() - t0
    load1 = os.getloadavg()[0]
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    same = set(a.topics) == set(b.topics) and all(
        [bytes(p) for p in a.topics[t].payloads] == [bytes(p) for p in d.payloads]
        for t, d in b.topics.items()
    )
    msgs = sum(result.counts.values())
    return {
        "msgs": msgs,
        "expected": sum(result.expected.values()),
        "lost": sum(abs(v) for v in result.lost.values()),
        "same": same,
        "wall": wall,
        "load": (load0, load1),
        "cpu": result.cpu_s,
        "pacing": result.pacing,
    }


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[1000, 2000, 2500, 4000])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", type=Path, default=None, metavar="DIR")
    args = parser.parse_args(argv)
    best = 0.0
    loads: list[float] = []
    print(f"scenario: {SCENARIO.name}, {args.duration:g} s of data per run, rate_factor 1, "
          f"{args.repeats} runs per rate")  # fmt: skip
    print(f"start: {_uptime()}")
    head = "  ".join(f"{n.split('_')[0][:4]:>5}" for n in NODES)
    print(f"{'rate Hz':>8} {'run':>3} {'msgs':>8} {'lost':>7} {'same':>5} {'wall s':>6} "
          f"{'load':>10}  cpu s: {head}  {'us/msg':>6}")  # fmt: skip
    worst: dict[float, int] = {}
    for rate in sorted(args.rates):
        ok_all = True
        with tempfile.TemporaryDirectory() as tmp:
            gen = Path(tmp) / "gen"
            subprocess.run(
                [sys.executable, "-m", "strapdown_ros.cli", "generate", str(SCENARIO),
                 "--out", str(gen), "--duration", str(args.duration), "--quiet",
                 "--set", f"rate_hz={rate:g}"],
                check=True,
            )  # fmt: skip
            for k in range(args.repeats + (args.profile is not None)):  # + 1 profiled
                profile = args.profile is not None and k == 0
                if profile:
                    pdir = args.profile / f"{rate:g}"
                    pdir.mkdir(parents=True, exist_ok=True)
                    os.environ[PROFILE_ENV] = str(pdir)
                try:
                    r = _one_run(rate, args.duration, gen, Path(tmp) / f"run{k}")
                except PipelineError as exc:
                    print(f"{rate:>8g} {k + 1:>3}  pipeline failed: {exc}")
                    ok_all = False
                    continue
                finally:
                    os.environ.pop(PROFILE_ENV, None)
                loads += list(r["load"])
                cpu = "  ".join(f"{r['cpu'].get(n, float('nan')):>5.1f}" for n in NODES)
                us = 1e6 * sum(r["cpu"].values()) / max(r["msgs"], 1)
                tag = " (profiled)" if profile else ""
                print(f"{rate:>8g} {k + 1:>3} {r['msgs']:>8d} {r['lost']:>7d} "
                      f"{str(r['same']):>5} {r['wall']:>6.1f} "
                      f"{r['load'][0]:>4.2f}-{r['load'][1]:<4.2f}  cpu s: {cpu}  {us:>6.0f}"
                      f"{tag}")  # fmt: skip
                if r["pacing"]:
                    print(f"{'':>13}trajectory {r['pacing']}")
                if not profile:
                    worst[rate] = max(worst.get(rate, 0), r["lost"])
                    ok_all = ok_all and r["lost"] == 0 and r["same"]
        print(f"{rate:>8g} worst of {args.repeats}: {worst.get(rate, -1)} lost"
              f"{'' if ok_all else '  (not zero loss in every run)'}")  # fmt: skip
        if ok_all and rate in worst and rate > best and all(
            worst.get(r, 1) == 0 for r in args.rates if r < rate
        ):  # fmt: skip
            best = rate
    print(f"end: {_uptime()}")
    if loads:
        print(f"1-minute load average during the runs: {min(loads):.2f} to {max(loads):.2f} "
              f"(2 cores; an idle machine shows < 0.5 before a run)")  # fmt: skip
    print(f"highest zero-loss rate (all {args.repeats} runs) / {TARGET_HZ:g} Hz target: "
          f"{best / TARGET_HZ:.2f} x")  # fmt: skip
    print(f"live_zero_loss_max_rate_hz: {best:g} Hz")
    return best


if __name__ == "__main__":
    main()
