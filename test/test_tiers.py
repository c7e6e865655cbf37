"""The test tiers (test/tiers.py): automatic ``dds`` marking and the guard of the ROS-free tier.

The guard is checked on a small throw-away test file run by a nested pytest (plugin ``tiers``
loaded with ``-p``): a test that starts a child importing rclpy, or imports it in-process out
of sight of the static marking, must fail even though it swallowed the ImportError.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import tiers

TEST_DIR = Path(__file__).resolve().parent

SAMPLE = """
import importlib
import subprocess
import sys

import pytest


@pytest.fixture
def ros_env():
    return {}


def test_plain():
    assert True


def test_child_imports_rclpy():
    # as a test that runs a node or `strapdown-sim run` without the fixture; result ignored
    subprocess.run([sys.executable, "-c", "import rclpy"], capture_output=True)


def test_hidden_in_process_import():
    try:
        importlib.import_module("rcl" + "py")  # invisible to the static marking
    except ImportError:
        pytest.skip("swallowed")


def test_with_fixture(ros_env):
    subprocess.run([sys.executable, "-c", "import rclpy"], capture_output=True)


def _helper():
    from rclpy.node import Node  # noqa: F401


def test_calls_a_helper_that_imports_rclpy():
    _helper()


@pytest.mark.dds
def test_marked_by_hand():
    pass
"""


def _nested(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    (tmp_path / "test_sample.py").write_text(SAMPLE)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    env = {k: v for k, v in os.environ.items() if k != tiers.LOG_ENV}
    # this session's own guard (if active) must not reach the nested one
    stub = str(tiers.STUB_DIR)
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != stub]
    env["PYTHONPATH"] = os.pathsep.join([str(TEST_DIR), *paths])
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "tiers", "-p", "no:cacheprovider", "-rA",
         "-c", str(tmp_path / "pytest.ini"), str(tmp_path / "test_sample.py"), *args],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@pytest.mark.slow  # ~6 s: a nested pytest session
def test_ros_free_tier_fails_tests_that_import_rclpy(tmp_path: Path) -> None:
    proc = _nested(tmp_path, "-m", "not dds")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out
    assert "rclpy is blocked here and in child processes" in out, out
    # deselected: test_with_fixture, test_calls_a_helper_that_imports_rclpy, test_marked_by_hand
    assert "3 deselected, 2 errors" in out, out
    assert re.search(r"PASSED .*::test_plain", out), out
    for name in ("test_child_imports_rclpy", "test_hidden_in_process_import"):
        # the reason on the summary line since pytest 8; 7.4 (noble's python3-pytest) names the
        # test only (the sections below hold the reason in both)
        assert re.search(rf"^ERROR .*::{name}( - rclpy was imported|$)", out, re.M), (name, out)
    # the per-test error sections, without the short summary (which lists both tests)
    sections = out.split("short test summary info")[0]
    child, hidden = sections.split("ERROR at teardown of ")[1:3]
    assert child.startswith("test_child_imports_rclpy"), out
    assert "import rclpy in a child process: " in child and "in the test process" not in child
    assert hidden.startswith("test_hidden_in_process_import"), out
    assert "import rclpy in the test process" in hidden
    assert "import rclpy in a child process" not in hidden
    assert tiers.HINT.split(" (")[0] in out, out


def test_marking_of_this_suite() -> None:
    """Spot checks on real files (static analysis only, nothing is run)."""
    assert tiers.dds_reason(TEST_DIR / "test_dds_smoke.py", "test_session_is_isolated", [])
    bag_io = TEST_DIR / "test_bag_io.py"
    reason = tiers.dds_reason(bag_io, "test_type_hashes_match_rclpy", ["tmp_path"])
    assert reason and "imports rclpy" in reason
    assert tiers.dds_reason(bag_io, "test_write_read_round_trip", ["tmp_path", "storage"]) is None
    reason = tiers.dds_reason(TEST_DIR / "test_pipeline.py", "anything", ["tmp_path", "ros_env"])
    assert reason == "uses the ros_env fixture"
    # through strapdown_ros: importing the nodes' helpers loads rclpy
    chain = tiers._ros_chain("strapdown_ros.nodes.lifecycle")
    assert chain and chain[-1].startswith("rclpy"), chain
    assert tiers._ros_chain("strapdown_ros.generate") is None


def test_stub_refuses_and_records(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(tiers.STUB_DIR), **{tiers.LOG_ENV: str(tmp_path)})
    proc = subprocess.run(
        [sys.executable, "-c", "import rclpy"], env=env, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 1 and "ImportError: rclpy is blocked" in proc.stderr, proc.stderr
    (record,) = tmp_path.iterdir()
    assert record.read_text().endswith("-c"), record.read_text()
