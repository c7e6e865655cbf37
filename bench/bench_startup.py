"""Benchmark: a node's start-up time, from process start to "subscribed to" its inputs.

Starts each node of the live pipeline alone (no other node, no subscriber expected on its
outputs, so it subscribes as soon as it is set up; the trajectory node, which has no input, until
it logs its scenario line, i.e. is ready to publish) on ``default.yaml`` in a private ROS domain
and measures the wall time from ``Popen`` to the first log line that says it subscribed; also
``strapdown-sim validate`` of the same file (process start to exit). Each figure is the median
of ``--repeats`` starts, with the 1-minute load average before and after. Start-up is import
time plus the set-up the node does before it subscribes (for a processing node: reading the
scenario, its plan, the stage objects).

With ``--base DIR`` (a checkout of an earlier commit, e.g. ``git worktree add /tmp/base REV``)
every start alternates between that tree (first on ``PYTHONPATH``) and this one, and each line
ends with the ratio this / base, measured side by side under the same load.

Usage: python bench/bench_startup.py [--repeats 5] [--nodes trajectory_node ...] [--base DIR]
Last line: ``startup_max_s: X`` (the slowest node's median, this tree).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_live import live_nodes  # bench/ is the script's directory

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"

NODES = live_nodes(SCENARIO)  # the nodes `run` starts for it
#: Seconds a start may take before the bench gives up on it.
TIMEOUT_S = 60.0


def _exe(name: str) -> str:
    return str(Path(sys.executable).parent / name)


def _env(base: Path | None = None) -> dict[str, str]:
    env = dict(os.environ)
    if base is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(base), env.get("PYTHONPATH", "")]).rstrip(":")
    env.update(
        ROS_DOMAIN_ID=str(150 + os.getpid() % 80),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        RMW_IMPLEMENTATION=env.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp",
        PYTHONUNBUFFERED="1",
    )
    return env


#: What a node logs when its set-up is done: "subscribed to" its inputs; the trajectory node
#: (no inputs) its scenario line, printed once its trajectory is built and before it publishes;
#: the recorder its "recording N topic(s)" line (it subscribes to each topic once discovered).
READY = {"trajectory_node": "]: scenario ", "bag_recorder": "]: recording "}


def node_startup_s(name: str, work: Path, base: Path | None = None) -> float:
    """Seconds from process start to the node's ready line (then it is stopped)."""
    args = [_exe(name), "--ros-args", "-p", f"scenario:={SCENARIO}"]
    if name == "trajectory_node":
        args += ["-p", "rate_factor:=0.0"]
    if name == "bag_recorder":
        args += ["-p", f"output:={work / 'bag'}", "-p", "force:=true"]
    log = work / f"{name}.log"
    with open(log, "w") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, env=_env(base), stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL)  # fmt: skip
        try:
            while time.perf_counter() - t0 < TIMEOUT_S:
                if READY.get(name, "subscribed to") in log.read_text(errors="replace"):
                    return time.perf_counter() - t0
                if proc.poll() is not None:
                    raise RuntimeError(f"{name} exited ({proc.returncode}):\n{log.read_text()}")
                time.sleep(0.01)
            raise RuntimeError(f"{name}: not ready within {TIMEOUT_S:g} s")
        finally:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def validate_s(work: Path, base: Path | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run([_exe("strapdown-sim"), "validate", str(SCENARIO)], check=True,
                   capture_output=True, env=_env(base))  # fmt: skip
    return time.perf_counter() - t0


def _line(name: str, times: list[float], base: list[float] | None) -> str:
    text = f"  {name:<24} median {statistics.median(times):.2f} s (min {min(times):.2f}, max "
    text += f"{max(times):.2f})"
    if base:
        ratio = statistics.median(times) / statistics.median(base)
        text += f"; base median {statistics.median(base):.2f} s; ratio this/base {ratio:.2f}"
    return text


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--nodes", nargs="+", default=list(NODES))
    parser.add_argument("--base", type=Path, help="an earlier source tree, measured alternately")
    args = parser.parse_args(argv)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    results: dict[str, float] = {}
    checks: list[tuple[str, object]] = [("strapdown-sim validate", validate_s)]
    checks += [(name, lambda work, base, name=name: node_startup_s(name, work, base))
               for name in args.nodes]  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bench_startup_") as tmp:
        work = Path(tmp)
        for name, measure in checks:
            times: list[float] = []
            base: list[float] = []
            for _ in range(args.repeats):
                if args.base is not None:
                    base.append(measure(work, args.base))  # type: ignore[operator]
                times.append(measure(work, None))  # type: ignore[operator]
            results[name] = statistics.median(times)
            print(_line(name, times, base))
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    worst = max(v for k, v in results.items() if k in args.nodes)
    print(f"startup_max_s: {worst:.2f}")
    return worst


if __name__ == "__main__":
    main()
