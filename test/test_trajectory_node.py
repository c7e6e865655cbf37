"""trajectory_node publishes exactly what ``strapdown-sim generate`` writes (docs/interface.md §6).

A bag is generated offline for 3 s of the default scenario (600 cycles at 200 Hz, with
``recording.clock=true``). Then ``trajectory_node`` runs as its own process next to a raw
subscriber process (test/ros_helpers/raw_recorder.py) in this session's ROS domain, and every
received payload must be byte-identical to the bag's (up to Fast DDS' 4-byte alignment padding,
see :func:`_padded`), in the same order per topic; the payloads are also decoded (the project's
codec and rclpy's own deserializer) and compared bit for bit with the bag's fields. Parameter
errors, the subscriber wait and signals are checked too. Every wait has a timeout and children
still running at the end are killed.
"""

from __future__ import annotations

import os
import pickle
import re
import signal
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")

import node_testing as nt  # noqa: E402

from strapdown_ros.bag import cdr  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
# The node's own streams: no TF/map topics and no aiding sensors (aiding_node's, tested apart).
SCENARIO = nt.scenario_without_tf(REPO / "config" / "scenarios" / "default.yaml", aiding=False)
DURATION_S = 3.0
TOPICS = {
    "/reference/imu": "sensor_msgs/msg/Imu",
    "/reference/odom": "nav_msgs/msg/Odometry",
    "/reference/fix": "sensor_msgs/msg/NavSatFix",
    "/clock": "rosgraph_msgs/msg/Clock",
}
COUNTS = {"/reference/imu": 600, "/reference/odom": 601, "/reference/fix": 601, "/clock": 601}
TIMEOUT_S = 60.0


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """The bag of ``strapdown-sim generate`` for the scenario the node runs (with /clock)."""
    out = tmp_path_factory.mktemp("generate") / "bag"
    # the reference streams only: what trajectory_node publishes
    overrides = ["recording.clock=true", "variation=null", "navigator=null", "imu_errors=null",
                 "aided=null"]
    contents = nt.generated(SCENARIO, out, DURATION_S, overrides, timeout=120)
    assert {t: len(d.payloads) for t, d in contents.topics.items()} == COUNTS
    return contents


def _record_and_run(
    procs: list[nt.Proc], ros_env, tmp_path: Path, counts: dict[str, int], *params: str
) -> tuple[dict, nt.Proc]:
    """Run the recorder and the node; return the recording and the node process."""
    deadline = time.monotonic() + TIMEOUT_S
    topics = [(topic, msgtype, counts[topic]) for topic, msgtype in TOPICS.items()]
    recorder, out = nt.raw_recorder(procs, ros_env, tmp_path, topics, TIMEOUT_S - 5)
    node = nt.launch(procs, nt.node_args("trajectory_node", *params), ros_env, tmp_path,
                     "trajectory_node")  # fmt: skip
    node_rc = node.wait(deadline)
    rec_rc = recorder.wait(deadline)
    assert node_rc == 0, node.describe() + recorder.describe()
    assert rec_rc == 0, recorder.describe() + node.describe()
    assert "Traceback" not in node.output, node.describe()
    with open(out, "rb") as f:
        return pickle.load(f), node


def _check_rclpy_decoding(topic: str, payloads: list[bytes], want) -> None:
    """Decode with rclpy's own deserializer and compare key fields bit for bit with the bag."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, NavSatFix

    def stamp(s) -> int:
        return s.sec * 1_000_000_000 + s.nanosec

    def same(got: list, expected) -> None:
        g = np.asarray(got, dtype=np.float64)
        assert g.tobytes() == np.ascontiguousarray(expected, dtype=np.float64).tobytes(), topic

    cls = {"/reference/imu": Imu, "/reference/odom": Odometry, "/reference/fix": NavSatFix}
    msgs = [deserialize_message(p, cls.get(topic, Clock)) for p in payloads]
    if topic == "/clock":
        assert [stamp(m.clock) for m in msgs] == want.stamps_ns.tolist()
        return
    assert [stamp(m.header.stamp) for m in msgs] == want.stamps_ns.tolist()
    assert {m.header.frame_id for m in msgs} == {want.frame_id}
    if topic == "/reference/imu":
        same([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in msgs],
             want.angular_velocity)  # fmt: skip
        a = [m.linear_acceleration for m in msgs]
        same([[v.x, v.y, v.z] for v in a], want.linear_acceleration)
        q = [m.orientation for m in msgs]
        same([[v.x, v.y, v.z, v.w] for v in q], want.orientation)
    elif topic == "/reference/odom":
        p = [m.pose.pose.position for m in msgs]
        same([[v.x, v.y, v.z] for v in p], want.position)
        q = [m.pose.pose.orientation for m in msgs]
        same([[v.x, v.y, v.z, v.w] for v in q], want.orientation)
        t = [m.twist.twist.linear for m in msgs]
        same([[v.x, v.y, v.z] for v in t], want.twist_linear)
        assert {m.child_frame_id for m in msgs} == {want.child_frame_id}
    else:
        same([m.latitude for m in msgs], want.latitude)
        same([m.longitude for m in msgs], want.longitude)
        same([m.altitude for m in msgs], want.altitude)


def _compare(recording: dict, bag, topics: list[str]) -> None:
    for topic in topics:
        got = recording["topics"][topic]
        want = bag.topics[topic]
        assert len(got) == len(want.payloads), topic
        pairs = zip(got, want.payloads, strict=True)
        first_bad = next((i for i, (g, w) in enumerate(pairs) if g != nt.padded(w)), None)
        assert first_bad is None, f"{topic}: payload {first_bad} differs from the bag"
        decoded = cdr.deserialize(want.msgtype, got)
        assert nt.bitwise_equal(decoded, want.fields), topic
        _check_rclpy_decoding(topic, got, want.fields)


def test_publishes_exactly_the_generated_bag(bag, procs, ros_env, tmp_path):
    """rate_factor 0, time_source sim: imu, odom, fix and /clock identical to the bag."""
    recording, node = _record_and_run(
        procs,
        ros_env,
        tmp_path,
        COUNTS,
        f"scenario:={SCENARIO}",
        f"duration_s:={DURATION_S}",
        "rate_factor:=0.0",
        "wait_for_subscribers:=1",
    )
    _compare(recording, bag, list(TOPICS))
    for topic, n in COUNTS.items():
        assert f"{topic}: {n}" in node.output, node.describe()


def test_paced_wall_time_run(bag, procs, ros_env, tmp_path):
    """rate_factor 1, time_source wall: no /clock, data identical, published in real time."""
    counts = dict(COUNTS, **{"/clock": 0})
    recording, node = _record_and_run(
        procs,
        ros_env,
        tmp_path,
        counts,
        f"scenario:={SCENARIO}",
        "duration_s:=3",  # an integer is accepted for a double parameter
        "rate_factor:=1.0",
        "time_source:=wall",
        "wait_for_subscribers:=1",
    )
    assert recording["topics"]["/clock"] == []
    _compare(recording, bag, ["/reference/imu", "/reference/odom", "/reference/fix"])
    # 600 IMU messages 5 ms apart: first to last arrival spans 2.995 s of wall time, not a burst
    # (how late it may be: a figure of bench/bench_node_timing.py, not asserted here).
    arrival = np.asarray(recording["arrival"]["/reference/imu"])
    span = arrival[-1] - arrival[0]
    print(f"trajectory_node paced: 600 IMU messages span {span:.3f} s (ideal 2.995 s)")
    assert span > 2.95, span
    match = re.search(r"3\.000 s of data in (\d+\.\d+) s of wall time", node.output)
    assert match and float(match.group(1)) > 2.99, node.describe()
    assert re.search(r"max lateness \d+\.\d+ ms", node.output), node.describe()


@pytest.mark.parametrize(
    ("params", "expected"),
    [
        ([], r"parameter 'scenario': is required"),
        (["scenario:=/nonexistent/scenario.yaml"], r"scenario file not found"),
        (
            [f"scenario:={SCENARIO}", "overrides:=['initial.latitude_deg=100']"],
            r"invalid scenario: initial\.latitude_deg: must be <= 90",
        ),
        (
            [f"scenario:={SCENARIO}", "overrides:=trajectory.segments.0.duration_s=-1"],
            r"invalid scenario: trajectory\.segments\[0\]\.duration_s: must be > 0",
        ),
        ([f"scenario:={SCENARIO}", "duration_s:=601.0"], r"invalid scenario: duration_s: "),
        ([f"scenario:={SCENARIO}", "time_source:=gps"], r"parameter 'time_source': must be one"),
        ([f"scenario:={SCENARIO}", "qos_reliability:=x"], r"parameter 'qos_reliability'"),
    ],
    ids=["missing", "no-file", "bad-value", "bad-segment", "too-long", "time-source", "qos"],
)
def test_invalid_input_exits_2(params, expected, ros_env):
    rc, output = nt.node_exit("trajectory_node", ros_env, *params)
    assert rc == 2, output
    assert re.search(expected, output), output


def test_no_subscriber_within_timeout_exits_1(ros_env):
    topic = f"/strapdown_test/lonely_imu_{os.getpid()}"
    params = [f"scenario:={SCENARIO}", "duration_s:=1.0", f"imu_topic:={topic}"]
    params += [
        f"odom_topic:={topic}_odom",
        f"fix_topic:={topic}_fix",
        f"clock_topic:={topic}_clock",
        "wait_for_subscribers:=1",
        "wait_timeout_s:=0.5",
    ]
    rc, output = nt.node_exit("trajectory_node", ros_env, *params)
    assert rc == 1, output
    assert "timeout after 0.5 s waiting for subscriptions" in output, output
    assert "(has 0, wants 1)" in output, output


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_stops_cleanly(sig, procs, ros_env, tmp_path):
    deadline = time.monotonic() + TIMEOUT_S
    topic = f"/strapdown_test/signal_imu_{os.getpid()}"
    node = nt.Proc(
        nt.node_args(
            "trajectory_node",
            f"scenario:={SCENARIO}",
            "duration_s:=60",
            "rate_factor:=1",
            f"imu_topic:={topic}",
            f"odom_topic:={topic}_odom",
            f"fix_topic:={topic}_fix",
            f"clock_topic:={topic}_clock",
        ),
        ros_env,
        tmp_path,
        "trajectory_node",
    )
    procs.append(node)
    node.wait_for(r"time_source sim, rate_factor 1", deadline)
    time.sleep(0.5)  # publishing, paced
    node.proc.send_signal(sig)
    assert node.wait(time.monotonic() + 15) == 0, node.describe()
    assert "Traceback" not in node.output, node.describe()
