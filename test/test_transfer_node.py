"""transfer_node live (``strapdown-sim run``) records the ``/transfer/*`` topics ``generate``
writes.

The shipped transfer-alignment scenarios (a fixed pylon; a scanning platform whose resolver the
stage simulates, in the node as in ``generate``), shortened to 12 s (the wing rock starts at 10 s),
live as separate processes over DDS (trajectory, variation, IMU error model, transfer filter,
recorder; flow-controlled at 5x real time): every ``/transfer/*`` topic, and every other, must
have the same messages, byte for byte, in the same order
(:func:`node_testing.assert_recorded_as_generated`).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from node_testing import assert_recorded_as_generated, generate, run_live

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
SCENARIOS = [REPO / "config" / "scenarios" / f"{name}.yaml"
             for name in ("transfer_alignment", "transfer_alignment_scan")]  # fmt: skip

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_run_equals_generate(tmp_path, ros_env, scenario: Path) -> None:
    gen, live = tmp_path / "generate", tmp_path / "run"
    common = ["--duration", "12"]
    generate(scenario, gen, *common, timeout=900)
    run_live(scenario, live, dict(ros_env), *common, "--rate-factor", "5", timeout=900)
    log = (tmp_path / "run.logs" / "transfer_node.log").read_text()  # run started it
    assert "Traceback" not in log and "0 measurement(s) rejected" in log, log
    topics = read_bag(gen, raw=True).topics
    transfer = sorted(t for t in topics if t.startswith("/transfer/") and len(topics[t].payloads))
    assert len(transfer) == 11, transfer  # odom, vel, 3 errors, nees, 4 mounting, nis
    # every topic, /transfer/* included: the same payloads in the same order
    assert_recorded_as_generated(live, gen)
