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
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.pipeline import PROFILE_ENV

SCENARIO = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"
TARGET_HZ = 1000.0


def live_nodes(scenario: Path) -> tuple[str, ...]:
    """The executables ``run`` starts for ``scenario`` (the chain's live graph), recorder last."""
    from strapdown_ros.config import load_scenario
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import live_graph

    nodes, _ = live_graph(resolve_plan(load_scenario(scenario)))
    return (*(n.executable for n in nodes), "bag_recorder")


NODES = live_nodes(SCENARIO)


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def _proc_cpu(root: int) -> dict[str, float]:
    """CPU seconds so far of the node processes under ``root`` (by console-script name)."""
    tick = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[1]) != root:  # ppid
            continue
        names = [Path(c.decode(errors="replace")).name for c in cmd[:2]]
        name = next((n for n in names if n in NODES), None)
        if name is not None:
            out[name] = (int(fields[11]) + int(fields[12])) / tick
    return out


def _one_run(
    python: str, rate: float, duration: float, gen: Path, live: Path, flow: bool,
    period: float | None = None,
) -> dict:
    """One ``strapdown-sim run`` of the tree of ``python``; the lag lines relayed as they come."""
    load0 = os.getloadavg()[0]
    cmd = [python, "-m", "strapdown_ros.cli", "run", str(SCENARIO), "--out", str(live),
           "--duration", str(duration), "--set", f"rate_hz={rate:g}", "--force"]  # fmt: skip
    if flow:
        cmd.append("--unpaced")
    if period is not None:
        cmd += ["--publish-period", f"{period:g}"]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if "behind real time" in line:
                print(f"{'':>13}{line.strip()}", flush=True)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    start_cpu: dict[str, float] = {}
    marker = live.parent / f"{live.name}.logs" / "bag_recorder.log"
    while proc.poll() is None:  # start-up done: the recorder subscribed to the source
        if not start_cpu and "subscribed to /reference/imu" in _read(marker):
            start_cpu = _proc_cpu(proc.pid)
        time.sleep(0.1)
    reader.join(timeout=10)
    wall = time.monotonic() - t0
    load1 = os.getloadavg()[0]
    text = "".join(lines)
    if proc.returncode not in (0, 1) or "topics:" not in text:
        raise RuntimeError(f"strapdown-sim run failed ({proc.returncode}):\n{text[-3000:]}")
    cpu = {n: float(v) for n, v in re.findall(r"(\w+_node|bag_recorder) ([0-9.]+) s", _cpu(text))}
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    # each topic's payloads as a multiset, as the run tests compare them: /tf has three
    # publishers, whose messages the recorder may interleave in another order than generate's
    differ = sorted(
        t for t in set(a.topics) | set(b.topics)
        if t not in a.topics or t not in b.topics
        or sorted(bytes(p) for p in a.topics[t].payloads)
        != sorted(bytes(p) for p in b.topics[t].payloads)
    )
    same = not differ
    if differ:
        print(f"{'':>13}payloads differ from generate's on {', '.join(differ)}", flush=True)
    msgs = sum(len(d) for d in a.topics.values())
    expected = sum(len(d) for d in b.topics.values())
    pacing = re.search(r"pacing:\s+(.*)", text)
    return {
        "msgs": msgs,
        "expected": expected,
        "lost": expected - msgs,
        "same": same,
        "wall": wall,
        "load": (load0, load1),
        "cpu": cpu,
        "cpu_run": {n: v - start_cpu.get(n, 0.0) for n, v in cpu.items()},
        "startup_known": bool(start_cpu),
        "pacing": pacing.group(1) if pacing else "",
        "lag_lines": sum("behind real time" in line for line in lines),
    }


def _read(path: Path) -> str:
    try:
        return path.read_text(errors="replace")
    except OSError:
        return ""


def _cpu(text: str) -> str:
    m = re.search(r"cpu:\s+(.*)", text)
    return m.group(1) if m else ""


def main(argv: list[str] | None = None) -> float:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[1000, 2000, 2500, 4000])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", type=Path, default=None, metavar="DIR")
    parser.add_argument("--base", type=Path, default=None, metavar="TREE",
                        help="an earlier source tree (with its .venv), run alternately")
    parser.add_argument("--flow", action="store_true",
                        help="flow-controlled unpaced runs (lossless: CPU per message only)")
    parser.add_argument("--publish-period", type=float, default=None, metavar="S",
                        help="the source's publish groups (run --publish-period; default: "
                        "run's own default)")
    parser.add_argument("--against-period", type=float, default=None, metavar="S",
                        help="also run this tree with --publish-period S, alternately")
    args = parser.parse_args(argv)
    trees = [("this", sys.executable, args.publish_period)]
    if args.base is not None:
        trees.append(("base", str(args.base.resolve() / ".venv" / "bin" / "python"), None))
    if args.against_period is not None:
        trees.append((f"p{args.against_period * 1e3:g}ms", sys.executable, args.against_period))
    best = 0.0
    loads: list[float] = []
    mode = "unpaced, flow control" if args.flow else "rate_factor 1"
    print(f"scenario: {SCENARIO.name}, {args.duration:g} s of data per run, {mode}, "
          f"{args.repeats} runs per rate" + (f", base tree {args.base}" if args.base else "")
          + "".join(f", {t}: publish period {'default' if p is None else f'{p:g} s'}"
                    for t, _, p in trees))  # fmt: skip
    print(f"start: {_uptime()}")
    head = "  ".join(f"{n.split('_')[0][:4]:>5}" for n in NODES)
    print(f"{'rate Hz':>8} {'run':>8} {'msgs':>8} {'lost':>7} {'same':>5} {'wall s':>6} "
          f"{'load':>10}  {head}  {'total':>6}  (CPU µs per recorded message)")  # fmt: skip
    worst: dict[float, int] = {}
    per_msg: dict[str, list[float]] = {}
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
                for tag, python, period in trees if not profile else trees[:1]:
                    try:
                        r = _one_run(python, rate, args.duration, gen, Path(tmp) / f"run{k}",
                                     args.flow, period)  # fmt: skip
                    except RuntimeError as exc:
                        print(f"{rate:>8g} {k + 1:>3} {tag}  pipeline failed: {exc}")
                        ok_all = False
                        continue
                    loads += list(r["load"])
                    msgs = max(r["msgs"], 1)
                    run = r["cpu_run"]
                    cells = "  ".join(f"{1e6 * run.get(n, float('nan')) / msgs:>5.1f}"
                                      for n in NODES)  # fmt: skip
                    total = 1e6 * sum(run.values()) / msgs
                    label = f"{k + 1} {tag}" + (" prof" if profile else "")
                    print(f"{rate:>8g} {label:>8} {r['msgs']:>8d} {r['lost']:>7d} "
                          f"{str(r['same']):>5} {r['wall']:>6.1f} "
                          f"{r['load'][0]:>4.2f}-{r['load'][1]:<4.2f}  {cells}  "
                          f"{total:>6.1f}" + ("" if r["startup_known"] else " (start-up in)"))
                    if r["pacing"]:
                        print(f"{'':>13}trajectory {r['pacing']}")
                    if not profile:
                        per_msg.setdefault(f"{rate:g} {tag}", []).append(total)
                    if not profile and tag == "this" and not args.flow:
                        worst[rate] = max(worst.get(rate, 0), r["lost"])
                        ok_all = ok_all and r["lost"] == 0 and r["same"]
                    if args.flow and not r["same"]:
                        print(f"{'':>13}NOT IDENTICAL to generate's bag")
                os.environ.pop(PROFILE_ENV, None)
        if not args.flow:
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
    for key, values in per_msg.items():
        print(f"cpu_us_per_msg {key}: median {statistics.median(values):.1f} "
              f"(start-up excluded, all processes)")
    if args.flow:
        print("live_zero_loss_max_rate_hz: not measured (--flow: flow-controlled runs)")
        return best
    print(f"highest zero-loss rate (all {args.repeats} runs) / {TARGET_HZ:g} Hz target: "
          f"{best / TARGET_HZ:.2f} x")  # fmt: skip
    print(f"live_zero_loss_max_rate_hz: {best:g} Hz")
    return best


if __name__ == "__main__":
    main()
