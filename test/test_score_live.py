"""``strapdown-sim score --node``: a suite bag played by bag_player into a node of the tests'
own (ros_helpers/offset_filter.py: the truth moved by a fixed ECEF offset, republished as
nav_msgs/Odometry), recorded by bag_recorder and scored, all real processes over DDS in the
session's ROS domain (test/conftest.py).

* End to end: every truth message comes back as an estimate, and the scored error is the
  offset turned into NED at the (standing) car's latitude and longitude, computed here from the
  geodetic formula, not from the scorer.
* Errors, each with its one-line reason and exit status: the node's command not found (2), an
  input the bag does not have (2), the node exiting early (1), publishing nothing (1), having no
  publisher on the topic (1), publishing another type (1).
* Ctrl-C (SIGINT to strapdown-sim alone, as a terminal sends it to the foreground process
  group, which the children are not in): exit 130, the recording closed and readable, no
  process of the run left.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from node_testing import REPO, executable, generate

pytestmark = [pytest.mark.dds, pytest.mark.slow]

SUITE_CAR = REPO / "config" / "suite" / "car_city.yaml"
FILTER = REPO / "test" / "ros_helpers" / "offset_filter.py"
#: Seconds of the suite drive: the car waits at a light for the first 10 s (it stands still).
DURATION_S = 2.0
OFFSET_ECEF_M = np.array([1.0, 2.0, 3.0])
#: The suite car's start (config/suite/car_city.yaml ``initial``), deg.
LAT_DEG, LON_DEG = 52.52, 13.405


@pytest.fixture(scope="module")
def suite_bag(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("suite") / "car_city"
    generate(SUITE_CAR, out, "--duration", DURATION_S)
    return out


def _filter(*args: str) -> str:
    return f"{sys.executable} {FILTER} " + " ".join(args)


def _score_live(bag: Path, out: Path, node: str, *extra: str, env: dict[str, str],
                timeout: float = 300) -> subprocess.CompletedProcess:  # fmt: skip
    cmd = [executable("strapdown-sim"), "score", str(bag), "--topic", "/offset_filter/odom",
           "--node", node, "--input", "/reference/odom", "--out", str(out),
           "--domain-id", env["ROS_DOMAIN_ID"], "--rate-factor", "4", *extra]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=REPO)


def _pids(text: str) -> list[int]:
    return [int(p) for p in re.findall(r"\(pid (\d+)\)", text)]


def _assert_gone(pids: list[int]) -> None:
    """No process of the run is left (none is a zombie of ours: strapdown-sim reaped them)."""
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def _truth_count(bag: Path) -> int:
    from strapdown_ros.bag.reader import read_bag

    return len(read_bag(bag, ["/reference/odom"], raw=True).topics["/reference/odom"].payloads)


def test_live_score_end_to_end(suite_bag, tmp_path, ros_env) -> None:
    out = tmp_path / "score"
    proc = _score_live(suite_bag, out, _filter("--offset", *map(str, OFFSET_ECEF_M)),
                       "--scenario", str(SUITE_CAR), "--duration", str(DURATION_S),
                       env=ros_env)  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    pids = _pids(proc.stderr)
    assert len(pids) == 3, proc.stderr  # the recorder, the node, the player
    _assert_gone(pids)
    score = json.loads((out / "score.json").read_text())
    assert score["samples"] == _truth_count(suite_bag)
    assert score["outside_truth"] == 0
    # The offset in NED at the standing car (geodetic latitude; the geodetic and the local
    # vertical of the scorer's NED are the same axes): R = [[-sφcλ, -sφsλ, cφ], [-sλ, cλ, 0],
    # [-cφcλ, -cφsλ, -sφ]].
    phi, lam = np.radians(LAT_DEG), np.radians(LON_DEG)
    r = np.array([
        [-np.sin(phi) * np.cos(lam), -np.sin(phi) * np.sin(lam), np.cos(phi)],
        [-np.sin(lam), np.cos(lam), 0.0],
        [-np.cos(phi) * np.cos(lam), -np.cos(phi) * np.sin(lam), -np.sin(phi)],
    ])  # fmt: skip
    want = r @ OFFSET_ECEF_M
    pos = score["position_error_m"]
    got = np.array([pos[a]["mean"] for a in ("north", "east", "down")])
    np.testing.assert_allclose(got, want, atol=1e-6)
    for a in ("north", "east", "down"):
        assert pos[a]["max_abs"] == pytest.approx(abs(pos[a]["mean"]), abs=1e-6)
    # The orientation is copied: the attitude error is only the tilt between the local levels
    # of the moved and the true position (|offset| / R at most, measured 3.5e-7 rad).
    att = score["attitude_error_rad"]
    tilt = np.linalg.norm(OFFSET_ECEF_M) / 6.35e6
    assert max(att[a]["max_abs"] for a in ("up", "east", "north")) < tilt


@pytest.mark.parametrize(
    ("node_args", "extra", "status", "message"),
    [
        (None, (), 2, r"no-such-filter-command: command not found"),
        ("--mode exit-early --after 5", (), 1, r"the node exited with status 3 while the bag"),
        ("--mode silent", (), 1, r"the node published nothing on /offset_filter/odom while"),
        ("--mode no-publisher", ("--startup-timeout", "8"), 1,
         r"the node has no publisher on /offset_filter/odom after 8 s"),
        ("--mode wrong-type", (), 1, r"publishes /offset_filter/odom as std_msgs/msg/String"),
    ],
    ids=["missing", "exit-early", "silent", "no-publisher", "wrong-type"],
)  # fmt: skip
def test_live_score_errors(suite_bag, tmp_path, ros_env, node_args, extra, status, message):
    node = "no-such-filter-command --x" if node_args is None else _filter(node_args)
    proc = _score_live(suite_bag, tmp_path / "score", node, *extra, env=ros_env)
    assert proc.returncode == status, proc.stdout + proc.stderr
    assert re.search(message, proc.stderr), proc.stderr
    assert "Traceback (most recent call last)" not in proc.stderr.split("--- log")[0]
    _assert_gone(_pids(proc.stderr))
    assert not (tmp_path / "score" / "score.json").exists()


def test_live_score_unknown_input_is_refused_before_anything_starts(suite_bag, tmp_path,
                                                                     ros_env) -> None:  # fmt: skip
    proc = _score_live(suite_bag, tmp_path / "score", _filter(), "--input", "/no/such",
                       env=ros_env)  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert "has no topic /no/such" in proc.stderr
    assert not (tmp_path / "score").exists()


def test_ctrl_c_stops_everything(suite_bag, tmp_path, ros_env) -> None:
    out = tmp_path / "score"
    log = tmp_path / "stderr.txt"
    cmd = [executable("strapdown-sim"), "score", str(suite_bag), "--topic", "/offset_filter/odom",
           "--node", _filter(), "--input", "/reference/odom", "--out", str(out),
           "--domain-id", ros_env["ROS_DOMAIN_ID"], "--rate-factor", "0.05"]  # fmt: skip
    with open(log, "w") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, env=ros_env,
                                cwd=REPO)  # fmt: skip
        deadline = time.monotonic() + 240
        while "bag_player started" not in log.read_text():
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        # Playing (40 s of wall time at rate 0.05) once the node has its first message: the
        # estimates arrive; then Ctrl-C.
        node_log = out / "estimate.logs" / "node.log"
        while "FIRST" not in node_log.read_text():
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < deadline, node_log.read_text()
            time.sleep(0.1)
        bag = out / "estimate"
        time.sleep(3.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=120) == 130, log.read_text()
    text = log.read_text()
    assert "interrupted" in text and "closed and readable" in text, text
    pids = _pids(text)
    assert len(pids) == 3, text
    _assert_gone(pids)
    from strapdown_ros.bag.reader import read_bag

    got = read_bag(bag, ["/offset_filter/odom"], raw=True).topics["/offset_filter/odom"]
    assert 0 < len(got.payloads) < _truth_count(suite_bag)
