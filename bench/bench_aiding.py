"""Benchmark: the aiding stage's cost per simulated hour, beside the reference's, same run.

Scenario: the default flight (200 Hz). Timed:

* ``reference``: the reference stream's pieces and their serialized batches
  (:func:`strapdown_ros.stages.trajectory.reference_batch_chunks`, what ``generate`` computes);
* ``aiding``: :class:`strapdown_ros.stages.aiding.AidingStage` fed the reference's Odometry
  payloads piece by piece (decode, truth at the epochs, models, serialize): GNSS ``spp`` at
  10 Hz with latency and an outage, barometer ``mems`` 25 Hz, magnetometer ``mems`` 50 Hz,
  wheel odometer ``abs_sensor`` 50 Hz;
* ``aiding, per message``: the same fed one Odometry message per call (the live node's worst
  case), on the first ``--messages`` messages.

Usage: python bench/bench_aiding.py. Last line: ``aiding_s_per_sim_hour: X s``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from strapdown_ros.config import load_scenario
from strapdown_ros.config.aiding import AidingSpec
from strapdown_ros.config.base import validate_section
from strapdown_ros.stages.aiding import AidingStage
from strapdown_ros.stages.trajectory import reference_batch_chunks

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "scenarios" / "default.yaml"
SPEC = {
    "gnss": {"preset": "spp", "rate_hz": 10, "lever_arm_m": [0.5, 0.0, -1.2], "latency_s": 0.05,
             "outages": [[100, 130]], "seed": 1},
    "barometer": {"preset": "mems", "seed": 2},
    "magnetometer": {"preset": "mems", "seed": 3},
    "wheel_odometer": {"preset": "abs_sensor", "lever_arm_m": [-1.0, 0.8, 1.5], "seed": 4},
}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--messages", type=int, default=6000)
    args = parser.parse_args()
    scenario = load_scenario(DEFAULT)
    spec = validate_section(AidingSpec, SPEC, "aiding")
    topic = scenario.recording.topics["reference_odom"]
    best_ref = best_aid = float("inf")
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        pieces = [b for _, b in reference_batch_chunks(scenario)]
        best_ref = min(best_ref, time.perf_counter() - t0)
        t0 = time.perf_counter()
        stream = AidingStage(scenario, spec)  # type: ignore[arg-type]
        for batches in pieces:
            stream.feed_batches(batches)
        best_aid = min(best_aid, time.perf_counter() - t0)
    payloads = [p for batches in pieces for b in batches if b.topic == topic for p in b.payloads]
    sim_s = (len(payloads) - 1) * scenario.period_ns * 1e-9
    messages = sum(stream.published.values())
    head = payloads[: args.messages]
    t0 = time.perf_counter()
    single = AidingStage(scenario, spec)  # type: ignore[arg-type]
    for p in head:
        single.on_payloads([p])
    per_msg = (time.perf_counter() - t0) / len(head)
    hour = 3600.0 / sim_s
    print(f"scenario: {DEFAULT.name}, {sim_s:.0f} s at {scenario.rate_hz:g} Hz, "
          f"{len(payloads)} truth messages -> {messages} aiding messages")  # fmt: skip
    print(f"reference (pieces + batches): {best_ref:.3f} s = {best_ref * hour:.2f} s per "
          "simulated hour")  # fmt: skip
    print(f"aiding (piece by piece): {best_aid:.3f} s = {best_aid * hour:.2f} s per simulated "
          f"hour ({best_aid / best_ref:.1%} of the reference)")  # fmt: skip
    print(f"aiding, one truth message per call: {per_msg * 1e6:.0f} µs per message = "
          f"{per_msg * 3600 * scenario.rate_hz:.1f} s per simulated hour at "
          f"{scenario.rate_hz:g} Hz")  # fmt: skip
    print(f"aiding_s_per_sim_hour: {best_aid * hour:.2f} s")


if __name__ == "__main__":
    main()
