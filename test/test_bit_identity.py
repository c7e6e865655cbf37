"""Every shipped scenario still generates the same bits as at the base commit, on every topic.

``tools/compare_generate.py --base BASE --duration-cap 30`` generates each scenario twice,
with the package of commit ``BASE`` (from ``git archive``) and with the working tree, and
compares the bags message by message, every topic; it must print "identical" for every shipped
scenario (a scenario the base cannot generate fails: move ``BASE`` forward when a change of the
numbers is intended, and say so in the commit). Needs the
git history (skipped in a shallow clone or a source tree without it). Plus fast unit tests
that the comparison itself detects a difference.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
TOOL = REPO / "tools" / "compare_generate.py"
#: The last commit whose numbers are the reference: every later commit must reproduce them.
#: 85f039d: 3789100's numbers except, on purpose, /tf_static (a transform per aiding sensor) and
#: /wheel/twist (the encoder counts from mid-pulse, its noise bounded by the speed: zero at rest).
BASE = "85f039d"
DURATION_CAP_S = "30"
SCENARIOS = sorted((REPO / "config" / "scenarios").glob("*.yaml"))
#: Shipped scenarios added after BASE (nothing to compare them with; their own tests check them).
NEW_SINCE_BASE = ("transfer_alignment", "transfer_alignment_scan")
_AIDED = ("odom", "fix", "vel", "error/position", "error/velocity", "error/attitude", "nees",
          "bias/gyro", "bias/accel", "bias/gyro_sigma", "bias/accel_sigma")
_PER_SENSOR = ("innovation", "nis")
#: Topics a scenario gained since BASE (a new section): every topic of BASE must still match.
NEW_TOPICS_SINCE_BASE = {
    scenario: ("/reference/imu_measured", *(f"/aided/{t}" for t in _AIDED),
               *(f"/aided/{k}/{m}" for m in measurements for k in _PER_SENSOR))
    for scenario, measurements in (
        ("default", ("gnss_position", "gnss_velocity", "baro", "mag")),
        ("car", ("gnss_position", "gnss_velocity", "wheel")),
    )
}  # fmt: skip
def _compare_generate():
    spec = importlib.util.spec_from_file_location("compare_generate", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _base_unavailable() -> str | None:
    """Why commit ``BASE`` cannot be archived here (None: it can)."""
    if shutil.which("git") is None:
        return "git is not installed"
    inside = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "--is-inside-work-tree"],
        capture_output=True, text=True,
    )  # fmt: skip
    if inside.returncode != 0 or inside.stdout.strip() != "true":
        return f"{REPO} is not a git work tree (no history to take commit {BASE} from)"
    found = subprocess.run(
        ["git", "-C", str(REPO), "cat-file", "-e", f"{BASE}^{{commit}}"], capture_output=True
    )
    if found.returncode != 0:
        shallow = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--is-shallow-repository"],
            capture_output=True, text=True,
        ).stdout.strip()  # fmt: skip
        why = "a shallow clone" if shallow == "true" else "a history without it"
        return f"commit {BASE} (the pre-refactor base) is not available: {why}"
    return None


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_generate_is_bit_identical_to_the_base(scenario: Path) -> None:
    why = _base_unavailable()
    if why:
        pytest.skip(why)
    if scenario.stem in NEW_SINCE_BASE:
        pytest.skip(f"{scenario.stem} is new since {BASE}")
    allow = NEW_TOPICS_SINCE_BASE.get(scenario.stem, ())
    proc = subprocess.run(
        [sys.executable, str(TOOL), "--base", BASE, "--duration-cap", DURATION_CAP_S,
         *(["--allow-new-topics", ",".join(allow)] if allow else []), str(scenario)],
        cwd=REPO, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    out = proc.stdout + proc.stderr
    assert f"{scenario.stem}: new since {BASE}" not in proc.stdout, (
        f"{scenario.stem} did not exist at {BASE}: nothing compared; move BASE forward"
    )
    assert f"{scenario.stem}: identical (" in proc.stdout, out
    assert proc.returncode == 0, out


# --- the comparison itself ---------------------------------------------------------------


def _write_bag(path: Path, values: list[float], topic: str = "/v") -> Path:
    """A rosbag2 (mcap) bag with one Vector3Stamped per value (x = the value)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Stamped = store.types["geometry_msgs/msg/Vector3Stamped"]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(topic, Stamped.__msgtype__, typestore=store)
        for i, x in enumerate(values):
            msg = Stamped(Header(Time(sec=i, nanosec=0), "map"), Vector3(x=x, y=2.0, z=-0.0))
            writer.write(conn, i * 10**9, store.serialize_cdr(msg, Stamped.__msgtype__))
    return path


def test_compare_bags_reports_no_problem_for_equal_bags(tmp_path: Path) -> None:
    tool = _compare_generate()
    a = _write_bag(tmp_path / "a", [0.1, 0.2, 0.3])
    b = _write_bag(tmp_path / "b", [0.1, 0.2, 0.3])
    assert tool.compare_bags(a, b) == []


def test_compare_bags_detects_one_float(tmp_path: Path) -> None:
    tool = _compare_generate()
    a = _write_bag(tmp_path / "a", [0.1, 0.2, 0.3])
    b = _write_bag(tmp_path / "b", [0.1, float.fromhex("0x1.999999999999bp-3"), 0.3])  # 1 ulp
    assert float.fromhex("0x1.999999999999bp-3") != 0.2
    problems = tool.compare_bags(a, b)
    assert problems == ["/v[1].vector.x: 0.2 != 0.20000000000000004"]


def test_compare_bags_detects_counts_and_topics(tmp_path: Path) -> None:
    tool = _compare_generate()
    a = _write_bag(tmp_path / "a", [0.1, 0.2, 0.3])
    assert tool.compare_bags(a, _write_bag(tmp_path / "b", [0.1, 0.2])) == ["/v: 3 != 2 messages"]
    problems = tool.compare_bags(a, _write_bag(tmp_path / "c", [0.1, 0.2, 0.3], topic="/w"))
    assert problems and problems[0].startswith("topics differ"), problems


def test_compare_bags_allows_only_named_new_topics(tmp_path: Path) -> None:
    """A topic only in the new bag is no difference when allowed; a missing one always is."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    tool = _compare_generate()
    store = get_typestore(Stores.ROS2_JAZZY)
    base = _write_bag(tmp_path / "base", [0.1, 0.2])
    new = tmp_path / "new"
    msgtype = "geometry_msgs/msg/Vector3Stamped"
    with Writer(new, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic in ("/v", "/gnss/fix"):
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for i, payload in enumerate(tool.read_messages(base)["/v"][1]):
                writer.write(conn, i * 10**9, payload[1])
    assert tool.compare_bags(base, new) == ["topics differ: ['/gnss/fix']"]
    assert tool.compare_bags(base, new, allow_new=frozenset({"/gnss/fix"})) == []
    assert tool.compare_bags(new, base, allow_new=frozenset({"/gnss/fix"})) != []
