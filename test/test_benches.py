"""Every script in bench/ runs to its end with tiny arguments (slow tier).

Only that the script finishes and prints its result line is checked — never a figure: the
figures are measured by running the benches themselves (docs/benchmarks.md). A bench that
needs the peers (pyins, requirements/bench.txt) runs up to its comparison when they are
installed; without them it must stop with the message saying how to install them (exit status
1, no traceback), as bench_peers does.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BENCH = REPO / "bench"
HAVE_PYINS = importlib.util.find_spec("pyins") is not None

#: script → (tiny arguments, text its output must hold at the end)
ROS_FREE = {
    "bench_aided.py": (
        ["--compare", "5", "--short", "5", "--long", "10"] if HAVE_PYINS
        else ["--no-pyins", "--short", "5", "--long", "10"],
        "rss_growth_long:",
    ),  # fmt: skip
    "bench_aiding.py": (["--repeats", "1", "--messages", "300"], None),
    "bench_campaign.py": (["--runs", "2", "--duration", "3", "--repeats", "1"], None),
    "bench_exact.py": (["--cycles", "20000", "--loop-cycles", "500"], "speedup_vs_loop"),
    "bench_generate.py": (["--repeats", "1", "--set", "duration_s=2"], "generate_vs_floor"),
    "bench_navigator.py": (
        ["--duration-s", "5", "--python-steps", "200", "--repeats", "1"], "steps/s",
    ),  # fmt: skip
    "bench_serialize.py": (["--cycles", "2000", "--repeats", "1"], None),
    "bench_trajectory.py": (["--repeats", "1"], "local_truth_120k_s:"),
    "bench_variation.py": (
        ["--repeats", "1", "--pairs", "20", "--duration", "5"], "variation_cycles_per_s:",
    ),  # fmt: skip
    "waldmann_table3.py": (["--duration", "10", "--no-variants", "--no-phase"], None),
}
#: the benches that start nodes over DDS
ROS = {
    "bench_live.py": (
        ["--rates", "200", "--duration", "2", "--repeats", "1"], "live_zero_loss_max_rate_hz:",
    ),  # fmt: skip
    "bench_player.py": (["--duration", "1", "--rates", "200"], "player_p99_ms_200hz:"),
    "bench_startup.py": (["--repeats", "1", "--nodes", "trajectory_node"], "startup_max_s:"),
    "bench_node_timing.py": (["--repeats", "1"], "variation_lag_median_ms:"),
}
#: the benches comparing with the peers: tiny arguments
PEERS = {"bench_peers.py": (["--duration-s", "20", "--repeats", "1"], "speedup_vs_pyins")}


def test_every_bench_is_listed():
    listed = set(ROS_FREE) | set(ROS) | set(PEERS)
    assert {p.name for p in BENCH.glob("*.py")} == listed


def _run(script: str, args: list[str], env: dict[str, str] | None, timeout: float):
    return subprocess.run(
        [sys.executable, str(BENCH / script), *args], cwd=REPO, env=env, capture_output=True,
        text=True, timeout=timeout,
    )  # fmt: skip


def _check(script: str, proc: subprocess.CompletedProcess, expect: str | None) -> None:
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"{script} exited {proc.returncode}:\n{out[-4000:]}"
    assert "Traceback" not in out, out[-4000:]
    if expect is not None:
        assert expect in proc.stdout, f"{script}: no {expect!r} in\n{proc.stdout[-3000:]}"


@pytest.mark.slow
@pytest.mark.timeout(1800)
@pytest.mark.parametrize("script", sorted(ROS_FREE))
def test_bench_runs(script):
    args, expect = ROS_FREE[script]
    _check(script, _run(script, args, None, 900), expect)


@pytest.mark.slow
@pytest.mark.timeout(1800)
@pytest.mark.parametrize("script", sorted(ROS))
def test_ros_bench_runs(script, ros_env):
    args, expect = ROS[script]
    _check(script, _run(script, args, ros_env, 1200), expect)


@pytest.mark.slow
@pytest.mark.timeout(1800)
@pytest.mark.parametrize("script", sorted(PEERS))
def test_peer_bench_runs_or_says_what_is_missing(script):
    args, expect = PEERS[script]
    proc = _run(script, args, None, 900)
    if HAVE_PYINS:
        _check(script, proc, expect)
    else:
        out = proc.stdout + proc.stderr
        assert proc.returncode == 1, out[-3000:]
        assert "Traceback" not in out and "requirements/bench.txt" in out, out[-3000:]
