"""The report's aiding part (strapdown_ros.report.aiding): measured minus truth per topic."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.config.aiding import AidingSpec
from strapdown_ros.config.base import validate_section
from strapdown_ros.report.aiding import aiding_errors, aiding_table, plot_aiding
from strapdown_ros.stages.aiding import AidingStage
from strapdown_ros.stages.trajectory import reference_batch_chunks

REPO = Path(__file__).resolve().parent.parent
DOC = {
    "gnss": {"preset": "spp", "rate_hz": 5, "lever_arm_m": [1.0, 0.5, -1.0], "latency_s": 0.1,
             "outages": [[8.0, 11.0]], "seed": 1},
    "barometer": {"noise_sigma_pa": 2.0, "lever_arm_m": [0.2, 0.0, 0.0], "seed": 2},
    "magnetometer": {"preset": "mems", "seed": 3},
    "wheel_odometer": {"noise_sigma_mps": 0.05, "lever_arm_m": [-2.0, 0.8, 1.1], "seed": 4},
}  # fmt: skip


def _bag(tmp_path: Path, doc: dict, custom: bool) -> Path:
    scenario = load_scenario(REPO / "config/scenarios/default.yaml", duration_s=30.0)
    spec = validate_section(AidingSpec, doc, "aiding")
    stream = AidingStage(scenario, spec)  # type: ignore[arg-type]
    path = tmp_path / "bag"
    data = {"aiding": spec.model_dump_json(exclude_none=True)} if custom else {}
    with BagWriter(path, custom_data=data) as writer:
        for _, batches in reference_batch_chunks(scenario):
            writer.write_batches(batches + stream.feed_batches(batches))
    return path


def test_errors_against_the_error_free_twin(tmp_path):
    contents = read_bag(_bag(tmp_path, DOC, custom=True))
    start = int(contents["/reference/odom"].stamps_ns[0])
    errors = aiding_errors(contents, start)
    assert set(errors) == {"/gnss/fix", "/gnss/vel", "/baro/pressure", "/mag", "/wheel/twist"}
    # white-only sensors: the error is the white noise (std within 4 SE of ~750/1500 samples)
    baro = errors["/baro/pressure"].error[:, 0]
    assert abs(baro.std() / 2.0 - 1) < 4 / np.sqrt(2 * len(baro))
    wheel = errors["/wheel/twist"].error[:, 0]
    assert abs(wheel.std() / 0.05 - 1) < 4 / np.sqrt(2 * len(wheel))
    assert np.all(errors["/baro/pressure"].sigma == 2.0)
    gnss = errors["/gnss/fix"]
    assert gnss.gaps and abs(gnss.gaps[0][0] - 7.8) < 1e-9 and abs(gnss.gaps[0][1] - 11.0) < 1e-9
    assert np.allclose(gnss.sigma[0], np.sqrt([0.3**2 + 1.5**2, 0.3**2 + 1.5**2, 0.6**2 + 3**2]))
    assert np.all(np.abs(gnss.error) < 6 * gnss.sigma)
    lines = aiding_table(errors)
    assert any("`/gnss/fix` | north" in line for line in lines)
    assert any("Outages" in line for line in lines)
    png = plot_aiding(errors, "test", tmp_path / "aiding.png")
    assert png.stat().st_size > 10_000


def test_error_free_bag_has_zero_errors(tmp_path):
    keep = ("rate_hz", "lever_arm_m", "latency_s", "outages")
    doc = {k: {kk: vv for kk, vv in v.items() if kk in keep} for k, v in DOC.items()}
    contents = read_bag(_bag(tmp_path, doc, custom=True))
    errors = aiding_errors(contents, int(contents["/reference/odom"].stamps_ns[0]))
    for e in errors.values():
        assert np.all(e.error == 0), e.topic


def test_without_custom_data_sensors_at_the_imu(tmp_path):
    """Without the section in custom_data the truth is at the IMU: the GNSS "error" then holds
    the lever arm (same noise, so the difference of the two error series is C l exactly)."""
    with_section = read_bag(_bag(tmp_path / "a", DOC, custom=True))
    without = read_bag(_bag(tmp_path / "b", DOC, custom=False))
    start = int(without["/reference/odom"].stamps_ns[0])
    errors = aiding_errors(without, start)
    assert "sensors taken at the IMU" in errors["/mag"].note
    diff = errors["/gnss/fix"].error - aiding_errors(with_section, start)["/gnss/fix"].error
    assert np.allclose(np.linalg.norm(diff, axis=1), np.linalg.norm([1.0, 0.5, -1.0]), atol=1e-6)
