"""stages/tf.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the scenarios' own numbers (lever arm, initial position, stamps), transforms
read back with rosbags' deserializer, the geodetic-to-ECEF closed form.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset
from strapdown_ros.plan.resolve import resolve_plan
from strapdown_ros.stages.tf import TFStage, plan_datum

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
TS = get_typestore(Stores.ROS2_JAZZY)


def test_static_variation_is_in_tf_static():
    """A variation with constant offsets: ``base_link → variation_imu`` in /tf_static at the
    lever arm [1, 0.5, 0] m FRD (FLU [1, −0.5, 0]), no rotation, stamped t0."""
    scenario = load_scenario(SCENARIOS / "savage_test_example.yaml", duration_s=1.0)
    plan = resolve_plan(scenario)
    assert plan.variation_static
    batch = TFStage(plan).static_batch()
    assert batch is not None and len(batch.payloads) == 1
    msg = TS.deserialize_cdr(bytes(batch.payloads[0]), "tf2_msgs/msg/TFMessage")
    by_pair = {(t.header.frame_id, t.child_frame_id): t for t in msg.transforms}
    tr = by_pair[("base_link", "variation_imu")]
    v, q = tr.transform.translation, tr.transform.rotation
    np.testing.assert_allclose([v.x, v.y, v.z], [1.0, -0.5, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-12)
    assert tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec == scenario.start_time_ns


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    a, e2 = 6378137.0, 6.69437999014e-3
    rn = a / math.sqrt(1.0 - e2 * math.sin(lat) ** 2)
    return np.array([(rn + h) * math.cos(lat) * math.cos(lon),
                     (rn + h) * math.cos(lat) * math.sin(lon),
                     (rn * (1.0 - e2) + h) * math.sin(lat)])  # fmt: skip


def test_datum_without_initial_is_the_trajectory_start():
    """No ``initial`` section: the map datum is the trajectory's position at t0 (here the
    scenario's initial position, which the trajectory starts from)."""
    scenario = load_scenario(SCENARIOS / "default.yaml", duration_s=1.0)
    plan = resolve_plan(scenario)
    ini = scenario.initial
    lat, lon = math.radians(ini.latitude_deg), math.radians(ini.longitude_deg)
    bare = dataclasses.replace(plan, scenario=scenario.model_copy(update={"initial": None}))
    bare.__dict__["trajectory"] = plan.trajectory  # the cached model: kinds with `initial` need it
    d = plan_datum(bare)
    assert abs(d.latitude_rad - lat) < 1e-12 and abs(d.longitude_rad - lon) < 1e-12
    assert abs(d.altitude_m - ini.altitude_m) < 1e-6
    np.testing.assert_allclose(d.r0_e, _ecef(lat, lon, ini.altitude_m), rtol=0, atol=1e-6)


def test_body_tf_at_every_truth_stamp_when_t0_is_off_the_period_grid(tmp_path: Path):
    """A start stamp that is not a multiple of the period: ``map → base_link`` at every
    reference truth stamp all the same (decimation counted from t0)."""
    doc = yaml.safe_load((SCENARIOS / "waldmann_rest.yaml").read_text())
    doc["duration_s"] = 0.1
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    scenario = load_scenario(path)
    assert (2 * scenario.start_time_ns) % scenario.period_ns != 0
    generate_dataset(scenario, tmp_path / "bag")
    odom, body = [], []
    with Reader(tmp_path / "bag") as reader:
        for conn, stamp, raw in reader.messages():
            if conn.topic == "/reference/odom":
                odom.append(stamp)
            elif conn.topic == "/tf":
                for tr in TS.deserialize_cdr(raw, conn.msgtype).transforms:
                    if tr.child_frame_id == "base_link":
                        body.append(tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec)
    assert len(odom) == round(0.1 * scenario.rate_hz) + 1
    assert sorted(body) == sorted(odom)
