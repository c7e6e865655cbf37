"""Degenerate values over DDS: a generated bag's Odometry messages, one given a zero-norm
orientation quaternion (finite numbers: a non-finite check lets it through), are published
into ``navigator_node``, ``variation_node`` and ``aiding_node``; their output is recorded
(``ros_helpers/reference_replay.py --zero-quat-odom``). No non-finite number may be published,
the message is named in one warning and counted (``degenerate 1``) in the node's summary, and
the node exits 0. Also over DDS: a lost first IMU interval is said (docs/reliability.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from node_testing import padded  # noqa: E402
from test_faults_nodes import (  # noqa: E402
    NAV,
    VAR,
    _all_finite,
    _decoded,
    _drive,
    _run_case,
    _stamps,
    bag,  # noqa: F401 - fixture
)

pytestmark = pytest.mark.slow
DEGENERATE = "orientation quaternion of norm far from 1"


def _aiding_topics(contents) -> dict[str, str]:
    from strapdown_ros.stages.aiding import AIDING_MSGTYPES

    return {t: m for t, m in AIDING_MSGTYPES.items() if t in contents.topics}


def _said_once(log: str) -> None:
    assert log.count(DEGENERATE) == 1 and "degenerate 1" in log, log


def test_navigator_degenerate_truth(bag, tmp_path, ros_env, procs) -> None:  # noqa: F811
    """Why: NaN on the navigator's error topics, nothing said. Now the truth is dropped as lost:
    the odometry is the same bytes, the errors miss only that stamp, all finite."""
    got, dec, log, rc = _run_case(bag, tmp_path, ros_env, procs, NAV, ["--zero-quat-odom", "300"])
    for topic, fields in dec.items():
        assert _all_finite(fields), f"{topic}: non-finite values published\n{log}"
    ref = [padded(p) for p in bag[1].topics["/navigator/odom"].payloads]
    assert got["/navigator/odom"] == ref, log
    n_err = len(bag[1].topics["/navigator/error/position"].payloads)
    assert len(got["/navigator/error/position"]) >= n_err - 1, log
    _said_once(log)
    assert rc == 0, log


def test_variation_degenerate_reference(bag, tmp_path, ros_env, procs) -> None:  # noqa: F811
    """Why: NaN on all of the variation node's topics for 25 messages. Now the reference message
    is dropped (the solution restarts after it), every output finite, the last one reached."""
    got, dec, log, rc = _run_case(bag, tmp_path, ros_env, procs, VAR, ["--zero-quat-odom", "151"])
    for topic, fields in dec.items():
        assert _all_finite(fields), f"{topic}: non-finite values published\n{log}"
    want = _stamps(bag[1].topics["/variation/odom"].fields)[-1]
    assert _stamps(dec["/variation/odom"])[-1] == want, log
    _said_once(log)
    assert rc == 0, log


def test_aiding_degenerate_truth(bag, tmp_path, ros_env, procs) -> None:  # noqa: F811
    """Why: NaN on every aiding sensor topic. Now the truth message is dropped (its epochs
    skipped), every output finite."""
    outputs = _aiding_topics(bag[1])
    if not outputs:
        pytest.skip("the scenario has no aiding sensors")
    got, log, rc = _drive(tmp_path, ros_env, procs, "aiding_node",
                          ("/reference/imu", "/reference/odom"), outputs, bag[0],
                          ["--zero-quat-odom", "200", "--no-wait-imu"])  # fmt: skip
    dec = _decoded(got, outputs)
    assert dec, log
    for topic, fields in dec.items():
        assert _all_finite(fields), f"{topic}: non-finite values published\n{log}"
    _said_once(log)
    assert rc == 0, log


def test_navigator_lost_first_interval(bag, tmp_path, ros_env, procs) -> None:  # noqa: F811
    """Why: the second IMU message lost (the first interval is 2T): T was learned, nothing was
    said. Now one gap event, the period and the output rate right."""
    _, dec, log, rc = _run_case(bag, tmp_path, ros_env, procs, NAV, ["--drop-imu", "2"])
    assert "IMU period T = 5000000 ns" in log, log
    assert log.count("before the IMU period was known (1 message(s) missing)") == 1, log
    assert "gap 1" in log, log
    stamps = _stamps(dec["/navigator/odom"])
    assert np.all(np.diff(stamps) == 10 * 5_000_000), log
    assert rc == 0, log
