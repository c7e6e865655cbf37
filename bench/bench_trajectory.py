"""Benchmark: segments trajectory build and vectorized evaluation, and LatLonPath build.

The timings that ``test/test_traj_segments.py`` used to assert (wall-clock budgets do not
belong in tests: a loaded machine fails them, a fast one hides a regression). The trajectories
are the test's own (``INITIAL``/``MIXED``, ``FAST_TURNS``, ``NEAR_POLE``, built with its
``build`` helper), so the figures follow the test cases. Each figure is the best of
``--repeats`` runs and is printed beside the former budget as a ratio (``< 1``: within it).

* ``build``: the MIXED segments trajectory from its scenario values (budget 0.25 s);
* ``local_truth``: MIXED evaluated at 120 000 times in one call (budget 1.0 s);
* ``latlon_path_<case>``: ``LatLonPath`` of each case from its pieces (budget 0.5 s).

Usage: python bench/bench_trajectory.py [--repeats 5]
Last line: ``local_truth_120k_s: X``.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: Former test budgets (s).
BUDGETS = {"build": 0.25, "local_truth": 1.0, "latlon_path": 0.5}


def _test_module():
    """``test/test_traj_segments.py`` (its trajectories and helpers), imported by path."""
    sys.path.insert(0, str(REPO / "test"))
    spec = importlib.util.spec_from_file_location(
        "test_traj_segments", REPO / "test" / "test_traj_segments.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def best_of(repeats: int, fn) -> tuple[float, object]:
    best, result = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    tm = _test_module()

    build_s, mixed = best_of(args.repeats, lambda: tm.build(tm.INITIAL, tm.MIXED))
    t = np.linspace(0.0, mixed.duration, 120_000)
    truth_s, _ = best_of(args.repeats, lambda: mixed.local_truth(t))
    rows = [("build", build_s, BUDGETS["build"]), ("local_truth", truth_s, BUDGETS["local_truth"])]
    cases = {"mixed": (tm.INITIAL, tm.MIXED), "fast": tm.FAST_TURNS, "pole": tm.NEAR_POLE}
    for name, case in cases.items():
        traj = tm.build(*case)
        first = traj.local_truth(np.array([0.0]))
        breaks, velocity = tm.piece_breaks(traj), tm.velocity_of(traj)
        seconds, _ = best_of(
            args.repeats,
            lambda traj=traj, first=first, breaks=breaks, velocity=velocity: tm.LatLonPath(
                breaks, first.lat[0], first.lon[0], velocity
            ),
        )
        rows.append((f"latlon_path_{name}", seconds, BUDGETS["latlon_path"]))

    print(f"{'what':<22} {'best (s)':>10} {'budget (s)':>11} {'ratio':>7}")
    for name, seconds, budget in rows:
        print(f"{name:<22} {seconds:10.4f} {budget:11.2f} {seconds / budget:7.3f}")
    print(f"local_truth_120k_s: {truth_s:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
