"""Benchmark: highest IMU rate the live pipeline records with zero loss (``strapdown-sim run``).

Runs the whole live pipeline (trajectory_node → variation_node → navigator_node, bag_recorder,
separate processes, real DDS over loopback, ``rate_factor`` 1 = real time) on ``default.yaml``
shortened to ``--duration`` seconds, at increasing IMU rates, and checks each recording
against the message counts the scenario produces and, payload for payload, against
``strapdown-sim generate``'s bag of the same scenario. The ratio printed is the highest
zero-loss rate over the 1 kHz target.

Usage: python bench/bench_live.py [--rates 200 500 1000 2000 2500 4000] [--duration 20]
Last line: ``live_zero_loss_max_rate_hz: X Hz``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.pipeline import PipelineError, run_pipeline

SCENARIO = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"
TARGET_HZ = 1000.0


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    rates = [200, 500, 1000, 2000, 2500, 4000]
    parser.add_argument("--rates", type=float, nargs="+", default=rates)
    parser.add_argument("--duration", type=float, default=20.0)
    args = parser.parse_args(argv)
    best = 0.0
    print(f"scenario: {SCENARIO.name}, {args.duration:g} s of data per run, rate_factor 1")
    print(f"{'rate Hz':>8} {'msgs':>8} {'wall s':>7} {'lost':>5} {'== generate':>12}")
    for rate in sorted(args.rates):
        with tempfile.TemporaryDirectory() as tmp:
            live, gen = Path(tmp) / "run", Path(tmp) / "gen"
            overrides = [f"rate_hz={rate:g}"]
            subprocess.run(
                [sys.executable, "-m", "strapdown_ros.cli", "generate", str(SCENARIO),
                 "--out", str(gen), "--duration", str(args.duration), "--quiet",
                 "--set", overrides[0]],
                check=True,
            )  # fmt: skip
            t0 = time.monotonic()
            try:
                result = run_pipeline(
                    SCENARIO, live, overrides=overrides, duration_s=args.duration,
                    progress=False,
                )  # fmt: skip
            except PipelineError as exc:
                print(f"{rate:>8g}  pipeline failed: {exc}")
                continue
            wall = time.monotonic() - t0
            a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
            same = set(a.topics) == set(b.topics) and all(
                [bytes(p) for p in a.topics[t].payloads] == [bytes(p) for p in d.payloads]
                for t, d in b.topics.items()
            )
            lost = sum(max(v, 0) for v in result.lost.values())
            msgs = sum(result.counts.values())
            print(f"{rate:>8g} {msgs:>8d} {wall:>7.1f} {lost:>5d} {str(same):>12}")
            if lost == 0 and same:
                best = max(best, rate)
    print(f"highest zero-loss rate / {TARGET_HZ:g} Hz target: {best / TARGET_HZ:.2f} x")
    print(f"live_zero_loss_max_rate_hz: {best:g} Hz")
    return best


if __name__ == "__main__":
    main()
