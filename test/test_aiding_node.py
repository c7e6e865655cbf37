"""aiding_node live (strapdown-sim run) records what generate writes: payloads and log times.

Two scenarios: survey_rtk.yaml (RTK GNSS with a 30 ms latency, wheel encoder) and car.yaml with
the tunnel moved into the run (GNSS outage, ABS wheel sensor), each live at 5x real time.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from node_testing import executable

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
AIDING = ("/gnss/fix", "/gnss/vel", "/baro/pressure", "/mag", "/wheel/twist")

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [
        ("survey_rtk.yaml", []),
        ("car.yaml", ["--set", "aiding.gnss.outages=[[3.0, 5.5]]"]),
    ],
    ids=["survey_rtk", "car-tunnel"],
)
def test_run_equals_generate(tmp_path, ros_env, scenario, overrides) -> None:
    path = REPO / "config" / "scenarios" / scenario
    gen, live = tmp_path / "generate", tmp_path / "run"
    common = ["--duration", "8", *overrides]
    proc = subprocess.run(
        [executable("strapdown-sim"), "generate", str(path), "--out", str(gen), "--quiet", *common],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run(
        [executable("strapdown-sim"), "run", str(path), "--out", str(live), *common,
         "--rate-factor", "5", "--domain-id", ros_env["ROS_DOMAIN_ID"]],
        capture_output=True, text=True, timeout=240, env=dict(ros_env),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "zero loss" in proc.stdout, proc.stdout
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    assert set(a.topics) == set(b.topics)
    aiding = [t for t in b.topics if t in AIDING]
    assert {"/gnss/fix", "/gnss/vel", "/wheel/twist"} <= set(aiding)
    for topic in aiding:
        assert [bytes(p) for p in a.topics[topic].payloads] == [
            bytes(p) for p in b.topics[topic].payloads
        ], topic
        assert np.array_equal(a.topics[topic].log_time_ns, b.topics[topic].log_time_ns), topic
    fix = b["/gnss/fix"]
    if scenario == "car.yaml":  # 1 Hz, no fix in [3, 5.5) s
        t = (fix.stamps_ns - fix.stamps_ns[0]) // 10**9
        assert list(t) == [0, 1, 2, 6, 7, 8]
    else:  # 10 Hz, 30 ms latency: log time = stamp + 30 ms
        log = b.topics["/gnss/fix"].log_time_ns
        assert np.all(log - fix.stamps_ns == 30_000_000)
