"""Several IMU error models in one scenario (``imu_errors`` as a list): parsing, the rules across
models (keys named), ``generate`` writing every model's stream (each the stream a one-model
scenario writes: the models draw from their own seeds) and the aided filter of default.yaml on
its reference-IMU model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.config.imu_errors import ImuErrorsSpec
from strapdown_ros.config.scenario import parse_scenario
from strapdown_ros.generate import generate_dataset
from strapdown_ros.plan import resolve_plan

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"

VARIATION = {"preset": "tactical", "seed": 1, "input_topic": "/variation/imu",
             "output_topic": "/variation/imu_measured"}  # fmt: skip
REFERENCE = {"preset": "industrial", "seed": 7, "input_topic": "/reference/imu",
             "output_topic": "/reference/imu_measured"}  # fmt: skip


def _doc(imu_errors, duration_s: float = 1.0) -> dict:
    """A short flight with a variation (lever arm) and the given ``imu_errors``."""
    return {
        "rate_hz": 100,
        "duration_s": duration_s,
        "initial": {"latitude_deg": 45.0, "longitude_deg": 7.0, "altitude_m": 100.0,
                    "velocity_ned_mps": [20.0, 0.0, 0.0]},  # fmt: skip
        "trajectory": {"kind": "segments", "segments": [
            {"duration_s": 2.0, "heading_rate_dps": 3.0, "accel_mps2": 0.5, "transition_s": 1}]},
        "variation": {"lever_arm_m": [1.0, 0.5, -0.2]},
        "imu_errors": imu_errors,
    }  # fmt: skip


def test_one_mapping_and_a_list_parse_to_the_same_models():
    one = parse_scenario(_doc(VARIATION))
    listed = parse_scenario(_doc([VARIATION]))
    assert one.imu_errors == listed.imu_errors == (ImuErrorsSpec(**VARIATION),)
    two = parse_scenario(_doc([VARIATION, REFERENCE]))
    assert two.imu_errors == (ImuErrorsSpec(**VARIATION), ImuErrorsSpec(**REFERENCE))
    assert two.measured_imu_topics() == (
        ("/variation/imu", "/variation/imu_measured"),
        ("/reference/imu", "/reference/imu_measured"),
    )
    assert two.imu_errors_of("/reference/imu_measured").seed == 7
    assert two.imu_errors_of("/variation/imu") is None
    assert parse_scenario(_doc(None)).measured_imu_topics() == ()
    # the navigator may read either model's output (truth: that of the model's input)
    nav = {"imu_topic": "/reference/imu_measured"}
    spec = parse_scenario({**_doc([VARIATION, REFERENCE]), "navigator": nav}).navigator
    assert spec is not None
    from strapdown_ros.config import navigator_spec

    resolved = navigator_spec(parse_scenario({**_doc([VARIATION, REFERENCE]), "navigator": nav}))
    assert resolved.truth_topic == "/reference/odom"


@pytest.mark.parametrize(
    ("models", "key", "words"),
    [
        ([VARIATION, {**REFERENCE, "output_topic": "/variation/imu_measured"}],
         "imu_errors[1].output_topic", "also the output of imu_errors[0]"),
        ([VARIATION, {**REFERENCE, "input_topic": "/variation/imu", "output_topic": "/m"}],
         "imu_errors[1].input_topic", "also the input of imu_errors[0]"),
        ([VARIATION, {**REFERENCE, "input_topic": "/gnss/fix"}],
         "imu_errors[1].input_topic", "not an ideal IMU topic"),
        ([VARIATION, {**REFERENCE, "output_topic": "/reference/odom"}],
         "imu_errors[1].output_topic", "another stream's topic"),
        ([VARIATION, {**REFERENCE, "seed": -1}], "imu_errors[1].seed", "integer >= 0"),
        ([{**REFERENCE, "gyro_arw": 1.0}, VARIATION], "imu_errors[0].gyro_arw", ""),
        ({**VARIATION, "input_topic": "/gnss/fix"}, "imu_errors.input_topic", "ideal IMU"),
        ({**VARIATION, "seed": -1}, "imu_errors.seed", "integer >= 0"),
    ],
)  # fmt: skip
def test_rules_apply_per_model_and_across_models_naming_the_key(models, key, words):
    with pytest.raises(ScenarioError) as info:
        parse_scenario(_doc(models))
    assert info.value.key == key, str(info.value)
    assert words in info.value.problem, str(info.value)


def _messages(bag: Path) -> dict[str, list[bytes]]:
    with Reader(bag) as reader:
        out: dict[str, list[bytes]] = {}
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(bytes(raw))
    return out


@pytest.mark.slow
def test_generate_writes_every_model_each_as_a_one_model_run(tmp_path):
    """Two models: both measured streams are written; each is bit for bit the stream of a
    scenario with that model alone (a second model's draws do not touch the first's), and the
    other topics are those of the one-model run."""
    bags = {}
    for name, models in (("both", [VARIATION, REFERENCE]), ("variation", VARIATION),
                         ("reference", [REFERENCE])):  # fmt: skip
        plan = resolve_plan(parse_scenario(_doc(models)))
        generate_dataset(plan, tmp_path / name)
        bags[name] = _messages(tmp_path / name)
        assert {t: len(m) for t, m in bags[name].items()} == plan.counts()
    both, var, ref = bags["both"], bags["variation"], bags["reference"]
    assert len(both["/variation/imu_measured"]) == len(both["/variation/imu"]) > 90
    assert len(both["/reference/imu_measured"]) == len(both["/reference/imu"]) == 100
    assert both["/variation/imu_measured"] == var["/variation/imu_measured"]
    assert both["/reference/imu_measured"] == ref["/reference/imu_measured"]
    assert "/reference/imu_measured" not in var and "/variation/imu_measured" not in ref
    assert both["/variation/imu_measured"] != both["/variation/imu"]  # errors applied
    for topic, messages in var.items():  # every topic of the one-model run unchanged
        assert both[topic] == messages, topic


@pytest.mark.slow
def test_default_runs_the_aided_filter_on_its_reference_model(tmp_path):
    """default.yaml, 20 s: the aided filter integrates /reference/imu_measured (the second
    model) and its NEES stays in a sane range (position, velocity, attitude; 3 degrees of
    freedom each: mean 3 when consistent)."""
    scenario = load_scenario(DEFAULT, duration_s=20.0)
    assert [s.input_topic for s in scenario.imu_errors] == ["/variation/imu", "/reference/imu"]
    plan = resolve_plan(scenario)
    assert "aided" in plan.links and "/reference/imu_measured" in plan.topics
    generate_dataset(plan, tmp_path / "bag")
    ts = get_typestore(Stores.ROS2_JAZZY)
    nees = []
    with Reader(tmp_path / "bag") as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == plan.counts()
        conns = [c for c in reader.connections if c.topic == "/aided/nees"]
        for conn, _, raw in reader.messages(connections=conns):
            v = ts.deserialize_cdr(raw, conn.msgtype).vector
            nees.append((v.x, v.y, v.z))
    values = np.array(nees)
    assert values.shape == (201, 3) and np.all(np.isfinite(values))
    mean = values.mean(axis=0)
    assert np.all(mean > 0.1) and np.all(mean < 30.0), mean


def test_default_yaml_keeps_its_variation_model_first():
    """The variation model of default.yaml is the first of its list (the navigator's input,
    the stream it always had); the reference model is added after it."""
    doc = yaml.safe_load(DEFAULT.read_text())
    assert isinstance(doc["imu_errors"], list) and doc["imu_errors"][0] == VARIATION
    assert doc["imu_errors"][1]["input_topic"] == "/reference/imu"
    assert doc["imu_errors"][1]["seed"] != doc["imu_errors"][0]["seed"]
