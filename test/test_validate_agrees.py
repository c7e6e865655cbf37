"""``strapdown-sim validate`` and ``generate`` accept and reject exactly the same scenarios.

A table of bad scenario files (every section, type and range errors, cross-field rules,
problems only found while building the trajectory, unreadable files) is given to both commands;
each must exit 2 with the same ``<dotted key>: <problem>`` message, print no traceback and leave
no output behind. The in-process runs cover the whole table; a few cases also run as real
processes (``python -m strapdown_ros.cli``), where a traceback would reach the user.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from strapdown_ros import cli

GOOD = {
    "rate_hz": 100,
    "duration_s": 4,
    "initial": {"latitude_deg": 45.0, "longitude_deg": 7.0, "altitude_m": 300.0,
                "velocity_ned_mps": [50.0, 0.0, 0.0]},
    "trajectory": {"kind": "segments", "segments": [{"duration_s": 10}]},
}  # fmt: skip


def _with(path: str, value: object) -> dict:
    """GOOD with ``value`` at the dotted ``path`` (list indices as integers)."""
    doc = yaml.safe_load(yaml.safe_dump(GOOD))
    node = doc
    parts = [int(p) if p.isdigit() else p for p in path.split(".")]
    for part in parts[:-1]:
        node = node.setdefault(part, {}) if isinstance(part, str) else node[part]
    node[parts[-1]] = value
    return doc


VARIATION = {"lever_arm_m": [1.0, 0.0, 0.0]}
NAVIGATOR = {"imu_topic": "/variation/imu"}

#: case -> (scenario document or raw bytes, the key the message must name)
CASES: dict[str, tuple[object, str]] = {
    "unknown top-level key": ({**GOOD, "rate": 100}, "rate"),
    "rate is a string": (_with("rate_hz", "fast"), "rate_hz"),
    "rate without whole-ns period": (_with("rate_hz", 300), "rate_hz"),
    "oversample not dividing T": (_with("oversample", 3), "oversample"),
    "NaN duration": (_with("duration_s", float("nan")), "duration_s"),
    "negative duration": (_with("duration_s", -1), "duration_s"),
    "latitude out of range": (_with("initial.latitude_deg", 91.0), "initial.latitude_deg"),
    "pitch at 90": (_with("initial.attitude_rph_deg", [0, 90, 0]), "initial.attitude_rph_deg"),
    "short velocity": (_with("initial.velocity_ned_mps", [1, 2]), "initial.velocity_ned_mps"),
    "missing initial": ({k: v for k, v in GOOD.items() if k != "initial"}, "initial"),
    "unknown trajectory kind": (_with("trajectory.kind", "spline"), "trajectory"),
    "unknown segment key": (
        _with("trajectory.segments", [{"duration_s": 10, "yaw_rate_dps": 1}]),
        "trajectory.segments[0].yaw_rate_dps",
    ),
    "NaN in a segment": (
        _with("trajectory.segments", [{"duration_s": float("nan")}]),
        "trajectory.segments[0].duration_s",
    ),
    "speed would become negative": (
        _with("trajectory.segments", [{"duration_s": 10}, {"duration_s": 20, "accel_mps2": -5}]),
        "trajectory.segments[1]",
    ),
    "duration beyond the trajectory": (_with("duration_s", 30), "duration_s"),
    "latitude past the pole": (
        _with("trajectory.segments", [{"duration_s": 1.0e6}]), "trajectory.segments[0]"
    ),
    "trajectory longer than 1e7 s": (
        _with("trajectory.segments", [{"duration_s": 2.0e7}]), "trajectory.segments"
    ),
    "unknown variation key": ({**GOOD, "variation": {"lever_arm": [1, 0, 0]}}, "variation"),
    "variation method 3": ({**GOOD, "variation": {**VARIATION, "method": 3}}, "variation.method"),
    "negative scan rate": (
        {**GOOD, "variation": {**VARIATION, "scan": {"kind": "sweep", "amplitude_deg": 10,
                                                     "rate_dps": -1}}},
        "variation.scan.rate_dps",
    ),  # fmt: skip
    "unknown scan kind": (
        {**GOOD, "variation": {**VARIATION, "scan": {"kind": "spiral"}}},
        "variation.scan",
    ),
    "navigator mode": (
        {**GOOD, "variation": VARIATION, "navigator": {**NAVIGATOR, "mode": "rk4"}},
        "navigator.mode",
    ),
    "navigator on a topic without its section": (
        {**GOOD, "navigator": {"imu_topic": "/variation/imu_measured"}},
        "navigator.imu_topic",
    ),
    "negative ARW": ({**GOOD, "variation": VARIATION,
                      "imu_errors": {"gyro_arw_dpsh": -0.1}}, "imu_errors.gyro_arw_dpsh"),
    "unknown IMU preset": ({**GOOD, "variation": VARIATION,
                            "imu_errors": {"preset": "space"}}, "imu_errors.preset"),
    "bad topic name": (_with("recording.topics", {"reference_imu": "imu"}),
                       "recording.topics.reference_imu"),
    "unknown storage": (_with("recording.storage", "rosbag1"), "recording.storage"),
    "top level is a list": (b"- 1\n- 2\n", ""),
    "empty file": (b"", ""),
    "not YAML": (b"rate_hz: [1, 2\n", ""),
    "not UTF-8 text": (b"rate_hz: 100\nname: \xff\xfe\n", ""),
    "binary file": (bytes(range(256)), ""),
    "nested 1000 levels deep": (b"rate_hz: " + b"[" * 1000 + b"]" * 1000 + b"\n", ""),
    "recursive alias": (b"rate_hz: &r [*r]\n", ""),
}  # fmt: skip


def _write(tmp_path: Path, content: object) -> Path:
    path = tmp_path / "scenario.yaml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(yaml.safe_dump(content))
    return path


def _message(stderr: str, command: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert lines, f"{command} printed nothing on stderr"
    prefix = f"strapdown-sim {command}: "
    assert lines[-1].startswith(prefix), stderr
    return lines[-1][len(prefix):]


def test_the_good_scenario_is_valid(tmp_path, capsys):
    """The base of the table is valid for both (so each case fails for its own reason)."""
    path = _write(tmp_path, GOOD)
    assert cli.main(["validate", str(path)]) == 0
    assert cli.main(["generate", str(path), "--out", str(tmp_path / "bag"), "--quiet"]) == 0


@pytest.mark.parametrize("case", sorted(CASES))
def test_validate_and_generate_reject_the_same_way(tmp_path, capsys, case):
    content, key = CASES[case]
    path = _write(tmp_path, content)
    out = tmp_path / "bag"
    assert cli.main(["validate", str(path)]) == 2
    validate = _message(capsys.readouterr().err, "validate")
    assert cli.main(["generate", str(path), "--out", str(out), "--quiet"]) == 2
    generate = _message(capsys.readouterr().err, "generate")
    assert validate == generate
    assert validate.startswith("invalid scenario: ")
    if key:
        assert validate.removeprefix("invalid scenario: ").startswith(key), validate
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "case", ["speed would become negative", "not UTF-8 text", "negative scan rate"]
)
def test_no_traceback_reaches_the_user(tmp_path, case):
    path = _write(tmp_path, CASES[case][0])
    messages = []
    for args in (["validate", str(path)], ["generate", str(path), "--out", str(tmp_path / "o")]):
        proc = subprocess.run(
            [sys.executable, "-m", "strapdown_ros.cli", *args],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert proc.returncode == 2, proc.stderr
        assert "Traceback" not in proc.stderr, proc.stderr
        messages.append(_message(proc.stderr, args[0]))
    assert messages[0] == messages[1]
