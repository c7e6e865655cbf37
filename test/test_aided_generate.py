"""The aided filter as a link of the chain: ``generate`` writes its topics with the plan's
counts, and with every sensor noise and bias off (``test/data/aided_car_ideal.yaml``: the
measured IMU with its errors off, GNSS at its antenna, the wheel odometer) its errors, read
back from the bag with rosbags, stay at round-off (measured over 20 s: 1.3e-9 m, 1.4e-10 m/s,
1.7e-13 rad; limits 10 times these). The full-length and noisy cases: test_aided_exact.py and
test_aided_consistency.py."""

from __future__ import annotations

from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset
from strapdown_ros.plan import resolve_plan

SCENARIO = Path(__file__).resolve().parent / "data" / "aided_car_ideal.yaml"
LIMITS = {"position": 1.3e-8, "velocity": 1.4e-9, "attitude": 1.7e-12}


@pytest.mark.slow
def test_generate_writes_the_aided_solution(tmp_path):
    scenario = load_scenario(SCENARIO, duration_s=20.0)
    plan = resolve_plan(scenario)
    assert "aided" in plan.links
    generate_dataset(plan, tmp_path / "bag")
    ts = get_typestore(Stores.ROS2_JAZZY)
    worst = dict.fromkeys(LIMITS, 0.0)
    with Reader(tmp_path / "bag") as reader:
        got = {c.topic: c.msgcount for c in reader.connections}
        assert got == plan.counts()
        errors = [c for c in reader.connections if c.topic.startswith("/aided/error/")]
        assert len(errors) == 3
        for conn, _, raw in reader.messages(connections=errors):
            v = ts.deserialize_cdr(raw, conn.msgtype).vector
            key = conn.topic.rsplit("/", 1)[1]
            worst[key] = max(worst[key], abs(v.x), abs(v.y), abs(v.z))
    for key, limit in LIMITS.items():
        assert worst[key] < limit, (key, worst[key])


def test_run_refuses_a_link_no_node_runs(tmp_path):
    """``run`` of a scenario with a link no node runs live (the suite's timing.yaml: sensor
    timing errors; the aided filter has aided_node, test_aided_node.py) stops before starting
    anything, naming the section, and writes nothing."""
    import subprocess
    import sys

    timing = Path(__file__).resolve().parents[1] / "config" / "suite" / "timing.yaml"
    out = tmp_path / "live"
    proc = subprocess.run(
        [sys.executable, "-m", "strapdown_ros.cli", "run", str(timing), "--out", str(out),
         "--duration", "2"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert "timing" in proc.stderr and "generate" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    assert not out.exists()
