"""Benchmark: ``strapdown-sim generate`` on a scenario vs the bag-writing floor, same run.

* ``total``: :func:`strapdown_ros.generate.generate_dataset` end to end (validation, trajectory,
  Method 2 regeneration, messages, serialization, bag writing), best of ``--repeats``;
* ``floor``: :class:`strapdown_ros.bag.writer.BagWriter` alone writing the very same,
  already serialized payloads (read back from the generated bag, every topic), best of
  ``--repeats``.

Prints the real-time factor (scenario duration / total) and ``total / floor``; the target is
total <= 1.5 x floor (generation and serialization nearly free next to the write).

Usage: python bench/bench_generate.py [SCENARIO] [--storage mcap] [--repeats 3] [--set k=v]
(``--set variation=null`` times the reference streams alone.)
Last line: ``generate_vs_floor: X x``.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from strapdown_ros.bag.batches import Batch
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(DEFAULT))
    parser.add_argument("--storage", default="mcap", choices=("mcap", "sqlite3"))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    scenario = load_scenario(args.scenario, args.overrides)
    tmp = Path(tempfile.mkdtemp(prefix="bench_generate_"))
    try:
        # the floor's input: the same payloads, read back from a generated bag (not timed)
        generate_dataset(scenario, tmp / "input", storage=args.storage)
        contents = read_bag(tmp / "input", raw=True)
        batches = [
            Batch(d.topic, d.msgtype, d.log_time_ns, d.payloads) for d in contents.topics.values()
        ]
        shutil.rmtree(tmp / "input")
        n_msgs = sum(len(b.payloads) for b in batches)
        t_total = t_floor = float("inf")
        summary = None
        for k in range(args.repeats):
            out = tmp / f"gen{k}"
            t0 = time.perf_counter()
            summary = generate_dataset(scenario, out, storage=args.storage)
            t_total = min(t_total, time.perf_counter() - t0)
            shutil.rmtree(out)
            out = tmp / f"floor{k}"
            t0 = time.perf_counter()
            with BagWriter(out, storage=args.storage) as writer:
                writer.write_batches(batches)
            t_floor = min(t_floor, time.perf_counter() - t0)
            shutil.rmtree(out)
        assert summary is not None
        duration = summary.duration_s
        print(
            f"scenario: {args.scenario} ({duration:g} s, {summary.cycles} cycles, "
            f"{n_msgs} messages, {args.storage})"
        )
        print(f"total generate: {t_total:.3f} s  (real-time factor {duration / t_total:.0f}x)")
        print(
            f"floor (writer alone, pre-serialized): {t_floor:.3f} s "
            f"({t_floor / n_msgs * 1e6:.2f} us/msg)"
        )
        print(f"generate_vs_floor: {t_total / t_floor:.2f} x")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
