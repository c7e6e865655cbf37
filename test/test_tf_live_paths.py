"""stages/tf.py's live-node paths without ROS: the topics each node derives
(``node_derived_topics``, ``static_topic``, ``TFStage.topics``), the variation node's reference
input (``TFStage.observe_reference_payloads``) and the solver wrapper (``SolverWithTF``).

Expected values do not come from the code under test: topic names and types counted by hand
from the scenario files and docs/interface.md (topics table, "Frames and TF"), messages
serialized with rosbags' typestore, map-frame positions from the geodetic-to-ECEF closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation
from test_tf_mutants import MS, SCENARIOS, T0, _default, _ecef, _enu, _pose, _stamp

from strapdown_ros.config import load_scenario
from strapdown_ros.plan.resolve import resolve_plan
from strapdown_ros.stages.tf import SolverWithTF, TFStage, node_derived_topics, static_topic

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types

TF = "tf2_msgs/msg/TFMessage"
ODOM = "nav_msgs/msg/Odometry"
DV = "geometry_msgs/msg/Vector3Stamped"
DQ = "geometry_msgs/msg/QuaternionStamped"

# Each node's outputs in default.yaml (docs/interface.md's default names, the node's order).
TRAJECTORY = ("/reference/odom", "/reference/fix", "/reference/imu")
VARIATION = ("/variation/odom", "/variation/fix", "/variation/imu", "/variation/reference/odom",
             "/variation/reference/imu")  # fmt: skip
NAVIGATOR = ("/navigator/odom", "/navigator/fix", "/navigator/error/position",
             "/navigator/error/velocity", "/navigator/error/attitude")  # fmt: skip
AIDING = ("/gnss/fix", "/gnss/vel", "/baro/pressure", "/mag")


def _plan(overrides: list[str] | None = None, name: str = "default.yaml"):
    return resolve_plan(load_scenario(SCENARIOS / name, overrides or [], duration_s=1.0))


def _items(plan, outputs, **kw) -> list[tuple[str, str]]:
    return list(node_derived_topics(plan, outputs, **kw).items())


# -- node_derived_topics -----------------------------------------------------------------------


def test_node_outputs_are_the_plans():
    """The hand lists above are the outputs the default plan gives each node."""
    plan = _plan()
    by_link: dict[str, set[str]] = {}
    for topic, p in plan.topics.items():
        by_link.setdefault(p.link, set()).add(topic)
    assert by_link["trajectory"] == set(TRAJECTORY)
    assert by_link["variation"] == set(VARIATION)
    assert by_link["navigator"] == set(NAVIGATOR)
    assert by_link["aiding"] == set(AIDING)


def test_default_nodes_derive_their_tf_and_map_twins():
    """default.yaml (TF on, map odometry on, increments off, moving variation): trajectory
    /tf_static (static=True only), /tf and /reference/odom_map; variation /tf (moving
    offsets) and the map twins of both its Odometry topics; navigator /tf and its map twin;
    aiding and the IMU error models nothing. ``static`` defaults to False and adds /tf_static
    to any node; the outputs may be any iterable."""
    plan = _plan()
    assert not plan.variation_static
    assert _items(plan, (t for t in TRAJECTORY), static=True) == [
        ("/tf_static", TF), ("/tf", TF), ("/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, TRAJECTORY) == [("/tf", TF), ("/reference/odom_map", ODOM)]
    assert _items(plan, TRAJECTORY, static=False) == [("/tf", TF), ("/reference/odom_map", ODOM)]
    assert _items(plan, VARIATION) == [
        ("/tf", TF), ("/variation/odom_map", ODOM),
        ("/variation/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, VARIATION, static=True) == [
        ("/tf_static", TF), ("/tf", TF), ("/variation/odom_map", ODOM),
        ("/variation/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, NAVIGATOR) == [("/tf", TF), ("/navigator/odom_map", ODOM)]
    assert _items(plan, AIDING) == []
    assert _items(plan, AIDING, static=True) == [("/tf_static", TF)]
    assert _items(plan, ("/variation/imu_measured",)) == []
    assert _items(plan, ("/reference/imu_measured",)) == []
    assert _items(plan, ()) == []


def test_each_odometry_source_alone():
    """One output at a time: the reference, navigator and (moving) variation Odometry are TF
    sources; the variation's reference Odometry only gets its map twin."""
    plan = _plan()
    assert _items(plan, ["/reference/odom"]) == [("/tf", TF), ("/reference/odom_map", ODOM)]
    assert _items(plan, ["/navigator/odom"]) == [("/tf", TF), ("/navigator/odom_map", ODOM)]
    assert _items(plan, ["/variation/odom"]) == [("/tf", TF), ("/variation/odom_map", ODOM)]
    assert _items(plan, ["/variation/reference/odom"]) == [
        ("/variation/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, ["/variation/imu", "/navigator/fix"]) == []


def test_static_variation_derives_no_tf():
    """savage_test_example.yaml (constant lever arm: ``base_link → variation_imu`` is in
    /tf_static): the variation node publishes its map twins and no /tf; the trajectory node
    still /tf_static and /tf."""
    plan = _plan(name="savage_test_example.yaml")
    assert plan.variation_static
    assert _items(plan, VARIATION) == [
        ("/variation/odom_map", ODOM), ("/variation/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, ["/variation/odom"]) == [("/variation/odom_map", ODOM)]
    assert _items(plan, TRAJECTORY, static=True) == [
        ("/tf_static", TF), ("/tf", TF), ("/reference/odom_map", ODOM)]  # fmt: skip
    # the twins in output order
    assert _items(plan, ["/variation/odom", "/reference/odom"]) == [
        ("/tf", TF), ("/variation/odom_map", ODOM), ("/reference/odom_map", ODOM)]  # fmt: skip


def test_tf_disabled_leaves_the_map_twins():
    """``tf.enabled=false``: no /tf_static nor /tf from any node (also with static=True),
    the map twins stay (map_odometry is on)."""
    plan = _plan(["tf.enabled=false"])
    assert _items(plan, TRAJECTORY, static=True) == [("/reference/odom_map", ODOM)]
    assert _items(plan, TRAJECTORY) == [("/reference/odom_map", ODOM)]
    assert _items(plan, VARIATION) == [
        ("/variation/odom_map", ODOM), ("/variation/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, NAVIGATOR, static=True) == [("/navigator/odom_map", ODOM)]
    assert _items(plan, AIDING) == []
    assert _items(plan, AIDING, static=True) == []


def test_map_odometry_off_leaves_tf():
    """``tf.map_odometry=false``: TF only."""
    plan = _plan(["tf.map_odometry=false"])
    assert _items(plan, TRAJECTORY, static=True) == [("/tf_static", TF), ("/tf", TF)]
    assert _items(plan, VARIATION) == [("/tf", TF)]
    assert _items(plan, NAVIGATOR) == [("/tf", TF)]
    assert _items(plan, ["/variation/reference/odom"]) == []
    assert _items(plan, AIDING) == []


def test_increments_beside_each_imu_output():
    """``recording.increments=true``: Δv (Vector3Stamped) and Δq (QuaternionStamped) after
    each Imu output with a recording.topics key, in output order; /reference/imu_measured
    (no key) gets none."""
    plan = _plan(["recording.increments=true"])
    assert _items(plan, TRAJECTORY, static=True) == [
        ("/tf_static", TF), ("/tf", TF), ("/reference/odom_map", ODOM),
        ("/reference/imu_dv", DV), ("/reference/imu_dq", DQ)]  # fmt: skip
    assert _items(plan, VARIATION) == [
        ("/tf", TF), ("/variation/odom_map", ODOM), ("/variation/imu_dv", DV),
        ("/variation/imu_dq", DQ), ("/variation/reference/odom_map", ODOM),
        ("/variation/reference/imu_dv", DV), ("/variation/reference/imu_dq", DQ)]  # fmt: skip
    assert _items(plan, ("/variation/imu_measured",)) == [
        ("/variation/imu_measured_dv", DV), ("/variation/imu_measured_dq", DQ)]  # fmt: skip
    assert _items(plan, ("/reference/imu_measured",)) == []


def test_renamed_tf_topics():
    """``recording.topics.tf_static`` / ``.tf`` and a renamed variation reference Odometry:
    the derived names follow."""
    plan = _plan(["recording.topics.tf_static=/latched", "recording.topics.tf=/poses",
                  "recording.topics.variation_reference_odom=/vr/odom"])  # fmt: skip
    assert _items(plan, TRAJECTORY, static=True) == [
        ("/latched", TF), ("/poses", TF), ("/reference/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, ["/variation/odom", "/vr/odom"]) == [
        ("/poses", TF), ("/variation/odom_map", ODOM), ("/vr/odom_map", ODOM)]  # fmt: skip
    assert _items(plan, ["/vr/odom"]) == [("/vr/odom_map", ODOM)]
    assert _items(plan, AIDING) == []


# -- static_topic, TFStage.topics --------------------------------------------------------------


def test_static_topic_name_or_none():
    assert static_topic(_default([])) == "/tf_static"
    assert static_topic(_default(["recording.topics.tf_static=/latched"])) == "/latched"
    assert static_topic(_default(["tf.enabled=false"])) is None
    assert static_topic(_default(["tf.map_odometry=false"])) == "/tf_static"


def test_stage_topics_are_the_derived_topics_of_its_scenario():
    """``TFStage.topics``: /tf_static, /tf, then the twins of the given produced topics in
    their order (increments on); a scenario with TF off: the twins only."""
    produced = {"/variation/imu": "sensor_msgs/msg/Imu", "/gnss/fix": "sensor_msgs/msg/NavSatFix",
                "/reference/odom": ODOM}  # fmt: skip
    stage = TFStage(_plan(["recording.increments=true"]))
    assert list(stage.topics(produced).items()) == [
        ("/tf_static", TF), ("/tf", TF), ("/variation/imu_dv", DV), ("/variation/imu_dq", DQ),
        ("/reference/odom_map", ODOM)]  # fmt: skip
    off = TFStage(_plan(["tf.enabled=false"]))
    assert list(off.topics(produced).items()) == [("/reference/odom_map", ODOM)]
    assert stage.topics({}) == {"/tf_static": TF, "/tf": TF}


# -- observe_reference_payloads ----------------------------------------------------------------


def _odom_payload(ns: int, frame: str, pos, quat=(0.0, 0.0, 0.0, 1.0),
                  child: str = "reference_imu") -> bytes:  # fmt: skip
    """A nav_msgs/Odometry serialized by rosbags."""
    v3 = T["geometry_msgs/msg/Vector3"]
    header = T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id=frame,
    )
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=pos[0], y=pos[1], z=pos[2]),
        orientation=T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2], w=quat[3]),
    )
    twist = T["geometry_msgs/msg/Twist"](linear=v3(x=0.0, y=0.0, z=0.0),
                                         angular=v3(x=0.0, y=0.0, z=0.0))  # fmt: skip
    msg = T["nav_msgs/msg/Odometry"](
        header=header,
        child_frame_id=child,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
    )
    return bytes(TS.serialize_cdr(msg, ODOM))


GARBAGE = b"\x00\x01\x00\x00\x07"  # CDR header, then a truncated string length


def _stage() -> TFStage:
    return TFStage(_plan())  # default.yaml: moving variation, reference poses kept


def test_reference_payloads_of_one_frame_are_kept():
    """Three ``earth`` Odometry payloads at 0, 5, 10 ms: their stamps and positions kept."""
    stage = _stage()
    pos = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
    stage.observe_reference_payloads([_odom_payload(T0 + 5 * k * MS, "earth", pos[k])
                                      for k in range(3)])  # fmt: skip
    assert stage._ref_t.tolist() == [T0, T0 + 5 * MS, T0 + 10 * MS]
    assert stage._ref_p.tolist() == pos
    assert stage._ref_q.tolist() == [[0.0, 0.0, 0.0, 1.0]] * 3


def test_mixed_reference_payloads_are_read_one_by_one():
    """A batch with mixed frame ids (``earth``, ``map``, ``earth``) and an unreadable payload:
    read one by one, the ``earth`` ones kept, the ``map`` one and the bad one skipped; two
    payloads (``map`` first) the same; a single bad payload, or none, keeps nothing."""
    stage = _stage()
    stage.observe_reference_payloads([
        _odom_payload(T0, "earth", [1.0, 2.0, 3.0]),
        _odom_payload(T0 + 5 * MS, "map", [4.0, 5.0, 6.0]),
        GARBAGE,
        _odom_payload(T0 + 10 * MS, "earth", [7.0, 8.0, 9.0]),
    ])  # fmt: skip
    assert stage._ref_t.tolist() == [T0, T0 + 10 * MS]
    assert stage._ref_p.tolist() == [[1.0, 2.0, 3.0], [7.0, 8.0, 9.0]]
    two = _stage()
    two.observe_reference_payloads([
        _odom_payload(T0, "map", [1.0, 2.0, 3.0]),
        _odom_payload(T0 + 5 * MS, "earth", [4.0, 5.0, 6.0]),
    ])  # fmt: skip
    assert two._ref_t.tolist() == [T0 + 5 * MS]
    assert two._ref_p.tolist() == [[4.0, 5.0, 6.0]]
    bad = _stage()
    bad.observe_reference_payloads([GARBAGE])
    bad.observe_reference_payloads([])
    bad.observe_reference_payloads([GARBAGE, GARBAGE])
    assert bad._ref_t.size == 0


# -- SolverWithTF --------------------------------------------------------------------------------


class _Solver:
    """What a node's solver offers the wrapper: ``on_batch`` and its own attributes."""

    def __init__(self, out: list) -> None:
        self.out = out
        self.seen: list = []
        self.published = 7

    def on_batch(self, items: list) -> list:
        self.seen.append(list(items))
        return self.out


class _Frames:
    """A TFStage stand-in recording what the wrapper hands it."""

    def __init__(self, derived: list) -> None:
        self.derived = derived
        self.observed: list = []
        self.fed: list = []

    def observe_reference_payloads(self, payloads: list) -> None:
        self.observed.append(list(payloads))

    def derive_items(self, items: list) -> list:
        self.fed.append(list(items))
        return list(self.derived)


OUT = [("/variation/odom", T0, b"v0"), ("/variation/imu", T0, b"i0")]
DERIVED = [("/tf", T0, b"t0"), ("/variation/reference/odom_map", T0, b"r0"),
           ("/variation/odom_map", T0, b"m0"), ("/tf", T0 + MS, b"t1")]  # fmt: skip
ITEMS = [("imu", b"a"), ("odom", b"b"), ("imu", b"c"), ("odom", b"d")]


def test_wrapper_outputs_then_derived_items_it_publishes():
    """Reference input ``odom``: its payloads (b, d) observed before the solver runs on all
    items; the solver's outputs first, then the derived items whose topic is published, in
    their order."""
    solver, frames = _Solver(list(OUT)), _Frames(DERIVED)
    w = SolverWithTF(solver, frames, ["/tf", "/variation/odom_map"], reference_input="odom")
    got = w.on_batch(ITEMS)
    assert frames.observed == [[b"b", b"d"]]
    assert solver.seen == [ITEMS]
    assert frames.fed == [OUT]
    assert got == [*OUT, ("/tf", T0, b"t0"), ("/variation/odom_map", T0, b"m0"),
                   ("/tf", T0 + MS, b"t1")]  # fmt: skip


def test_wrapper_without_reference_input_observes_nothing():
    solver, frames = _Solver(list(OUT)), _Frames(DERIVED)
    w = SolverWithTF(solver, frames, {"/variation/reference/odom_map"})
    got = w.on_batch(ITEMS)
    assert frames.observed == []
    assert got == [*OUT, ("/variation/reference/odom_map", T0, b"r0")]


def test_wrapper_without_topics_or_output_is_the_solver():
    """No published derived topic: nothing observed or derived, the solver's list itself; no
    output: the solver's empty list, nothing derived (the reference still observed)."""
    solver, frames = _Solver(list(OUT)), _Frames(DERIVED)
    w = SolverWithTF(solver, frames, [], reference_input="odom")
    got = w.on_batch(ITEMS)
    assert got is solver.out and got == OUT
    assert frames.observed == [] and frames.fed == []
    empty, frames = _Solver([]), _Frames(DERIVED)
    w = SolverWithTF(empty, frames, ["/tf"], reference_input="odom")
    got = w.on_batch(ITEMS)
    assert got is empty.out and got == []
    assert frames.observed == [[b"b", b"d"]] and frames.fed == []


def test_wrapper_attributes_fall_through_to_the_solver():
    """Its own attributes (solver, frames, a set copy of the topics, reference_input), the
    rest the solver's."""
    solver, frames = _Solver(list(OUT)), _Frames(DERIVED)
    topics = ["/tf", "/tf", "/variation/odom_map"]
    w = SolverWithTF(solver, frames, topics, reference_input="odom")
    topics.append("/navigator/odom_map")
    assert w.topics == {"/tf", "/variation/odom_map"} and type(w.topics) is set
    assert w.solver is solver and w.frames is frames and w.reference_input == "odom"
    assert w.published == 7 and w.out is solver.out
    with pytest.raises(AttributeError):
        _ = w.no_such_attribute
    gen = SolverWithTF(solver, frames, (t for t in ("/a", "/b")))
    assert gen.topics == {"/a", "/b"} and gen.reference_input is None


def test_wrapper_with_the_tf_stage_pairs_the_reference_input():
    """default.yaml's variation node path with a real TFStage: the reference Odometry input
    (identity attitude) at 0 and 5 ms, the solver's variation Odometry at the same stamps
    (attitude R_k, scipy): ``base_link → variation_imu`` is p_var − p_ref and R_k, the map twin
    C_E^ENU (p_var − r0) (closed forms); /variation/reference/odom_map is not published."""
    plan = _plan()
    ini = plan.scenario.initial
    lat, lon = math.radians(ini.latitude_deg), math.radians(ini.longitude_deg)
    r0, c = _ecef(lat, lon, ini.altitude_m), _enu(lat, lon)
    stamps = [T0, T0 + 5 * MS]
    p_ref = [r0 + [10.0, -20.0, 30.0], r0 + [11.0, -19.0, 31.0]]
    p_var = [p_ref[0] + [-6.0, 1.5, 0.3], p_ref[1] + [-5.5, 1.0, 0.2]]
    rot = Rotation.from_euler("zyx", [[90.0, 5.0, -3.0], [80.0, 4.0, -2.0]], degrees=True)
    items = [("imu", b"x")] + [("odom", _odom_payload(t, "earth", p)) for t, p in
                               zip(stamps, p_ref, strict=True)]  # fmt: skip
    out = [("/variation/odom", t, _odom_payload(t, "earth", p, q, "variation_imu"))
           for t, p, q in zip(stamps, p_var, rot.as_quat(), strict=True)]  # fmt: skip
    out.append(("/variation/reference/odom", T0, _odom_payload(T0, "earth", p_ref[0])))
    w = SolverWithTF(_Solver(out), TFStage(plan), ["/tf", "/variation/odom_map"],
                     reference_input="odom")  # fmt: skip
    got = w.on_batch(items)
    assert got[:3] == out
    derived = got[3:]
    assert sorted((t, s) for t, s, _ in derived) == [
        ("/tf", T0), ("/tf", T0 + 5 * MS),
        ("/variation/odom_map", T0), ("/variation/odom_map", T0 + 5 * MS)]  # fmt: skip
    for topic, stamp, payload in derived:
        k = stamps.index(stamp)
        if topic == "/tf":
            (tr,) = TS.deserialize_cdr(payload, TF).transforms
            assert (tr.header.frame_id, tr.child_frame_id) == ("base_link", "variation_imu")
            assert _stamp(tr) == stamp
            p, r = _pose(tr)
            np.testing.assert_allclose(p, p_var[k] - p_ref[k], rtol=0, atol=1e-7)
            assert (r.inv() * rot[k]).magnitude() < 1e-9
        else:
            msg = TS.deserialize_cdr(payload, ODOM)
            assert msg.header.frame_id == "map"
            q = msg.pose.pose.position
            np.testing.assert_allclose([q.x, q.y, q.z], c @ (p_var[k] - r0), rtol=0, atol=1e-6)
