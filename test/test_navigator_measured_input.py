"""The navigator's input may be the IMU error model's output whatever its name: a navigator on
a measured reference IMU (free inertial on the measured data) takes the reference truth; the
default name of the measured stream is refused, with the key, when the model writes elsewhere
(it made ``generate`` end in a KeyError traceback)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.config.scenario import navigator_spec

CAR = Path(__file__).resolve().parents[1] / "config" / "suite" / "car_city.yaml"
#: One IMU error model, of the reference IMU (the suite file lists two: the variation IMU's and
#: the reference IMU's, the aided filter's input).
ON_REFERENCE = ["imu_errors=[{preset: industrial, seed: 21, input_topic: /reference/imu, "
                "output_topic: /reference/imu_measured}]"]  # fmt: skip


def test_navigator_on_the_measured_reference_imu_takes_the_reference_truth(tmp_path) -> None:
    doc = yaml.safe_load(CAR.read_text())
    del doc["navigator"]["truth_topic"]  # its default: the truth of the IMU it integrates
    (tmp_path / "car.yaml").write_text(yaml.safe_dump(doc))
    s = load_scenario(tmp_path / "car.yaml", [*ON_REFERENCE,
                      "navigator.imu_topic=/reference/imu_measured"], duration_s=5)  # fmt: skip
    spec = navigator_spec(s)
    assert (spec.imu_topic, spec.truth_topic) == ("/reference/imu_measured", "/reference/odom")


def test_the_default_measured_name_is_refused_when_the_model_writes_elsewhere() -> None:
    with pytest.raises(ScenarioError, match=r"navigator\.imu_topic.*/variation/imu_measured.*"
                       r"not an IMU stream; one of: .*/reference/imu_measured") as err:  # fmt: skip
        load_scenario(CAR, ON_REFERENCE, duration_s=5)
    assert "/variation/imu_measured," not in str(err.value).split("one of:")[1]


def test_the_shipped_measured_variation_input_is_unchanged() -> None:
    spec = navigator_spec(load_scenario(CAR, duration_s=5))
    assert (spec.imu_topic, spec.truth_topic) == ("/variation/imu_measured", "/variation/odom")
