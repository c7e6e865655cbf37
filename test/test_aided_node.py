"""aided_node live (``strapdown-sim run``) records the ``/aided/*`` topics ``generate`` writes.

Both aided test scenarios, shortened, live as separate processes over DDS (flow-controlled at
5x real time): the flight (200 Hz tactical IMU, GNSS 5 Hz, barometer 25 Hz, magnetometer
50 Hz) and the drive with a GNSS latency of 0.25 s (the filter rolls back and re-runs at every
fix, innovations and NIS logged at the arrival) and the tunnel moved into the run (an outage
coasted through). Every ``/aided/*`` topic must have the same messages, byte for byte, with the
same log times; every other topic too (:func:`node_testing.assert_recorded_as_generated`).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from node_testing import assert_recorded_as_generated, generate, run_live

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
DATA = REPO / "test" / "data"

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(
    ("name", "duration_s", "overrides"),
    [
        ("aided_default_noisy", 20, []),
        ("aided_car_noisy", 30,
         ["aiding.gnss.latency_s=0.25", "aiding.gnss.outages=[[8.0, 12.5]]"]),  # fmt: skip
    ],
    ids=["flight", "drive-latency-outage"],
)
def test_run_equals_generate(tmp_path, ros_env, name, duration_s, overrides) -> None:
    scenario = DATA / f"{name}.yaml"
    gen, live = tmp_path / "generate", tmp_path / "run"
    common = ["--duration", str(duration_s)]
    for o in overrides:
        common += ["--set", o]
    generate(scenario, gen, *common, timeout=900)
    run_live(scenario, live, dict(ros_env), *common, "--rate-factor", "5", timeout=900)
    log = (tmp_path / "run.logs" / "aided_node.log").read_text()  # run started it
    assert "Traceback" not in log and "input events: none" in log, log
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    aided = sorted(t for t in b.topics if t.startswith("/aided/"))
    assert len(aided) >= 17, aided
    for topic in aided:
        got, want = a.topics[topic], b.topics[topic]
        assert len(want.payloads) > 0, topic
        assert Counter(map(bytes, got.payloads)) == Counter(map(bytes, want.payloads)), topic
        assert np.array_equal(np.sort(got.log_time_ns), np.sort(want.log_time_ns)), topic
    if overrides:  # innovations and NIS logged at the arrival: 0.25 s after their stamps
        nis = b["/aided/nis/gnss_position"]
        log = b.topics["/aided/nis/gnss_position"].log_time_ns
        assert np.all(log - np.asarray(nis.stamps_ns) == 250_000_000)
        t = (np.asarray(nis.stamps_ns) - int(nis.stamps_ns[0])) // 10**9
        assert not np.any((t >= 8) & (t <= 12)), t  # no fix in the tunnel [8, 12.5) s
    assert_recorded_as_generated(live, gen)
