"""Benchmark: bag_player's pacing error against the wall clock at 200 Hz and 1 kHz, vs the floor.

For each rate, a bag of the default scenario's reference stream (Imu, Odometry, NavSatFix, with
the TF, map-frame odometry and aiding topics derived from it; ``--duration`` s, ``rate_hz``
overridden) is written by ``strapdown-sim generate``. The subscriber subscribes to every topic
of the bag (with the type the bag stores) and /clock: the player waits for a subscription on
each topic it plays. Then, in the same run:

* ``floor``: a bare loop in this process that sleeps until each due time of the bag's schedule
  (``time.sleep`` to the deadline, no ROS, no bag, normal scheduler): the wall-clock pacing the
  machine allows at that moment.
* ``player``: ``bag_player`` (rate_factor 1, /clock on) publishes the bag to a subscriber
  process (this script with ``--subscribe``: raw subscriptions on rclpy's EventsExecutor).
  *publish - due* is the player's own report: CLOCK_MONOTONIC just before each publish minus its
  due time (p50/p99/max over every message). *delivered* is measured by the subscriber, which
  stamps every arrival with ``time.monotonic`` (system-wide clock): arrival_i - (a + t_i - t_0),
  t the log time (the k-th arrival on a topic is its k-th message: reliable, in order), the
  anchor a chosen so that the earliest message has error 0 (lateness beyond
  the fastest delivery; DDS and the subscriber's own scheduling included).
  ``p99_vs_floor`` = player p99 / floor p99 puts the figure in context on a loaded machine.
* ``player, SingleThreadedExecutor``: the same with ``executor:=single_threaded`` (the
  baseline: what the player did before it ran on the EventsExecutor).
* ``player, SCHED_FIFO 10``: the same with ``realtime_priority:=10`` for the player (and the
  subscriber's thread on SCHED_FIFO too), if the process may; otherwise the line says so.

Target: player p99 <= 1 ms. Usage: python bench/bench_player.py [--duration 10] [--rates 200
1000]. Last lines per rate: ``player_p99_ms_<rate>``, ``delivered_p99_ms_<rate>``,
``player_rt_p99_ms_<rate>``, ``delivered_rt_p99_ms_<rate>``.
"""

from __future__ import annotations

import argparse
import os
import pickle
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
OVERRIDES = ["variation=null", "navigator=null", "imu_errors=null", "aided=null"]
CLOCK = ("/clock", "rosgraph_msgs/msg/Clock")
PACING = re.compile(r"pacing error over \d+ messages: p50 (\S+) ms, p99 (\S+) ms, max (\S+) ms")


def _bin(name: str) -> str:
    local = Path(sys.executable).parent / name
    return str(local) if local.exists() else name


def subscribe(
    out: str, counts: dict[str, int], types: dict[str, str], timeout_s: float, rt: int
) -> int:
    """Subscriber mode: record the arrival time of every message per topic; write ``out``."""
    if rt > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt))
        except OSError:
            pass
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from strapdown_ros.nodes.message_types import message_class

    rclpy.init()
    node = rclpy.create_node("bench_player_subscriber")
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_ALL, depth=1, reliability=ReliabilityPolicy.RELIABLE
    )
    arrival: dict[str, list[float]] = {t: [] for t in counts}
    subs = []
    for topic in counts:

        def on_message(data: bytes, append=arrival[topic].append) -> None:
            append(time.monotonic())

        cls = message_class(types[topic])
        subs.append(node.create_subscription(cls, topic, on_message, qos, raw=True))
    executor = EventsExecutor()
    executor.add_node(node)
    print("READY", flush=True)
    deadline = time.monotonic() + timeout_s
    while any(len(arrival[t]) < n for t, n in counts.items()) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    with open(out, "wb") as f:
        pickle.dump({"arrival": arrival}, f)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def floor(stamps_ns: np.ndarray) -> np.ndarray:
    """Errors (s) of a bare sleep-until-deadline loop over the same schedule."""
    t = (stamps_ns - stamps_ns[0]) * 1e-9
    start = time.monotonic() + 0.05
    errors = np.empty(t.size)
    for i, dt in enumerate(t):
        deadline = start + dt
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(remaining)
        errors[i] = time.monotonic() - deadline
    return errors


def stats(errors_s: np.ndarray) -> str:
    e = np.asarray(errors_s) * 1e3
    p50, p99 = np.percentile(e, [50, 99])
    return f"p50 {p50:.3f} ms, p99 {p99:.3f} ms, max {e.max():.3f} ms"


def play(
    bag: Path, times: dict[str, np.ndarray], types: dict[str, str], duration_s: float,
    tmp: Path, env, rt: int, executor: str = "events",
):  # fmt: skip
    """Play ``bag`` to a subscriber process (``times``: each topic's log times, ns, in order;
    ``types``: its message type); returns (subscriber errors (s), player's p99 (ms), player's
    report)."""
    out = tmp / "sub.pkl"
    counts = {t: len(v) for t, v in times.items()}
    spec = ",".join(f"{t}={types[t]}={n}" for t, n in counts.items())
    sub = subprocess.Popen(
        [sys.executable, __file__, "--subscribe", str(out), "--counts", spec,
         "--timeout", str(duration_s + 60), "--rt", str(rt)],
        env=env, stdout=subprocess.PIPE, text=True, cwd=REPO,
    )  # fmt: skip
    assert sub.stdout is not None and sub.stdout.readline().strip() == "READY"
    args = [_bin("bag_player"), "--ros-args"]
    params = [f"bag:={bag}", "wait_for_subscribers:=1", "qos_depth:=100000"]
    for p in (*params, f"realtime_priority:={rt}", f"executor:={executor}"):
        args += ["-p", p]
    player = subprocess.run(
        args, env=env, capture_output=True, text=True, timeout=duration_s + 120, cwd=REPO
    )
    sub.wait(timeout=duration_s + 90)
    log = player.stdout + player.stderr
    if player.returncode != 0:
        raise SystemExit(f"bag_player failed:\n{log}")
    with open(out, "rb") as f:
        rec = pickle.load(f)
    got = {t: len(rec["arrival"][t]) for t in counts}
    if got != counts:
        short = {t: f"{got[t]} of {n}" for t, n in counts.items() if got[t] != n}
        raise SystemExit(f"the subscriber did not get every message: {short}")
    arrival = np.concatenate([np.asarray(rec["arrival"][t]) for t in counts])
    stamps = np.concatenate([times[t] for t in counts])
    # anchored at the earliest delivery: errors are lateness beyond the fastest message's
    errors = arrival - (stamps - stamps.min()) * 1e-9
    errors -= errors.min()
    reported = PACING.search(log)
    if reported is None:
        raise SystemExit(f"no pacing report in the player's log:\n{log}")
    own = "p50 {} ms, p99 {} ms, max {} ms".format(*reported.groups())
    if "cannot use SCHED_FIFO" in log:
        own += " (SCHED_FIFO refused: normal scheduler)"
    return errors, float(reported.group(2)), own


def run_rate(rate_hz: int, duration_s: float, tmp: Path, env: dict[str, str]) -> dict[str, float]:
    bag = tmp / f"bag{rate_hz}"
    cmd = [_bin("strapdown-sim"), "generate", str(SCENARIO), "--out", str(bag), "--quiet"]
    cmd += ["--duration", str(duration_s), "--set", f"rate_hz={rate_hz}"]
    for o in OVERRIDES:
        cmd += ["--set", o]
    subprocess.run(cmd, check=True, cwd=REPO)
    from strapdown_ros.bag.reader import read_bag

    contents = read_bag(bag, raw=True)
    times = {t: np.asarray(d.log_time_ns, dtype=np.int64) for t, d in contents.topics.items()}
    types = {t: d.msgtype for t, d in contents.topics.items()}
    all_t = np.sort(np.concatenate(list(times.values())))
    times[CLOCK[0]], types[CLOCK[0]] = np.unique(all_t), CLOCK[1]  # one /clock per log time
    total = sum(len(v) for v in times.values())
    print(f"rate {rate_hz} Hz: {duration_s:g} s, {total} messages, "
          f"{total / duration_s:.0f} msgs/s incl. /clock")  # fmt: skip
    floor_err = floor(all_t)
    p99_floor = float(np.percentile(floor_err, 99) * 1e3)
    print(f"  {'floor (sleep loop, same schedule):':<48}{stats(floor_err)}")
    result = {}
    runs = (
        ("player_single_threaded", 0, "single_threaded", "player, SingleThreadedExecutor"),
        ("player", 0, "events", "player"),
        ("player_rt", 10, "events", "player, SCHED_FIFO 10"),
    )
    for label, rt, executor, name in runs:
        errors, p99, own = play(bag, times, types, duration_s, tmp, env, rt, executor)
        print(f"  {name + ' (publish - due):':<48}{own}  p99_vs_floor {p99 / p99_floor:.2f} x")
        print(f"  {name + ' (delivered):':<48}{stats(errors)}")
        result[label] = p99
        result[label.replace("player", "delivered")] = float(np.percentile(errors, 99) * 1e3)
    base = result["player_single_threaded"]
    print(f"  player p99 with SingleThreadedExecutor / EventsExecutor (default): "
          f"{base / result['player']:.2f} x")  # fmt: skip
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--rates", type=int, nargs="+", default=[200, 1000])
    parser.add_argument("--subscribe", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--counts", default="", help=argparse.SUPPRESS)
    parser.add_argument("--timeout", type=float, default=60.0, help=argparse.SUPPRESS)
    parser.add_argument("--rt", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.subscribe:
        spec = [s.split("=") for s in args.counts.split(",")]
        counts = {topic: int(n) for topic, _, n in spec}
        types = {topic: msgtype for topic, msgtype, _ in spec}
        sys.exit(subscribe(args.subscribe, counts, types, args.timeout, args.rt))

    env = dict(os.environ)
    # a private domain in 102..232 (test sessions use 1..101, see test/conftest.py)
    env.setdefault("ROS_DOMAIN_ID", str(102 + os.getpid() % 131))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    tmp = Path(tempfile.mkdtemp(prefix="bench_player_"))
    try:
        load = os.getloadavg()[0]
        print(f"machine: {os.cpu_count()} cores, load average {load:.2f}")
        results = {rate: run_rate(rate, args.duration, tmp, env) for rate in args.rates}
        for rate, res in results.items():
            label = f"{rate // 1000}khz" if rate % 1000 == 0 else f"{rate}hz"
            for name, p99 in res.items():
                print(f"{name}_p99_ms_{label}: {p99:.3f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
