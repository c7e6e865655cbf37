"""A user's own scenario (test/data/user_car_400hz.yaml: a car at 400 Hz, the IMU 0.3 m
forward and yawed 180°, industrial IMU errors, RTK GNSS 10 Hz with latency, a wheel encoder,
spherical gravity) passes ``strapdown-sim check`` and ``report`` as processes; the report
names the IMU's axes as mounted (x aft, y right: from the scenario's 180° yaw), draws the
measured IMU beside the ideal one and says which IMU a navigator consumes."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "test" / "data" / "user_car_400hz.yaml"


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "strapdown_ros.cli", *args],
                          capture_output=True, text=True, timeout=600)  # fmt: skip


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("user") / "bag"
    proc = _cli("generate", str(SCENARIO), "--duration", "4", "--out", str(out), "--quiet",
                "--set", "navigator={imu_topic: /variation/imu_measured, mode: paper}")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return out


def test_check_passes_with_spherical_gravity(bag):
    proc = _cli("check", str(bag))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "gravity model spherical (from the bag's metadata)" in proc.stdout
    assert proc.stdout.count(": ok") == 3 and "DEFECT" not in proc.stdout, proc.stdout


def test_report_passes_and_labels_the_mounted_axes(bag, tmp_path):
    proc = _cli("report", str(bag), "--out", str(tmp_path / "r"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    md = (tmp_path / "r" / "report.md").read_text()
    assert "gravity model spherical (from the bag's metadata)" in md
    assert "DEFECT" not in md and md.count("| ok |") == 3, md
    assert (tmp_path / "r" / "imu.png").stat().st_size > 10_000

    from strapdown_ros.report.data import load_bag
    from strapdown_ros.report.plots import imu_list

    data = load_bag(bag, exactness=False, allan=False)
    assert data.imus["/reference"].axis_labels == ("x (forward)", "y (left)", "z (up)")
    # yawed 180° about z (down in FRD, up in FLU): x points aft, y right, z stays up
    assert data.imus["/variation"].axis_labels == ("x (aft)", "y (right)", "z (up)")
    drawn = [(d.topic, d.measured, d.axis_labels[0]) for d in imu_list(data)]
    assert drawn == [("/reference/imu", False, "x (forward)"), ("/variation/imu", False, "x (aft)"),
                     ("/variation/imu_measured", True, "x (aft)")]  # fmt: skip


def test_report_header_names_the_imu_a_solution_consumes(bag, tmp_path):
    """With ``navigator.imu_topic`` in the bag's metadata the header says ideal or measured;
    without it, that the metadata does not record it."""
    plain = tmp_path / "plain"
    shutil.copytree(bag, plain)
    meta = yaml.safe_load((plain / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["custom_data"].pop("navigator.imu_topic", None)
    (plain / "metadata.yaml").write_text(yaml.safe_dump(meta))
    proc = _cli("report", str(plain), "--no-exactness")
    assert proc.returncode == 0, proc.stderr
    md = (plain / "report" / "report.md").read_text()
    assert "solution `/navigator`: the bag's metadata does not record which IMU" in md
    for topic, kind in (("/variation/imu_measured", "measured"), ("/variation/imu", "ideal")):
        copy = tmp_path / f"copy_{kind}"
        shutil.copytree(bag, copy)
        meta = yaml.safe_load((copy / "metadata.yaml").read_text())
        meta["rosbag2_bagfile_information"]["custom_data"]["navigator.imu_topic"] = topic
        (copy / "metadata.yaml").write_text(yaml.safe_dump(meta))
        proc = _cli("report", str(copy), "--no-exactness")
        assert proc.returncode == 0, proc.stderr
        md = (copy / "report" / "report.md").read_text()
        assert f"solution `/navigator` consumes the {kind} IMU `{topic}`" in md, md[:2000]
