"""Benchmark: vectorized Savage 2020 eqs. (2)-(4) update vs the same update as a Python loop.

Both paths compute one exact cycle for each of N independent (state, increment) pairs; the
vectorized path does all N in one call, the loop calls the single-cycle form N times. The loop
is timed on a subset (it is slow) and compared per cycle. Both run in this process, side by
side, and their results are checked equal before timing counts.

Usage: python bench/bench_exact.py [--cycles 1000000] [--loop-cycles 20000]
Last line: ``speedup_vs_loop: X x``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from strapdown_ros.core.exact_update import exact_update, exact_update_single
from strapdown_ros.core.rotations import dcm_from_rotvec


def make_inputs(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    c = dcm_from_rotvec(rng.normal(size=(n, 3)))
    v = rng.normal(size=(n, 3)) * 100.0
    r = rng.normal(size=(n, 3)) * 6.4e6
    dalpha = rng.normal(size=(n, 3)) * 1e-3
    dv = rng.normal(size=(n, 3)) * 0.1
    g0 = rng.normal(size=(n, 3)) * 9.8
    g1 = g0 + rng.normal(size=(n, 3)) * 1e-6
    return c, v, r, dalpha, dv, g0, g1


def best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=1_000_000)
    parser.add_argument("--loop-cycles", type=int, default=20_000)
    args = parser.parse_args()
    period = 0.005
    inputs = make_inputs(args.cycles)
    sub = [a[: args.loop_cycles] for a in inputs]

    def vectorized():
        return exact_update(*inputs, period)

    def loop():
        out = []
        for i in range(args.loop_cycles):
            out.append(exact_update_single(*(a[i] for a in sub), period))
        return out

    # Same results before timing means anything.
    cv, vv, rv = exact_update(*sub, period)
    for i, (cs, vs, rs) in enumerate(loop()):
        assert np.allclose(cv[i], cs, atol=1e-15) and np.allclose(vv[i], vs, atol=1e-11)
        assert np.allclose(rv[i], rs, atol=1e-8)

    t_vec = best_of(vectorized, 3)
    t_loop = best_of(loop, 2)
    per_vec = t_vec / args.cycles
    per_loop = t_loop / args.loop_cycles
    print(f"cycles (vectorized): {args.cycles}")
    print(
        f"vectorized: {t_vec:.3f} s total, {per_vec * 1e9:.1f} ns/cycle, "
        f"{1 / per_vec:,.0f} cycles/s"
    )
    print(
        f"python loop ({args.loop_cycles} cycles): {t_loop:.3f} s total, "
        f"{per_loop * 1e9:.1f} ns/cycle, {1 / per_loop:,.0f} cycles/s"
    )
    print(f"speedup_vs_loop: {per_loop / per_vec:.1f} x")


if __name__ == "__main__":
    main()
