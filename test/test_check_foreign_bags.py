"""``check``, ``report``, ``bag info`` and ``replay`` on a bag strapdown_ros did not write: a
robot's bag (sensor_msgs/Imu at 100 Hz in ``imu_link``, nav_msgs/Odometry at 50 Hz in ``odom``,
a std_msgs/String, no strapdown metadata), written here with rosbags' own writer. Each command
says what it can and cannot do with it, with a documented exit status and no traceback
(docs/interface.md §6). Commands run as processes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

T0_NS = 1_700_000_000_000_137_000


def _cli(*args: str) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "strapdown_ros.cli", *args],
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stdout + proc.stderr
    return proc


def write_robot_bag(path: Path, imu_topic: str = "/imu", odom_topic: str = "/odom") -> Path:
    """3 s of a robot driving at 0.5 m/s: Imu 100 Hz, Odometry 50 Hz (local frame), a String."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    t = ts.types
    vec, quat = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Quaternion"]

    def header(ns: int, frame: str):
        return t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
            frame_id=frame,
        )

    msgs = []
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        ci = w.add_connection(imu_topic, "sensor_msgs/msg/Imu", typestore=ts)
        co = w.add_connection(odom_topic, "nav_msgs/msg/Odometry", typestore=ts)
        cs = w.add_connection("/status", "std_msgs/msg/String", typestore=ts)
        for k in range(300):
            ns = T0_NS + k * 10_000_000
            m = t["sensor_msgs/msg/Imu"](
                header=header(ns, "imu_link"), orientation=quat(x=0, y=0, z=0, w=1),
                orientation_covariance=np.r_[-1.0, np.zeros(8)],
                angular_velocity=vec(x=0.01, y=0.0, z=0.02),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec(x=0.1, y=0.0, z=9.81),
                linear_acceleration_covariance=np.zeros(9),
            )  # fmt: skip
            msgs.append((ns, ci, ts.serialize_cdr(m, "sensor_msgs/msg/Imu")))
        for k in range(150):
            ns = T0_NS + k * 20_000_000 + 375_000
            pose = t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=0.01 * k, y=0.0, z=0.0),
                orientation=quat(x=0, y=0, z=0, w=1),
            )
            twist = t["geometry_msgs/msg/Twist"](linear=vec(x=0.5, y=0, z=0),
                                                 angular=vec(x=0, y=0, z=0))  # fmt: skip
            m = t["nav_msgs/msg/Odometry"](
                header=header(ns, "odom"), child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                                 covariance=np.zeros(36)),
            )  # fmt: skip
            msgs.append((ns, co, ts.serialize_cdr(m, "nav_msgs/msg/Odometry")))
        status = ts.serialize_cdr(t["std_msgs/msg/String"](data="ok"), "std_msgs/msg/String")
        msgs.append((T0_NS, cs, status))
        for ns, conn, data in sorted(msgs, key=lambda x: x[0]):
            w.write(conn, ns, data)
    return path


@pytest.fixture(scope="module", params=["paired_names", "other_names"])
def robot_bag(request, tmp_path_factory):
    names = ("/imu", "/odom") if request.param == "paired_names" else ("/imu/data",
                                                                       "/odometry/filtered")
    return write_robot_bag(tmp_path_factory.mktemp("robot") / "bag", *names), names


def test_check_says_nothing_can_be_verified(robot_bag):
    bag, (imu, odom) = robot_bag
    proc = _cli("check", str(bag))
    assert proc.returncode == 2, proc.stdout + proc.stderr  # nothing to verify
    assert "nothing to verify" in proc.stderr
    assert "not written by strapdown_ros" in proc.stdout
    assert "DEFECT" not in proc.stdout
    if imu == "/imu":  # the pair is named like a stream: the reason it is not one
        assert "/imu + /odom: not checked: the Odometry positions (frame 'odom'" in proc.stdout


def test_report_states_what_it_shows(robot_bag, tmp_path):
    bag, (imu, odom) = robot_bag
    proc = _cli("report", str(bag), "--out", str(tmp_path / "r"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    md = (tmp_path / "r" / "report.md").read_text()
    assert "## What this report can show of this bag" in md
    assert "not written by strapdown_ros" in md and "DEFECT" not in md
    assert "![imu](imu.png)" in md  # the robot's Imu is plotted ...
    assert "![trajectory]" not in md  # ... its local-frame Odometry is not a trajectory
    if odom == "/odom":
        assert "`/odom`: Odometry in frame `odom` with positions that are not ECEF" in md


def test_bag_info_states_what_the_commands_do(robot_bag):
    bag, (imu, odom) = robot_bag
    proc = _cli("bag", "info", str(bag))
    assert proc.returncode == 0, proc.stderr
    assert "not written by strapdown_ros" in proc.stdout and f"`{imu}`" in proc.stdout


def test_replay_refuses_before_starting_anything(robot_bag, tmp_path):
    bag, _ = robot_bag
    proc = _cli("replay", str(bag), "--into", "navigator", "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "cannot feed navigator_node" in proc.stderr
    assert "the bag has no topic /variation/imu" in proc.stderr
    assert not (tmp_path / "out").exists()
