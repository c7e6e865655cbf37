"""Benchmark: multirate navigator (Waldmann Table 1) fast-cycle throughput, numba vs Python.

Offline run of :func:`strapdown_ros.core.navigation.navigate_multirate` on the reference of
``config/scenarios/default.yaml`` with N = 10, P = 2. ``steps/s`` counts IMU increments
(``T_gyr`` fast steps) processed per second. The compiled engine (all ``T_nav`` cycles in one
numba kernel) and the per-cycle Python engine run in this process; the Python engine is timed
on the first ``--python-steps`` increments. The one-time JIT compile is excluded from the
throughput and reported separately: cold (a fresh interpreter with an empty numba cache dir)
and the first call in this process (compile, or load from numba's on-disk cache). Results of the
two engines are checked equal on the subset before timing counts.

The high-accuracy (``exact``) mode is timed the same way (compiled kernel vs the same kernel
interpreted, on the first 4000 increments).

Usage: python bench/bench_navigator.py [--duration-s S] [--python-steps 20000] [--repeats 5]
Last line: ``navigator_steps_per_s: X steps/s`` (compiled engine).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

from strapdown_ros.config import load_scenario
from strapdown_ros.core.navigation import _kernels, navigate_multirate, state_from_stream
from strapdown_ros.stages.trajectory import generate_reference

SCENARIO = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"
N, P = 10, 2


def best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


_COLD = textwrap.dedent(f"""
    import time
    import numpy as np
    from strapdown_ros.core.navigation import NavState, navigate_multirate
    st = NavState(0.0, 0.5, 0.1, 100.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    t0 = time.perf_counter()
    navigate_multirate(st, np.zeros(({N}, 3)), np.zeros(({N}, 3)), 0.005, {N}, {P}, engine="numba")
    print(time.perf_counter() - t0)
""")


def cold_compile_s() -> float:
    """Time of the first kernel call in a fresh interpreter with an empty numba cache dir."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        root = str(SCENARIO.parents[2])
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
        out = subprocess.run(
            [sys.executable, "-c", _COLD], env=env, capture_output=True, text=True, check=True
        )
    return float(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration-s", type=float, default=None, help="override duration")
    parser.add_argument("--python-steps", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    if not _kernels.HAVE_NUMBA:
        raise SystemExit("numba is not importable; nothing to compare")

    stream = generate_reference(load_scenario(SCENARIO, duration_s=args.duration_s))
    st = state_from_stream(stream)
    da, dv, t_gyr = stream.dalpha, stream.dv, stream.period
    steps = (da.shape[0] // N) * N
    py_steps = min((args.python_steps // N) * N, steps)

    def run(engine: str, m: int):
        return navigate_multirate(st, da[:m], dv[:m], t_gyr, N, P, engine=engine)

    # One-time compile (or load from numba's on-disk cache), excluded from the throughput.
    t_cold = cold_compile_s()
    t0 = time.perf_counter()
    run("numba", N)
    t_first = time.perf_counter() - t0
    hits = sum(_kernels.multirate_kernel.stats.cache_hits.values())

    # Same results before timing means anything.
    a, b = run("numba", py_steps), run("python", py_steps)
    for key in ("lat", "lon", "alt", "v_ned", "q_b_n"):
        x, y = getattr(a, key), getattr(b, key)
        assert np.allclose(x, y, rtol=1e-12, atol=1e-12 * np.abs(y).max()), key

    t_nb = best_of(lambda: run("numba", steps), args.repeats)
    t_py = best_of(lambda: run("python", py_steps), max(1, min(args.repeats, 2)))
    rate_nb, rate_py = steps / t_nb, py_steps / t_py
    print(f"scenario: {SCENARIO.name}, {steps} increments at {1 / t_gyr:g} Hz, N={N}, P={P}")
    print(f"numba cold JIT compile (fresh interpreter, empty cache): {t_cold:.3f} s")
    how = "cache load" if hits else "compile"
    print(f"numba first call in this process ({how}): {t_first:.3f} s")
    print(f"numba:  {t_nb * 1e3:.3f} ms for {steps} steps, {rate_nb:,.0f} steps/s")
    print(f"python: {t_py * 1e3:.3f} ms for {py_steps} steps, {rate_py:,.0f} steps/s")
    print(f"speedup_vs_python: {rate_nb / rate_py:.1f} x")

    # High-accuracy mode: the same increments through the exact per-increment composition.
    def run_exact(engine: str, m: int):
        return navigate_multirate(st, da[:m], dv[:m], t_gyr, N, P, mode="exact", engine=engine)

    run_exact("numba", N)  # compile / cache load, excluded
    t_ex = best_of(lambda: run_exact("numba", steps), args.repeats)
    ex_py_steps = min(py_steps, 4000)
    t_ex_py = best_of(lambda: run_exact("python", ex_py_steps), 1)
    rate_ex, rate_ex_py = steps / t_ex, ex_py_steps / t_ex_py
    print(f"exact mode numba:  {t_ex * 1e3:.3f} ms for {steps} steps, {rate_ex:,.0f} steps/s")
    print(f"exact mode python: {rate_ex_py:,.0f} steps/s (interpreted kernel)")
    print(f"exact_speedup_vs_python: {rate_ex / rate_ex_py:.1f} x")
    print(f"exact_navigator_steps_per_s: {rate_ex:.0f} steps/s")
    print(f"navigator_steps_per_s: {rate_nb:.0f} steps/s")
    return rate_nb


if __name__ == "__main__":
    main()
