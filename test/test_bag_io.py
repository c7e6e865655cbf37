"""Bulk CDR codec vs rosbags and rclpy; bag writer/reader round trips and failure modes."""

import shutil
import zlib

import numpy as np
import pytest
import yaml
from rosbags.typesys import Stores, get_typestore

from strapdown_ros import messages as msg
from strapdown_ros.bag import cdr
from strapdown_ros.bag.reader import BagReadError, read_bag
from strapdown_ros.bag.writer import (
    BagWriteError,
    BagWriter,
    batch,
    clock_batch,
    stream_batches,
    write_stream_topics,
)
from strapdown_ros.core.rotations import dcm_from_rotvec
from strapdown_ros.core.stream import Stream

TS = get_typestore(Stores.ROS2_JAZZY)
FRAME_IDS = ["", "a", "ab", "abc", "abcd", "abcde", "abcdef", "abcdefg", "reference_imu", "ü_frame"]
N = 7


def _stamps(rng, n=N):
    # includes negative and large stamps (sec is int32, nanosec uint32)
    return np.sort(rng.integers(-(2**40), 2_000_000_000 * 10**9, size=n)).astype(np.int64)


def random_fields(rng, msgtype, frame="abc", child="child"):
    n = N
    t = _stamps(rng)
    g = rng.normal
    if msgtype == cdr.IMU:
        return msg.ImuFields(
            t,
            frame,
            g(size=(n, 4)),
            g(size=(n, 9)),
            g(size=(n, 3)),
            g(size=(n, 9)),
            g(size=(n, 3)),
            g(size=(n, 9)),
        )
    if msgtype == cdr.ODOMETRY:
        return msg.OdometryFields(
            t,
            frame,
            child,
            g(size=(n, 3)),
            g(size=(n, 4)),
            g(size=(n, 36)),
            g(size=(n, 3)),
            g(size=(n, 3)),
            g(size=(n, 36)),
        )
    if msgtype == cdr.NAVSATFIX:
        return msg.NavSatFixFields(
            t,
            frame,
            rng.integers(-128, 128, n).astype(np.int8),
            rng.integers(0, 2**16, n).astype(np.uint16),
            g(size=n),
            g(size=n),
            g(size=n),
            g(size=(n, 9)),
            rng.integers(0, 256, n).astype(np.uint8),
        )
    if msgtype == cdr.CLOCK:
        return msg.ClockFields(t)
    if msgtype == cdr.QUATERNION_STAMPED:
        return msg.QuaternionStampedFields(t, frame, g(size=(n, 4)))
    if msgtype == cdr.TF_MESSAGE:  # three transforms: frame, child, and a fixed "map" pair
        frames, children = (frame, "map", child), (child, frame + "_b", "map")
        return msg.TFMessageFields(t, frames, children, g(size=(n, 3, 3)), g(size=(n, 3, 4)))
    if msgtype == cdr.TWIST_WITH_COVARIANCE_STAMPED:  # aiding (issue 16)
        return msg.TwistWithCovarianceStampedFields(
            t, frame, g(size=(n, 3)), g(size=(n, 3)), g(size=(n, 36))
        )
    if msgtype == cdr.FLUID_PRESSURE:
        return msg.FluidPressureFields(t, frame, g(size=n), g(size=n))
    if msgtype == cdr.MAGNETIC_FIELD:
        return msg.MagneticFieldFields(t, frame, g(size=(n, 3)), g(size=(n, 9)))
    return msg.Vector3StampedFields(t, frame, g(size=(n, 3)))


def rosbags_message(f, i):
    """The i-th message of a field container as a rosbags message object."""
    T = TS.types
    sec, nsec = divmod(int(f.stamps_ns[i]), 1_000_000_000)
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    if isinstance(f, msg.ClockFields):
        return T[cdr.CLOCK](clock=stamp)
    if isinstance(f, msg.TFMessageFields):
        return T[cdr.TF_MESSAGE](
            [
                T["geometry_msgs/msg/TransformStamped"](
                    header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=parent),
                    child_frame_id=child,
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](*f.translation[i, k]),
                        rotation=T["geometry_msgs/msg/Quaternion"](*f.rotation[i, k]),
                    ),
                )
                for k, (parent, child) in enumerate(
                    zip(f.frame_ids, f.child_frame_ids, strict=True)
                )
            ]
        )
    header = T["std_msgs/msg/Header"](stamp=stamp, frame_id=f.frame_id)
    vec = T["geometry_msgs/msg/Vector3"]
    quat = T["geometry_msgs/msg/Quaternion"]
    if isinstance(f, msg.ImuFields):
        return T[cdr.IMU](
            header=header,
            orientation=quat(*f.orientation[i]),
            orientation_covariance=f.orientation_covariance[i],
            angular_velocity=vec(*f.angular_velocity[i]),
            angular_velocity_covariance=f.angular_velocity_covariance[i],
            linear_acceleration=vec(*f.linear_acceleration[i]),
            linear_acceleration_covariance=f.linear_acceleration_covariance[i],
        )
    if isinstance(f, msg.OdometryFields):
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](*f.position[i]),
            orientation=quat(*f.orientation[i]),
        )
        twist = T["geometry_msgs/msg/Twist"](
            linear=vec(*f.twist_linear[i]), angular=vec(*f.twist_angular[i])
        )
        return T[cdr.ODOMETRY](
            header=header,
            child_frame_id=f.child_frame_id,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=pose, covariance=f.pose_covariance[i]
            ),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=twist, covariance=f.twist_covariance[i]
            ),
        )
    if isinstance(f, msg.NavSatFixFields):
        return T[cdr.NAVSATFIX](
            header=header,
            status=T["sensor_msgs/msg/NavSatStatus"](
                status=int(f.status[i]), service=int(f.service[i])
            ),
            latitude=f.latitude[i],
            longitude=f.longitude[i],
            altitude=f.altitude[i],
            position_covariance=f.position_covariance[i],
            position_covariance_type=int(f.position_covariance_type[i]),
        )
    if isinstance(f, msg.TwistWithCovarianceStampedFields):
        return T[cdr.TWIST_WITH_COVARIANCE_STAMPED](
            header=header,
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](
                    linear=vec(*f.linear[i]), angular=vec(*f.angular[i])
                ),
                covariance=f.covariance[i],
            ),
        )
    if isinstance(f, msg.FluidPressureFields):
        return T[cdr.FLUID_PRESSURE](
            header=header, fluid_pressure=f.fluid_pressure[i], variance=f.variance[i]
        )
    if isinstance(f, msg.MagneticFieldFields):
        return T[cdr.MAGNETIC_FIELD](
            header=header,
            magnetic_field=vec(*f.magnetic_field[i]),
            magnetic_field_covariance=f.magnetic_field_covariance[i],
        )
    if isinstance(f, msg.QuaternionStampedFields):
        return T[cdr.QUATERNION_STAMPED](header=header, quaternion=quat(*f.quaternion[i]))
    return T[cdr.VECTOR3_STAMPED](header=header, vector=vec(*f.vector[i]))


@pytest.mark.parametrize("msgtype", list(cdr.MSGTYPES))
def test_bytes_equal_rosbags(msgtype):
    rng = np.random.default_rng(zlib.crc32(msgtype.encode()))
    for frame in FRAME_IDS:
        f = random_fields(rng, msgtype, frame, child=frame[::-1] + "x")
        payloads = cdr.serialize(f)
        assert len(payloads) == N
        for i, p in enumerate(payloads):
            assert isinstance(p, bytes)
            assert p == bytes(TS.serialize_cdr(rosbags_message(f, i), msgtype)), (frame, i)
        back = cdr.deserialize(msgtype, payloads)
        assert back.equals(f)
        # rosbags reads our payloads back to the same message
        m = TS.deserialize_cdr(payloads[3], msgtype)
        assert bytes(TS.serialize_cdr(m, msgtype)) == payloads[3]


def test_blocks_and_constant_fields(monkeypatch):
    """serialize() in blocks (reused buffer, skipped all-zero constant fields) stays exact."""
    monkeypatch.setattr(cdr, "_BLOCK_BYTES", 1000)  # a few rows per block, ragged last block
    rng = np.random.default_rng(11)
    n = 23
    t = _stamps(rng, n)
    zeros36 = np.broadcast_to(np.zeros(36), (n, 36))
    negzero36 = np.broadcast_to(np.full(36, -0.0), (n, 36))  # -0.0 is not all-zero bytes
    odom = msg.OdometryFields(
        t,
        "earth",
        "body",
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 8))[:, ::2],  # strided input
        zeros36,
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 3)),
        negzero36,
    )
    fix = msg.navsatfix_fields_from_geodetic(
        t, *rng.normal(size=(3, n)), "gps", position_covariance=np.arange(9.0), service=5
    )
    imu = msg.ImuFields(
        t,
        "imu",
        *(np.broadcast_to(x, (n, k)) for x, k in [([0, 0, 0, 1.0], 4), (np.zeros(9), 9)]),
        rng.normal(size=(n, 3)),
        np.broadcast_to(np.eye(3).ravel(), (n, 9)),
        rng.normal(size=(n, 3)),
        np.zeros((n, 9)),
    )
    for f in (odom, fix, imu):
        msgtype = cdr.msgtype_of(f)
        payloads = cdr.serialize(f)
        assert payloads == cdr.split_rows(cdr.serialize_rows(f))
        assert all(type(p) is bytes for p in payloads)
        for i, p in enumerate(payloads):
            assert p == bytes(TS.serialize_cdr(rosbags_message(f, i), msgtype)), (msgtype, i)
        assert cdr.deserialize(msgtype, payloads).equals(f)
    assert cdr.serialize(msg.ClockFields(np.zeros(0, np.int64))) == []


def test_rclpy_reads_our_payloads_and_we_read_rclpys():
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, NavSatFix

    rng = np.random.default_rng(5)
    imu = random_fields(rng, cdr.IMU, "reference_imu")
    odom = random_fields(rng, cdr.ODOMETRY, "earth", "variation_imu")
    fix = random_fields(rng, cdr.NAVSATFIX, "ab")
    clock = random_fields(rng, cdr.CLOCK)
    for f, cls in ((imu, Imu), (odom, Odometry), (fix, NavSatFix), (clock, Clock)):
        payloads = cdr.serialize(f)
        ros = [deserialize_message(p, cls) for p in payloads]
        stamps = [(m.clock if cls is Clock else m.header.stamp) for m in ros]
        np.testing.assert_array_equal(
            [s.sec * 1_000_000_000 + s.nanosec for s in stamps], f.stamps_ns
        )
        # rclpy's own bytes (padding not zeroed by Fast CDR) decode to the same fields
        again = cdr.deserialize(cdr.msgtype_of(f), [serialize_message(m) for m in ros])
        assert again.equals(f)
    m = deserialize_message(cdr.serialize(imu)[2], Imu)
    assert m.header.frame_id == "reference_imu"
    np.testing.assert_array_equal(
        [m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w], imu.orientation[2]
    )
    np.testing.assert_array_equal(m.orientation_covariance, imu.orientation_covariance[2])
    np.testing.assert_array_equal(
        [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z], imu.angular_velocity[2]
    )
    np.testing.assert_array_equal(
        [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z],
        imu.linear_acceleration[2],
    )
    o = deserialize_message(cdr.serialize(odom)[4], Odometry)
    assert (o.header.frame_id, o.child_frame_id) == ("earth", "variation_imu")
    p = o.pose.pose
    np.testing.assert_array_equal(
        [
            p.position.x,
            p.position.y,
            p.position.z,
            p.orientation.x,
            p.orientation.y,
            p.orientation.z,
            p.orientation.w,
        ],
        np.r_[odom.position[4], odom.orientation[4]],
    )
    np.testing.assert_array_equal(o.pose.covariance, odom.pose_covariance[4])
    tw = o.twist.twist
    np.testing.assert_array_equal(
        [tw.linear.x, tw.linear.y, tw.linear.z, tw.angular.x, tw.angular.y, tw.angular.z],
        np.r_[odom.twist_linear[4], odom.twist_angular[4]],
    )
    np.testing.assert_array_equal(o.twist.covariance, odom.twist_covariance[4])
    n = deserialize_message(cdr.serialize(fix)[1], NavSatFix)
    assert (n.status.status, n.status.service, n.position_covariance_type) == (
        fix.status[1],
        fix.service[1],
        fix.position_covariance_type[1],
    )
    assert (n.latitude, n.longitude, n.altitude) == (
        fix.latitude[1],
        fix.longitude[1],
        fix.altitude[1],
    )


def test_deserialize_errors():
    rng = np.random.default_rng(6)
    a = cdr.serialize(random_fields(rng, cdr.IMU, "ab"))
    b = cdr.serialize(random_fields(rng, cdr.IMU, "ac"))
    c = cdr.serialize(random_fields(rng, cdr.IMU, "abcdefghij"))
    with pytest.raises(cdr.CdrError, match="mixed frame ids"):
        cdr.deserialize(cdr.IMU, a + b)
    with pytest.raises(cdr.CdrError, match="expected"):
        cdr.deserialize(cdr.IMU, a + c)
    with pytest.raises(cdr.CdrError, match="CDR_LE"):
        cdr.deserialize(cdr.IMU, [b"\x00\x00\x00\x00" + a[0][4:]])
    with pytest.raises(cdr.CdrError, match="no bulk CDR codec"):
        cdr.deserialize("std_msgs/msg/String", a)
    assert len(cdr.deserialize(cdr.IMU, [])) == 0


def moving_stream(cycles=50, t0_ns=1_700_000_000_000_000_000, period_ns=5_000_000):
    rng = np.random.default_rng(7)
    n = cycles + 1
    c = dcm_from_rotvec(rng.normal(size=(n, 3)))
    r = np.array([4.2e6, 0.9e6, 4.7e6]) + rng.normal(size=(n, 3))
    return Stream(
        t0_ns,
        period_ns,
        rng.normal(size=(cycles, 3)) * 1e-3,
        rng.normal(size=(cycles, 3)) * 0.05,
        c,
        rng.normal(size=(n, 3)) * 300.0,
        r,
    )


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_write_read_round_trip(tmp_path, storage):
    ref = moving_stream()
    var = moving_stream(cycles=50)
    batches = stream_batches(ref) + stream_batches(
        var,
        imu_topic="/variation/imu",
        odom_topic="/variation/odom",
        fix_topic="/variation/fix",
        body_frame="variation_imu",
    )
    batches.append(clock_batch(ref.stamps_ns))
    measured = msg.imu_fields(
        var, "variation_imu", orientation=False, angular_velocity_covariance=np.eye(3) * 1e-8
    )
    batches.append(batch("/variation/imu_measured", measured))
    err = msg.vector3_stamped_fields(ref.stamps_ns, np.ones((51, 3)), "ned")
    batches.append(batch("/navigator/error/position", err))
    out = tmp_path / "bag"
    with BagWriter(out, storage=storage, custom_data={"scenario": "test"}) as w:
        count = w.write_batches(batches)
    assert count == sum(len(b.payloads) for b in batches)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]  # no temp dir left

    bag = read_bag(out)
    assert bag.storage == storage and bag.version == 9 and bag.message_count == count
    assert bag.custom_data == {"scenario": "test"}
    expected = {
        "/reference/imu": msg.imu_fields(ref),
        "/reference/odom": msg.odometry_fields(ref),
        "/reference/fix": msg.navsatfix_fields(ref),
        "/variation/imu": msg.imu_fields(var, "variation_imu"),
        "/variation/odom": msg.odometry_fields(var, "variation_imu"),
        "/variation/fix": msg.navsatfix_fields(var, "variation_imu"),
        "/clock": msg.clock_fields(ref.stamps_ns),
        "/variation/imu_measured": measured,
        "/navigator/error/position": err,
    }
    assert set(bag.topics) == set(expected)
    for topic, f in expected.items():
        assert bag[topic].equals(f), topic
        np.testing.assert_array_equal(bag.topics[topic].log_time_ns, f.stamps_ns)
    assert bag.topics["/reference/imu"].msgtype == "sensor_msgs/msg/Imu"
    # the whole file is in time order
    with BagWriter(tmp_path / "single", storage=storage) as w:
        write_stream_topics(w, ref)
    assert read_bag(tmp_path / "single", topics=["/reference/imu"])["/reference/imu"].equals(
        msg.imu_fields(ref)
    )
    rebuilt = msg.stream_from_messages(bag["/reference/imu"], bag["/reference/odom"])
    np.testing.assert_allclose(rebuilt.r_e0, ref.r_e0, rtol=0, atol=2e-9)

    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    topic_meta = {
        t["topic_metadata"]["name"]: t["topic_metadata"] for t in meta["topics_with_message_count"]
    }
    qos = topic_meta["/reference/imu"]["offered_qos_profiles"]
    assert qos[0]["reliability"] == "reliable" and qos[0]["durability"] == "volatile"
    assert topic_meta["/reference/imu"]["type_description_hash"].startswith("RIHS01_")


def test_time_order_in_file(tmp_path):
    """Messages are stored in stamp order (sqlite3 row order = write order)."""
    import sqlite3

    ref = moving_stream(cycles=20)
    with BagWriter(tmp_path / "b", storage="sqlite3") as w:
        w.write_batches(stream_batches(ref))
    db = sqlite3.connect(tmp_path / "b" / "b.db3")
    try:
        topics = dict(db.execute("SELECT id, name FROM topics"))
        seq = [
            (t, topics[k])
            for t, k in db.execute("SELECT timestamp, topic_id FROM messages ORDER BY id")
        ]
    finally:
        db.close()
    times = [t for t, _ in seq]
    assert times == sorted(times) and len(seq) == 20 + 2 * 21
    # at equal stamps: odom, fix, imu (the order of the batches)
    assert [tp for t, tp in seq if t == ref.stamps_ns[3]] == [
        "/reference/odom",
        "/reference/fix",
        "/reference/imu",
    ]


def test_type_hashes_match_rclpy(tmp_path):
    import rclpy
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu, NavSatFix

    with BagWriter(tmp_path / "b") as w:
        w.write_batches(stream_batches(moving_stream(cycles=2)))
    meta = yaml.safe_load((tmp_path / "b" / "metadata.yaml").read_text())
    hashes = {
        t["topic_metadata"]["type"]: t["topic_metadata"]["type_description_hash"]
        for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]
    }
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("strapdown_hash_check", context=context)
        for i, (cls, name) in enumerate(
            ((Imu, cdr.IMU), (Odometry, cdr.ODOMETRY), (NavSatFix, cdr.NAVSATFIX))
        ):
            node.create_publisher(cls, f"/strapdown_hash_check_{i}", 1)
            info = node.get_publishers_info_by_topic(f"/strapdown_hash_check_{i}")
            assert str(info[0].topic_type_hash) == hashes[name]
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_refuse_overwrite_and_force(tmp_path):
    s = moving_stream(cycles=3)
    out = tmp_path / "bag"
    with BagWriter(out) as w:
        write_stream_topics(w, s)
    with pytest.raises(BagWriteError, match="exists already"):
        BagWriter(out)
    with BagWriter(out, force=True, storage="sqlite3") as w:
        write_stream_topics(w, s, fix_topic=None)
    bag = read_bag(out)
    assert bag.storage == "sqlite3" and "/reference/fix" not in bag.topics
    other = tmp_path / "notabag"
    other.mkdir()
    (other / "precious.txt").write_text("keep me")
    with pytest.raises(BagWriteError, match="not a rosbag2 bag"):
        BagWriter(other, force=True)
    with pytest.raises(BagWriteError, match="unknown storage"):
        BagWriter(tmp_path / "x", storage="bag1")


def test_incremental_writer_shares_the_destination_rules(tmp_path):
    """The recorder's writer refuses and replaces exactly what BagWriter does."""
    from strapdown_ros.bag.incremental import IncrementalBagWriter

    out = tmp_path / "bag"
    with BagWriter(out) as w:
        write_stream_topics(w, moving_stream(cycles=3))
    with pytest.raises(BagWriteError, match="exists already"):
        IncrementalBagWriter(out).open()
    rec = IncrementalBagWriter(out, force=True, custom_data={"k": "v"}).open()
    rec.add_topic("/reference/imu", "sensor_msgs/msg/Imu")
    rec.close()
    new = read_bag(out)  # the old bag's topics are gone; the new one has one, empty
    assert new.custom_data == {"k": "v"} and list(new.topics) == ["/reference/imu"]
    assert len(new.topics["/reference/imu"].log_time_ns) == 0
    other = tmp_path / "notabag"
    other.mkdir()
    (other / "precious.txt").write_text("keep me")
    with pytest.raises(BagWriteError, match="not a rosbag2 bag"):
        IncrementalBagWriter(other, force=True).open()
    assert (other / "precious.txt").read_text() == "keep me"


def test_no_half_written_bag_on_error(tmp_path):
    s = moving_stream(cycles=3)
    out = tmp_path / "bag"
    with pytest.raises(RuntimeError, match="boom"):
        with BagWriter(out) as w:
            write_stream_topics(w, s)
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    # a failure while replacing (force) keeps the old bag
    with BagWriter(out) as w:
        write_stream_topics(w, s)
    before = sorted(p.name for p in out.iterdir())
    with pytest.raises(TypeError):
        with BagWriter(out, force=True) as w:
            write_stream_topics(w, s, imu_kwargs={"no_such_option": 1})
    assert sorted(p.name for p in out.iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_write_errors(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        w.add_topic("/a", cdr.IMU)
        with pytest.raises(BagWriteError, match="already has type"):
            w.add_topic("/a", cdr.ODOMETRY)
        with pytest.raises(BagWriteError, match="not registered"):
            w.write("/b", 0, b"")
        with pytest.raises(BagWriteError, match="stamps for"):
            w.write_batches(
                [batch("/c", msg.clock_fields(np.arange(3)))._replace(stamps_ns=np.arange(2))]
            )
    with pytest.raises(BagWriteError, match="not open"):
        BagWriter(tmp_path / "c").write("/a", 0, b"")


def test_read_errors(tmp_path):
    with pytest.raises(BagReadError, match="does not exist"):
        read_bag(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagReadError, match="no metadata.yaml"):
        read_bag(tmp_path / "empty")
    s = moving_stream(cycles=200)
    for storage in ("mcap", "sqlite3"):
        out = tmp_path / storage
        with BagWriter(out, storage=storage) as w:
            write_stream_topics(w, s)
        data = next(p for p in out.iterdir() if p.suffix in (".mcap", ".db3"))
        with pytest.raises(BagReadError, match="no topic"):
            read_bag(out, topics=["/nope"])
        # unknown storage
        bad = tmp_path / f"{storage}_badstorage"
        shutil.copytree(out, bad)
        meta = (
            (bad / "metadata.yaml")
            .read_text()
            .replace(f"storage_identifier: {storage}", "storage_identifier: rosbag_v1")
        )
        (bad / "metadata.yaml").write_text(meta)
        with pytest.raises(BagReadError, match="storage 'rosbag_v1'"):
            read_bag(bad)
        # missing data file
        gone = tmp_path / f"{storage}_gone"
        shutil.copytree(out, gone)
        (gone / data.name).unlink()
        with pytest.raises(BagReadError, match="missing"):
            read_bag(gone)
        # truncated data file
        size = data.stat().st_size
        with data.open("r+b") as fh:
            fh.truncate(size // 2)
        with pytest.raises(BagReadError, match=rf"{data.name}.*truncated|truncated.*{data.name}"):
            read_bag(out)
