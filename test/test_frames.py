"""Frames and TF (docs/interface.md "Frames and TF"): datum maths, the TFMessage /
QuaternionStamped codecs (byte-identical to rosbags), increments, map-frame odometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from strapdown_ros import messages as msgs
from strapdown_ros.bag import cdr
from strapdown_ros.core.earth import dcm_ned_to_ecef, geodetic_to_ecef
from strapdown_ros.core.frames import Datum, body_in_map, sensor_in_body
from strapdown_ros.core.rotations import rotvec_from_quat

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types


def _time(ns: int):
    return T["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))


def test_datum_axes_and_inverse() -> None:
    lat, lon, alt = np.radians(48.1), np.radians(11.6), 520.0
    d = Datum.at(lat, lon, alt)
    np.testing.assert_allclose(d.r0_e, geodetic_to_ecef(lat, lon, alt), rtol=0, atol=1e-9)
    np.testing.assert_allclose(d.c_map_e @ d.c_map_e.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(d.c_map_e) == pytest.approx(1.0, abs=1e-15)
    c_ned_e = dcm_ned_to_ecef(lat, lon)
    # east = NED y, north = NED x, up = −NED z
    np.testing.assert_allclose(d.c_map_e[:, 0], c_ned_e[:, 1], atol=1e-15)
    np.testing.assert_allclose(d.c_map_e[:, 1], c_ned_e[:, 0], atol=1e-15)
    np.testing.assert_allclose(d.c_map_e[:, 2], -c_ned_e[:, 2], atol=1e-15)
    # 10 m up, 3 m north of the datum
    p = d.to_map(d.r0_e + 10.0 * d.c_map_e[:, 2] + 3.0 * d.c_map_e[:, 1])
    np.testing.assert_allclose(p, [0.0, 3.0, 10.0], atol=1e-8)
    r = np.random.default_rng(0).normal(size=(50, 3)) * 1e4 + d.r0_e
    np.testing.assert_allclose(d.to_earth(d.to_map(r)), r, rtol=0, atol=1e-8)


def test_level_body_facing_north_in_map() -> None:
    """A level body (FRD) heading north: in map (ENU) it faces +y, i.e. yaw +90°."""
    lat, lon = np.radians(30.0), np.radians(-100.0)
    d = Datum.at(lat, lon, 0.0)
    c_frd_e = dcm_ned_to_ecef(lat, lon)[None]  # C_FRD^NED = I
    pose = body_in_map(d, d.r0_e[None], c_frd_e)
    np.testing.assert_allclose(pose.position, 0.0, atol=1e-9)
    q = msgs.quat_ros_from_dcm(pose.c_body_map)[0]
    np.testing.assert_allclose(q, [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)], atol=1e-15)


def test_sensor_in_body_flu() -> None:
    """Lever arm 1 m forward, 0.5 m right, 0.2 m down (FRD) → (1, −0.5, −0.2) FLU; a 90° yaw
    to the right (FRD z) is a −90° yaw in FLU; the displacement is in the sensor axes."""
    c = Rotation.from_rotvec([0, 0, np.pi / 2]).as_matrix()[None]
    p, c_flu = sensor_in_body([[1.0, 0.5, 0.2]], [[0.1, 0.0, 0.0]], c)
    np.testing.assert_allclose(p, [[1.0, -0.5 - 0.1, -0.2]], atol=1e-15)
    np.testing.assert_allclose(
        c_flu, Rotation.from_rotvec([0, 0, -np.pi / 2]).as_matrix()[None], atol=1e-15
    )


@pytest.mark.parametrize(
    "frames", [("map",), ("earth", "base_link_x"), ("a", "bb", "ccc")], ids=["k1", "k2", "k3"]
)
def test_tf_codec_matches_rosbags(frames: tuple[str, ...]) -> None:
    k, n = len(frames), 200
    rng = np.random.default_rng(k)
    stamps = np.arange(n, dtype=np.int64) * 5_000_000 + 1_700_000_000_123_456_789
    c = Rotation.random(n * k, random_state=k).as_matrix().reshape(n, k, 3, 3)
    children = tuple(f + "_c" for f in frames)
    f = msgs.tf_message_fields(stamps, frames, children, rng.normal(size=(n, k, 3)), c)
    payloads = cdr.serialize(f)
    for i in (0, 77, n - 1):
        msg = T["tf2_msgs/msg/TFMessage"](
            [
                T["geometry_msgs/msg/TransformStamped"](
                    header=T["std_msgs/msg/Header"](stamp=_time(stamps[i]), frame_id=frames[j]),
                    child_frame_id=children[j],
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](*f.translation[i, j]),
                        rotation=T["geometry_msgs/msg/Quaternion"](*f.rotation[i, j]),
                    ),
                )
                for j in range(k)
            ]
        )
        assert bytes(TS.serialize_cdr(msg, cdr.TF_MESSAGE)) == payloads[i]
    back = cdr.deserialize(cdr.TF_MESSAGE, payloads)
    assert back.equals(f)
    # quaternions: w >= 0 and the DCM back to 1e-15
    assert np.all(f.rotation[..., 3] >= 0)
    np.testing.assert_allclose(msgs.dcm_from_quat_ros(f.rotation), c, atol=1e-15)


def test_quaternion_stamped_codec_matches_rosbags() -> None:
    stamps = np.arange(10, dtype=np.int64) * 1_000_000 + 3
    q = msgs.quaternion_stamped_fields(stamps, np.random.default_rng(1).normal(size=(10, 4)), "imu")
    payloads = cdr.serialize(q)
    msg = T["geometry_msgs/msg/QuaternionStamped"](
        header=T["std_msgs/msg/Header"](stamp=_time(stamps[4]), frame_id="imu"),
        quaternion=T["geometry_msgs/msg/Quaternion"](*q.quaternion[4]),
    )
    assert bytes(TS.serialize_cdr(msg, cdr.QUATERNION_STAMPED)) == payloads[4]
    assert cdr.deserialize(cdr.QUATERNION_STAMPED, payloads).equals(q)


def test_increments_recover_the_generator_increments() -> None:
    rng = np.random.default_rng(3)
    n, period_ns = 500, 5_000_000
    dalpha = rng.normal(size=(n, 3)) * np.logspace(-9, -1, n)[:, None]  # tiny to large angles
    dv = rng.normal(size=(n, 3))
    stamps = np.arange(1, n + 1, dtype=np.int64) * period_ns
    imu = msgs.imu_fields_from_increments(stamps, dalpha, dv, period_ns)
    f_dv, f_dq = msgs.increment_fields(imu, period_ns)
    assert f_dv.frame_id == f_dq.frame_id == imu.frame_id
    np.testing.assert_array_equal(f_dv.stamps_ns, stamps)
    # FLU = diag(1, -1, -1) FRD; to 1 ulp of the Δ/T round trip
    flu = np.array([1.0, -1.0, -1.0])
    np.testing.assert_allclose(f_dv.vector, dv * flu, rtol=3e-16, atol=0)
    q = f_dq.quaternion
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=2e-16)
    phi = rotvec_from_quat(np.concatenate([q[:, 3:], q[:, :3]], axis=1))
    np.testing.assert_allclose(phi, dalpha * flu, rtol=1e-14, atol=1e-22)


def test_map_odometry_of_ecef_odometry() -> None:
    lat, lon = np.radians(45.0), np.radians(7.0)
    d = Datum.at(lat, lon, 100.0)
    rng = np.random.default_rng(5)
    n = 20
    r_e = d.r0_e + rng.normal(size=(n, 3)) * 1000
    c_b_e = Rotation.random(n, random_state=5).as_matrix()
    odom = msgs.odometry_fields_from_ecef(
        np.arange(n), r_e, rng.normal(size=(n, 3)), c_b_e, rng.normal(size=(n, 3)), "body"
    )
    m = msgs.map_odometry_fields(odom, d.r0_e, d.c_map_e)
    assert (m.frame_id, m.child_frame_id) == ("map", "body")
    pose = body_in_map(d, r_e, c_b_e)
    np.testing.assert_allclose(m.position, pose.position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(msgs.dcm_from_quat_ros(m.orientation), pose.c_body_map, atol=1e-15)
    np.testing.assert_array_equal(m.twist_linear, odom.twist_linear)
    np.testing.assert_array_equal(m.twist_angular, odom.twist_angular)
    np.testing.assert_array_equal(m.pose_covariance, 0.0)
    # a given covariance is rotated into map axes; "not provided" is kept
    cov = np.diag([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    m2 = msgs.map_odometry_fields(
        msgs.odometry_fields_from_ecef(
            np.arange(n), r_e, r_e * 0, c_b_e, r_e * 0, "b", pose_covariance=cov
        ),
        d.r0_e,
        d.c_map_e,
    )
    c = d.c_map_e.T
    np.testing.assert_allclose(m2.pose_covariance[0].reshape(6, 6)[:3, :3], c @ cov[:3, :3] @ c.T)
    m3 = msgs.map_odometry_fields(
        msgs.odometry_fields_from_ecef(
            np.arange(n), r_e, r_e * 0, c_b_e, r_e * 0, "b", pose_covariance="not_provided"
        ),
        d.r0_e,
        d.c_map_e,
    )
    assert m3.pose_covariance[0, 0] == -1.0 and not m3.pose_covariance[:, 1:].any()


def test_frames_stage_same_bytes_for_any_chunking() -> None:
    """generate's path (whole batches) and the nodes' path (messages in arbitrary chunks) give
    the same derived messages, topic by topic, in the same order; counts as derived_counts."""
    from strapdown_ros.bag.batches import merge_order
    from strapdown_ros.config import load_scenario
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.tf import TFStage, derived_topic_plans, derived_topics
    from strapdown_ros.stages.trajectory import reference_batch_chunks
    from strapdown_ros.stages.variation import VariationStage

    repo = Path(__file__).resolve().parent.parent
    scenario = load_scenario(repo / "config/scenarios/default.yaml", duration_s=3.0)
    scenario = scenario.with_recording(increments=True)
    plan = resolve_plan(scenario)
    variation = VariationStage.offline(scenario, plan.cycles)
    source: list = []
    for _, batches in reference_batch_chunks(plan):
        source += batches + variation.feed_batches(batches)
    whole = TFStage(plan, offsets=variation.offsets)
    expected: dict[str, list[bytes]] = {}
    for b in whole.feed_batches(source):
        expected.setdefault(b.topic, []).extend(bytes(p) for p in b.payloads)
    items = [(source[k].topic, stamp, source[k].payloads[i]) for k, i, stamp in merge_order(source)]
    live = TFStage(plan)  # the node computes the offsets itself
    got: dict[str, list[bytes]] = {}
    rng = np.random.default_rng(7)
    pos = 0
    while pos < len(items):
        n = int(rng.integers(1, 50))
        for topic, _, payload in live.derive_items(items[pos : pos + n]):
            got.setdefault(topic, []).append(bytes(payload))
        pos += n
    # /tf gets several sources' transforms (reference, variation) whose interleaving depends
    # on the chunks (and, live, on the publishers): compared as a multiset; others in order
    n_tf = len(expected["/tf"])
    assert sorted(got.pop("/tf")) == sorted(expected.pop("/tf"))
    assert got == expected
    produced = {b.topic: b.msgtype for b in source}  # the stages fed here
    assert set(produced) <= set(plan.topic_types())
    assert set(expected) | {"/tf_static", "/tf"} == set(derived_topics(scenario, produced))
    upstream = {t: p for t, p in plan.topics.items() if t in produced}
    want = {t: len(v) for t, v in expected.items()} | {"/tf_static": 1, "/tf": n_tf}
    assert {p.topic: p.count for p in derived_topic_plans(plan, upstream)} == want


def test_recorder_reads_the_tf_stamp_for_the_log_time() -> None:
    """bag_recorder logs a message at its header stamp; for TFMessage, the first transform's
    (so that run's /tf has generate's log times). An empty TFMessage has none."""
    from strapdown_ros.bag.payload import PayloadInspector

    inspector = PayloadInspector(cdr.TF_MESSAGE)
    fields = msgs.tf_message_fields(
        np.array([1_700_000_000_123_456_789]),
        ["a", "bb"],
        ["c", "dd"],
        np.zeros((1, 2, 3)),
        np.tile(np.eye(3), (1, 2, 1, 1)),
    )
    (payload,) = cdr.serialize(fields)
    assert inspector.stamp_ns(payload) == 1_700_000_000_123_456_789
    assert not inspector.may_be_padded and inspector.true_length(payload) == len(payload)
    empty = bytes(TS.serialize_cdr(T["tf2_msgs/msg/TFMessage"]([]), cdr.TF_MESSAGE))
    assert inspector.stamp_ns(empty) is None
