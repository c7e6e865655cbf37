"""transfer_node live (``strapdown-sim run``) records the ``/transfer/*`` topics ``generate``
writes.

The shipped transfer-alignment scenario, shortened to 12 s (the wing rock starts at 10 s),
live as separate processes over DDS (trajectory, variation, IMU error model, transfer filter,
recorder; flow-controlled at 5x real time): every ``/transfer/*`` topic must have the same
messages, byte for byte, with the same log times; every other topic too
(:func:`node_testing.assert_recorded_as_generated`).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from node_testing import assert_recorded_as_generated, generate, run_live

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment.yaml"

pytestmark = pytest.mark.slow


def test_run_equals_generate(tmp_path, ros_env) -> None:
    gen, live = tmp_path / "generate", tmp_path / "run"
    common = ["--duration", "12"]
    generate(SCENARIO, gen, *common, timeout=900)
    run_live(SCENARIO, live, dict(ros_env), *common, "--rate-factor", "5", timeout=900)
    log = (tmp_path / "run.logs" / "transfer_node.log").read_text()  # run started it
    assert "Traceback" not in log and "0 measurement(s) rejected" in log, log
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    transfer = sorted(t for t in b.topics if t.startswith("/transfer/"))
    assert len(transfer) == 11, transfer  # odom, vel, 3 errors, nees, 4 mounting, nis
    for topic in transfer:
        got, want = a.topics[topic], b.topics[topic]
        assert len(want.payloads) > 0, topic
        assert Counter(map(bytes, got.payloads)) == Counter(map(bytes, want.payloads)), topic
        assert np.array_equal(np.sort(got.log_time_ns), np.sort(want.log_time_ns)), topic
    assert_recorded_as_generated(live, gen)
