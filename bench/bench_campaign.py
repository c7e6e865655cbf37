"""Benchmark: ``strapdown-sim campaign`` scaling over Dask workers and its cost per run.

In one process, side by side:

* the same campaign (``--runs`` runs of ``--duration`` s of the scenario) on a local cluster
  with 1 worker and with 2 workers (fresh output directories, the clusters started before the
  clock runs; a warm-up run per worker compiles the numba kernels first, as a long campaign
  amortizes it): ``campaign_speedup_2_workers`` = time(1 worker) / time(2 workers);
* the cost of one run on 1 worker against one ``generate_dataset`` of the same scenario and
  duration (every stream, written to a bag): ``campaign_run_vs_generate`` (< 1: a campaign run
  is cheaper than a full generate, because the shared streams are computed once).

Usage: python bench/bench_campaign.py [SCENARIO] [--runs 8] [--duration 300] [--repeats 2]
Last lines: ``campaign_run_vs_generate: X`` and ``campaign_speedup_2_workers: X x``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from strapdown_ros.campaign.compute import run_one, shared_inputs
from strapdown_ros.campaign.engine import dask_client, run_tasks
from strapdown_ros.campaign.runs import Campaign
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"


def _campaign_time(plan: Campaign, shared, runs: int, workers: int, repeats: int) -> float:
    best = float("inf")
    with dask_client(None, workers) as client:
        # warm-up: one run per worker (numba compilation, imports) outside the clock
        run_tasks(client, list(range(1000, 1000 + workers)), run_one, shared, (plan, None),
                  lambda k, v: None, log=lambda m: None)  # fmt: skip
        for _ in range(repeats):
            t = time.perf_counter()
            res = run_tasks(client, list(range(runs)), run_one, shared, (plan, None),
                            lambda k, v: None, log=print)  # fmt: skip
            best = min(best, time.perf_counter() - t)
            assert not res.failed, res.failed
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(DEFAULT))
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--duration", type=float, default=300.0)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start")
    plan = Campaign(Path(args.scenario), duration_s=args.duration)
    t = time.perf_counter()
    shared = shared_inputs(plan)
    t_shared = time.perf_counter() - t
    print(f"shared ({plan.shared_level}): {t_shared:.2f} s, once per campaign")

    t1 = _campaign_time(plan, shared, args.runs, 1, args.repeats)
    t2 = _campaign_time(plan, shared, args.runs, 2, args.repeats)
    per_run = t1 / args.runs

    scenario = load_scenario(args.scenario, duration_s=args.duration)
    tmp = Path(tempfile.mkdtemp(prefix="bench_campaign_"))
    t_gen = float("inf")
    try:
        for k in range(args.repeats):
            t = time.perf_counter()
            generate_dataset(scenario, tmp / f"g{k}")
            t_gen = min(t_gen, time.perf_counter() - t)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{args.runs} runs of {args.duration:g} s: 1 worker {t1:.2f} s, 2 workers {t2:.2f} s "
          f"(best of {args.repeats})")  # fmt: skip
    print(f"per run (1 worker): {per_run:.3f} s; one generate of the same scenario: {t_gen:.3f} s")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    print(f"campaign_run_vs_generate: {per_run / t_gen:.2f}")
    print(f"campaign_speedup_2_workers: {t1 / t2:.2f} x")


if __name__ == "__main__":
    main()
