"""Benchmark: Method 2 variation throughput, vectorized vs one pair at a time, same run.

Reference: the default scenario's reference stream (generated once, not timed). Offsets: a
constant lever arm with sinusoidal bending and a scanning attitude offset. Timed:

* ``vectorized``: :func:`strapdown_ros.core.variation.generate_variation` on the whole stream
  (the offline path, no bag I/O);
* ``per pair``: the same function on 5-sample windows, one Method 2 pair per call — what the
  streaming ``variation_node`` does — on a subset, compared per cycle.

Both give bit-identical increments (checked). Usage: python bench/bench_variation.py
Last line: ``variation_cycles_per_s: X cycles/s``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from strapdown_ros.config import load_scenario
from strapdown_ros.core.rotations import dcm_from_euler
from strapdown_ros.core.variation import OffsetArrays, _window, generate_variation
from strapdown_ros.stages.trajectory import generate_reference

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"


def offsets(n: int, period: float) -> OffsetArrays:
    t = np.arange(n) * period
    lever = np.tile([2.0, 6.0, -0.5], (n, 1))
    lever[:, 2] += 0.02 * np.sin(2 * np.pi * 3.0 * t)
    scan = dcm_from_euler(0 * t, 0.1 * np.sin(0.5 * t), 0.5 * np.sin(0.3 * t))
    return OffsetArrays(lever, np.zeros((n, 3)), scan)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pairs", type=int, default=2000, help="pairs timed one at a time")
    parser.add_argument("--duration", type=float, default=None, help="seconds of the reference")
    args = parser.parse_args(argv)
    reference = generate_reference(load_scenario(DEFAULT, (), args.duration))
    off = offsets(reference.cycles + 1, reference.period)
    best = np.inf
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        whole = generate_variation(reference, off)
        best = min(best, time.perf_counter() - t0)
    per_vec = best / whole.cycles
    t0 = time.perf_counter()
    for k in range(1, args.pairs + 1):
        a = 2 * k - 1
        win = _window(reference, a, 5)
        o = OffsetArrays(off.lever_arm[a : a + 5], off.displacement[a : a + 5],
                         off.c_bvar_bref[a : a + 5])  # fmt: skip
        w = generate_variation(win, o, lead=1)
        assert np.array_equal(w.dv, whole.dv[2 * k : 2 * k + 2])
    per_pair = (time.perf_counter() - t0) / (2 * args.pairs)
    print(f"reference: {DEFAULT.name}, {reference.cycles} cycles")
    print(
        f"vectorized Method 2: {best:.3f} s for {whole.cycles} cycles ({1 / per_vec:,.0f} cycles/s)"
    )
    print(f"one pair per call: {1 / per_pair:,.0f} cycles/s; ratio {per_pair / per_vec:.0f} x")
    print(f"variation_cycles_per_s: {1 / per_vec:.0f} cycles/s")


if __name__ == "__main__":
    main()
