"""stages/tf.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the scenarios' own numbers (lever arm, initial position, stamps), transforms
read back with rosbags' deserializer, the geodetic-to-ECEF closed form.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, batch
from strapdown_ros.config import load_scenario
from strapdown_ros.core.variation import OffsetArrays
from strapdown_ros.generate import generate_dataset
from strapdown_ros.messages import OdometryFields
from strapdown_ros.plan.resolve import resolve_plan
from strapdown_ros.stages.tf import (
    TFStage,
    _every,
    derived_topic_plans,
    derived_topics,
    plan_datum,
)

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
TS = get_typestore(Stores.ROS2_JAZZY)


@pytest.mark.parametrize("duration_s", [1.0, 0.005])
def test_static_variation_is_in_tf_static(duration_s: float):
    """A variation with constant offsets: ``base_link → variation_imu`` in /tf_static at the
    lever arm [1, 0.5, 0] m FRD (FLU [1, −0.5, 0]), no rotation, stamped t0; also for a run of
    one cycle (0.005 s at 200 Hz), where the offsets are asked for just one cycle."""
    scenario = load_scenario(SCENARIOS / "savage_test_example.yaml", duration_s=duration_s)
    plan = resolve_plan(scenario)
    assert plan.cycles == round(duration_s * 200)
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


def test_datum_key_is_the_map_origin_over_the_initial_position():
    """``tf.datum`` given: the map datum is that point (not ``initial``), in radians and metres,
    its ECEF position the closed form's."""
    datum = {"latitude_deg": 46.5, "longitude_deg": 8.25, "altitude_m": 1200.0}
    scenario = load_scenario(SCENARIOS / "default.yaml", [f"tf.datum={datum}"], duration_s=1.0)
    assert scenario.initial.latitude_deg != datum["latitude_deg"]
    d = plan_datum(resolve_plan(scenario))
    lat, lon = math.radians(46.5), math.radians(8.25)
    assert abs(d.latitude_rad - lat) < 1e-15 and abs(d.longitude_rad - lon) < 1e-15
    assert d.altitude_m == 1200.0
    np.testing.assert_allclose(d.r0_e, _ecef(lat, lon, 1200.0), rtol=0, atol=1e-6)


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


# -- derived_topic_plans, derived_topics, TFStage settings, observe_reference ---------------

DECIMATED = ["tf.body_rate_hz=50", "tf.navigator_rate_hz=10", "recording.increments=true"]
T0 = 1767225600 * 10**9  # default.yaml's start_time_s


def _default(overrides: list[str]):
    return load_scenario(SCENARIOS / "default.yaml", overrides, duration_s=1.0)


def test_planned_tf_counts_with_body_and_navigator_rates():
    """default.yaml, 1 s at 200 Hz (T = 5 ms), tf body 50 Hz and navigator 10 Hz, increments:
    hand counts. /tf: truth cycles 0, 4, …, 200 (51) + variation truth cycles 0, 4, …, 196 of
    its 199 (50) + every 2nd of the navigator's 20 outputs at 20 Hz (N = 10: 10) = 111;
    /tf_static one message at t0; each twin the count and first/last stamps of its source,
    link ``tf``, key ``<source key>_<suffix>``, the docs/interface.md message types, in the
    order tf_static, tf, then by source topic."""
    plan = resolve_plan(_default(DECIMATED))
    up = {p.key: p for p in plan.topics.values() if p.link != "tf"}
    assert (up["reference_odom"].count, up["variation_odom"].count) == (201, 199)
    assert up["navigator_odom"].count == 20
    tf = [p for p in plan.topics.values() if p.link == "tf"]
    static, dyn = tf[0], tf[1]
    assert (static.topic, static.msgtype, static.count, static.key) == (
        "/tf_static", "tf2_msgs/msg/TFMessage", 1, "tf_static")  # fmt: skip
    assert static.first_ns == static.last_ns == T0
    assert (dyn.topic, dyn.msgtype, dyn.count, dyn.key, dyn.first_ns) == (
        "/tf", "tf2_msgs/msg/TFMessage", 111, "tf", T0)  # fmt: skip
    types = {"map": "nav_msgs/msg/Odometry", "dv": "geometry_msgs/msg/Vector3Stamped",
             "dq": "geometry_msgs/msg/QuaternionStamped"}  # fmt: skip
    want = []
    for src in ("reference_odom", "reference_imu", "variation_odom", "variation_imu",
                "variation_reference_odom", "variation_reference_imu",
                "variation_imu_measured", "navigator_odom"):  # fmt: skip
        s = up[src]
        for suffix in ("map",) if src.endswith("odom") else ("dv", "dq"):
            name = s.topic + ("_map" if suffix == "map" else f"_{suffix}")
            want.append((name, types[suffix], s.count, "tf", f"{src}_{suffix}",
                         s.first_ns, s.last_ns))  # fmt: skip
    got = [(p.topic, p.msgtype, p.count, p.link, p.key, p.first_ns, p.last_ns) for p in tf[2:]]
    assert got == want


def test_derived_topics_without_map_odometry():
    """``tf.map_odometry: false``: no ``*_map`` topic, /tf_static and /tf still there (the
    section as written, docs/interface.md)."""
    scenario = _default(["tf.map_odometry=false"])
    produced = {t: p.msgtype for t, p in resolve_plan(scenario).topics.items()}
    out = derived_topics(scenario, produced)
    assert list(out) == ["/tf_static", "/tf"]
    assert not any(t.endswith("_map") for t in resolve_plan(scenario).topics)


def test_stage_settings_from_the_tf_rates():
    """TFStage's periods: body 1e9 / 50 Hz = 20 ms, navigator 1e9 / 10 Hz = 100 ms; without
    the rates T = 5 ms and N T = 50 ms; without a navigator none. The aiding sensors' frames in
    /tf_static at their lever arms FRD → FLU: gnss [1, 0, −1.2] → [1, 0, 1.2], barometer
    [2, 0.5, 0] → [2, −0.5, 0]; the magnetometer (no lever arm, the IMU's frame) has none."""
    s = TFStage(resolve_plan(_default(DECIMATED))).settings
    assert (s.t0_ns, s.period_ns, s.body_period_ns, s.navigator_period_ns) == (
        T0, 5_000_000, 20_000_000, 100_000_000)  # fmt: skip
    assert (s.tf, s.map_odometry, s.increments) == (True, True, True)
    stage = TFStage(resolve_plan(_default([])))
    s = stage.settings
    assert (s.body_period_ns, s.navigator_period_ns, s.increments) == (5_000_000, 50_000_000, False)
    levers = {f: list(v) for f, v in stage.sensor_frames}
    assert len(levers) == 2 and all(f != stage.frames["reference_imu"] for f in levers)
    assert sorted(levers.values()) == [[1.0, 0.0, 1.2], [2.0, -0.5, 0.0]]
    plain = resolve_plan(_default([])).topics["/tf"]
    assert plain.count == 201 + 199 + 20  # every truth, variation and navigator output
    bare = TFStage(resolve_plan(_default(["navigator=null"])))
    assert bare.settings.navigator_period_ns is None


def _odometry(stamps: list[int], frame: str = "earth", pos=None, q=None,
              child: str = "reference_imu") -> OdometryFields:  # fmt: skip
    n = len(stamps)
    pos = np.arange(3 * n, dtype=np.float64).reshape(n, 3) if pos is None else np.asarray(pos)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)) if q is None else np.asarray(q)
    return OdometryFields(np.asarray(stamps, dtype=np.int64), frame, child, pos, q,
                          np.zeros((n, 36)), np.zeros((n, 3)), np.zeros((n, 3)),
                          np.zeros((n, 36)))  # fmt: skip


def test_observe_reference_keeps_what_the_variation_pairs_with():
    """Reference poses kept for ``base_link → variation_imu`` (default.yaml: moving
    variation): two overlapping chunks, stamps [0, 5, 10] then [10, 15] ms, keep each stamp
    once, sorted, the first chunk's pose at the repeat (its position row 2 = [6, 7, 8]); none
    kept from a frame other than ``earth``, with ``variation_tf`` False, or with TF off."""
    plan = resolve_plan(_default([]))
    ms = 1_000_000
    stage = TFStage(plan)
    stage.observe_reference(_odometry([T0, T0 + 5 * ms, T0 + 10 * ms]))
    stage.observe_reference(_odometry([T0 + 10 * ms, T0 + 15 * ms]))
    assert stage._ref_t.tolist() == [T0 + k * ms for k in (0, 5, 10, 15)]
    assert stage._ref_p[2].tolist() == [6.0, 7.0, 8.0]
    assert stage._ref_p[3].tolist() == [3.0, 4.0, 5.0]
    other = TFStage(plan)
    other.observe_reference(_odometry([T0], frame="map"))
    off = TFStage(plan, variation_tf=False)
    off.observe_reference(_odometry([T0]))
    no_tf = TFStage(resolve_plan(_default(["tf.enabled=false"])))
    no_tf.observe_reference(_odometry([T0]))
    assert other._ref_t.size == off._ref_t.size == no_tf._ref_t.size == 0


# -- _every, plan_datum's error, _odometry, _variation_tf, feed_batches, offsets, stable sort --

MS = 1_000_000


def test_every_keeps_one_in_ratio_from_the_first():
    """1 in r of n consecutive messages, the first kept: len(range(0, n, r)) (0 for none, 1
    for one); the planned /tf of a truth topic of 0 or 1 messages (body 50 Hz: 1 in 4)."""
    for n in range(10):
        for r in range(1, 5):
            assert _every(n, r) == len(range(0, n, r)), (n, r)
            assert isinstance(_every(n, r), int)
    plan = resolve_plan(_default(DECIMATED))
    up = {t: p for t, p in plan.topics.items() if p.link != "tf"}
    for ref in (0, 1):
        few = {
            t: dataclasses.replace(p, count=ref if p.key == "reference_odom" else 0)
            if p.key in ("reference_odom", "variation_odom", "navigator_odom") else p
            for t, p in up.items()
        }  # fmt: skip
        tf = next(p for p in derived_topic_plans(plan, few) if p.key == "tf")
        assert tf.count == ref


def test_datum_without_any_position_is_an_error():
    """No ``tf.datum``, no ``initial`` and no trajectory: the exact error message."""
    scenario = load_scenario(SCENARIOS / "default.yaml", duration_s=1.0)
    plan = resolve_plan(scenario)
    bare = dataclasses.replace(plan, scenario=scenario.model_copy(update={"initial": None}))
    bare.__dict__["trajectory"] = None
    with pytest.raises(ValueError) as err:
        plan_datum(bare)
    assert str(err.value) == "the scenario has no initial position for the map datum"


def _enu(lat: float, lon: float) -> np.ndarray:
    """Rows: east, north, up in ECEF (C_E^ENU)."""
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def _transforms(b) -> list:
    msgs = [TS.deserialize_cdr(bytes(p), "tf2_msgs/msg/TFMessage") for p in b.payloads]
    return [tr for m in msgs for tr in m.transforms]


def _stamp(tr) -> int:
    return tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec


def _pose(tr) -> tuple[np.ndarray, Rotation]:
    v, q = tr.transform.translation, tr.transform.rotation
    return np.array([v.x, v.y, v.z]), Rotation.from_quat([q.x, q.y, q.z, q.w])


def test_navigator_tf_at_its_rate_and_nothing_from_other_frames():
    """default.yaml, navigator TF 10 Hz: navigator Odometry every 50 ms gives ``map →
    <child>`` at 0 and 100 ms, at the ENU offsets [k, 2k, −k] m from the initial position
    (closed-form ECEF and ENU axes), rotated C_E^ENU R (scipy); Odometry in another frame or
    none at all derives nothing."""
    scenario = _default(DECIMATED)
    stage = TFStage(resolve_plan(scenario))
    ini = scenario.initial
    lat, lon = math.radians(ini.latitude_deg), math.radians(ini.longitude_deg)
    r0, c = _ecef(lat, lon, ini.altitude_m), _enu(lat, lon)
    enu = np.array([[k, 2.0 * k, -k] for k in range(4)])
    rot = Rotation.from_euler("zyx", [[0.1 * k, 0.2, -0.3 * k] for k in range(4)])
    nav = _odometry([T0 + 50 * k * MS for k in range(4)], pos=r0 + enu @ c, q=rot.as_quat(),
                    child="navigator_imu")  # fmt: skip
    out = stage._odometry("navigator_odom", nav)
    assert [b.topic for b in out] == ["/navigator/odom_map", "/tf"]
    trs = _transforms(out[1])
    assert [_stamp(t) for t in trs] == [T0, T0 + 100 * MS]
    assert {(t.header.frame_id, t.child_frame_id) for t in trs} == {("map", "navigator_imu")}
    for t, k in zip(trs, (0, 2), strict=True):
        p, r = _pose(t)
        np.testing.assert_allclose(p, enu[k], rtol=0, atol=1e-5)
        want = Rotation.from_matrix(c) * rot[k]
        assert (r.inv() * want).magnitude() < 1e-9
    assert stage._odometry("navigator_odom", _odometry([T0], frame="map")) == []
    assert stage._odometry("reference_odom", _odometry([T0], frame="map")) == []
    assert stage._odometry("reference_odom", _odometry([])) == []


def test_variation_tf_pairs_with_the_reference_of_the_same_stamp():
    """default.yaml (moving variation, body TF at every cycle): reference poses at 0..25 ms,
    variation at 5, 10, 15 and 35 ms (no reference there), fed after an empty batch.
    ``base_link → variation_imu`` at 5, 10, 15 ms is R_refᵀ (p_var − p_ref), R_refᵀ R_var
    (scipy); the reference poses after 15 ms are kept for the next chunk, which pairs the last one
    (25 ms); none without a reference pose."""
    stage = TFStage(resolve_plan(_default([])))
    rng = np.random.default_rng(7)
    t_ref = [T0 + 5 * k * MS for k in range(6)]
    p_ref = rng.normal(0.0, 1e3, (6, 3)) + [4e6, 1e6, 4.8e6]
    r_ref = Rotation.random(6, random_state=1)
    t_var = [T0 + 5 * k * MS for k in (1, 2, 3, 7)]
    p_var = p_ref[[1, 2, 3, 0]] + rng.normal(0.0, 2.0, (4, 3))
    r_var = Rotation.random(4, random_state=2)
    empty = Batch("/reference/imu", cdr.IMU, np.zeros(0, dtype=np.int64), [])
    ref = batch("/reference/odom", _odometry(t_ref, pos=p_ref, q=r_ref.as_quat()))
    var = batch("/variation/odom", _odometry(t_var, pos=p_var, q=r_var.as_quat(),
                                             child="variation_imu"))  # fmt: skip
    out = stage.feed_batches([empty, ref, var])
    assert [b.topic for b in out] == ["/reference/odom_map", "/tf", "/variation/odom_map", "/tf"]
    trs = _transforms(out[3])
    assert [_stamp(t) for t in trs] == t_var[:3]
    assert {(t.header.frame_id, t.child_frame_id) for t in trs} == {("base_link", "variation_imu")}
    for t, j, k in zip(trs, range(3), (1, 2, 3), strict=True):
        p, r = _pose(t)
        np.testing.assert_allclose(p, r_ref[k].inv().apply(p_var[j] - p_ref[k]), rtol=0, atol=1e-9)
        assert (r.inv() * r_ref[k].inv() * r_var[j]).magnitude() < 1e-9
    assert stage._ref_t.tolist() == t_ref[4:]
    np.testing.assert_array_equal(stage._ref_p, p_ref[4:])
    last = _odometry([t_ref[5]], pos=p_ref[:1], q=r_var[:1].as_quat())
    more = stage._odometry("variation_odom", last)
    (t,) = _transforms(more[-1])
    p, r = _pose(t)
    np.testing.assert_allclose(p, r_ref[5].inv().apply(p_ref[0] - p_ref[5]), rtol=0, atol=1e-9)
    assert (r.inv() * r_ref[5].inv() * r_var[0]).magnitude() < 1e-9
    fresh = TFStage(resolve_plan(_default([])))  # no reference pose yet: no variation TF
    assert [b.topic for b in fresh._odometry("variation_odom", last)] == ["/variation/odom_map"]


def test_given_offsets_are_the_static_variation():
    """savage_test_example.yaml (static variation) with offsets passed in: /tf_static's
    ``base_link → variation_imu`` is their lever arm [3, 2, 1] m FRD (FLU [3, −2, −1]), not
    the scenario's [1, 0.5, 0]."""
    scenario = load_scenario(SCENARIOS / "savage_test_example.yaml", duration_s=1.0)
    plan = resolve_plan(scenario)
    n = plan.cycles + 1
    given = OffsetArrays(np.tile([3.0, 2.0, 1.0], (n, 1)), np.zeros((n, 3)),
                         np.tile(np.eye(3), (n, 1, 1)))  # fmt: skip
    b = TFStage(plan, offsets=given).static_batch()
    assert b is not None
    by_pair = {(t.header.frame_id, t.child_frame_id): t for t in _transforms(b)}
    p, r = _pose(by_pair[("base_link", "variation_imu")])
    np.testing.assert_allclose(p, [3.0, -2.0, -1.0], rtol=0, atol=1e-12)
    assert r.magnitude() < 1e-12


def test_observe_reference_keeps_the_first_of_many_repeats():
    """200 poses at 10 stamps (row k at stamp k mod 10, position row [3k, 3k + 1, 3k + 2]):
    each stamp once, with its first row k = stamp's index (a stable sort)."""
    stage = TFStage(resolve_plan(_default([])))
    stage.observe_reference(_odometry([T0 + (k % 10) * MS for k in range(200)]))
    assert stage._ref_t.tolist() == [T0 + j * MS for j in range(10)]
    assert stage._ref_p.tolist() == [[3.0 * j, 3.0 * j + 1, 3.0 * j + 2] for j in range(10)]


def _imu(stamps: list[int]):
    from strapdown_ros.messages import ImuFields

    n = len(stamps)
    z3, z9 = np.zeros((n, 3)), np.zeros((n, 9))
    return ImuFields(np.asarray(stamps, dtype=np.int64), "reference_imu",
                     np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), z9, z3, z9, z3, z9)  # fmt: skip


def test_feed_batches_reads_each_batch_as_its_type_only():
    """Increments derived only when configured (default.yaml has them off, on with
    ``recording.increments``), from Imu batches of the IMU topics; an Imu batch on an Odometry
    topic or an Odometry batch on a topic TF does not derive from gives nothing."""
    stamps = [T0 + 5 * k * MS for k in range(4)]
    imu = batch("/reference/imu", _imu(stamps))
    off = TFStage(resolve_plan(_default([])))
    assert off.feed_batches([imu]) == []
    on = TFStage(resolve_plan(_default(["recording.increments=true"])))
    assert [b.topic for b in on.feed_batches([imu])] == ["/reference/imu_dv", "/reference/imu_dq"]
    mislabeled = Batch("/reference/odom", cdr.IMU, imu.stamps_ns, imu.payloads)
    assert on.feed_batches([mislabeled]) == []
    assert on._ref_t.size == 0  # not taken for reference poses
    other = batch("/elsewhere/odom", _odometry(stamps))
    assert on.feed_batches([other]) == []
