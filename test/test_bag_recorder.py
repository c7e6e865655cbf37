"""bag_recorder records over real DDS exactly what ``strapdown-sim generate`` writes.

``trajectory_node`` (its own process, this session's ROS domain) publishes a scenario's
reference stream and ``/clock``; ``bag_recorder`` (another process) records the topics the
scenario produces into a bag on disk, which is read back and compared byte for byte with the
bag of ``generate`` for the same scenario (Fast DDS' NavSatFix padding stripped, log time =
header stamp). Also: SIGINT/SIGTERM finalize the bag; after a SIGKILL, ``strapdown-sim bag
repair`` restores every message that was flushed (both storages); 1 kHz without loss; invalid
parameters exit 2. Every wait has a timeout; children still running at the end are killed.
"""

from __future__ import annotations

import re
import signal
import time
from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")

import node_testing as nt  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402

from strapdown_ros.bag.reader import read_bag  # noqa: E402
from strapdown_ros.bag.writer import DEFAULT_QOS  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SCENARIO = nt.scenario_without_tf(REPO / "config" / "scenarios" / "default.yaml")
#: The reference stream with /clock: what trajectory_node publishes (time_source sim).
OVERRIDES = ["recording.clock=true", "variation=null", "navigator=null", "imu_errors=null",
             "aided=null"]
TOPICS = ["/clock", "/reference/odom", "/reference/fix", "/reference/imu"]
TIMEOUT_S = 90.0


def _generate(out: Path, duration_s: float, *extra: str) -> object:
    return nt.generated(SCENARIO, out, duration_s, [*OVERRIDES, *extra])


@pytest.fixture(scope="module")
def bag3(tmp_path_factory):
    """generate's bag of the reference stream, 3 s at 200 Hz (600 cycles)."""
    return _generate(tmp_path_factory.mktemp("gen") / "bag", 3.0)


@pytest.fixture(scope="module")
def bag30(tmp_path_factory):
    """generate's bag of the reference stream, 30 s (for the interrupted recordings)."""
    return _generate(tmp_path_factory.mktemp("gen") / "bag", 30.0)


def _overrides(extra: list[str]) -> str:
    return nt.list_param("overrides", [*OVERRIDES, *extra])


def _recorder(tmp_path: Path, ros_env, out: Path, *params: str, extra=()) -> nt.Proc:
    args = nt.node_args("bag_recorder", f"scenario:={SCENARIO}", _overrides(list(extra)),
                        f"output:={out}", *params)  # fmt: skip
    return nt.Proc(args, ros_env, tmp_path, "bag_recorder")


def _trajectory(
    tmp_path: Path, ros_env, duration_s: float, rate_factor: float, extra=(), params=()
) -> nt.Proc:
    args = nt.node_args(
        "trajectory_node", f"scenario:={SCENARIO}", _overrides(list(extra)),
        f"duration_s:={float(duration_s)}", f"rate_factor:={float(rate_factor)}",
        "wait_for_subscribers:=1", "wait_timeout_s:=30.0", "qos_depth:=10000", *params,
    )  # fmt: skip
    return nt.Proc(args, ros_env, tmp_path, "trajectory_node")


def _assert_prefix(got, want, topic: str, at_least: int = 0) -> int:
    """``got``'s messages of ``topic`` are the first n of ``want``'s, byte for byte."""
    g, w = got.topics[topic], want.topics[topic]
    n = len(g.payloads)
    assert n >= at_least, f"{topic}: {n} messages, expected at least {at_least}"
    first_bad = next((i for i in range(n) if g.payloads[i] != w.payloads[i]), None)
    assert first_bad is None, f"{topic}: message {first_bad} differs from generate's"
    assert g.log_time_ns.tolist() == w.log_time_ns[:n].tolist(), topic
    return n


def _run_to_end(procs, ros_env, tmp_path, want, duration_s, rate_factor, extra=(), storage="mcap"):
    deadline = time.monotonic() + TIMEOUT_S
    out = tmp_path / "rec"
    rec = _recorder(
        tmp_path, ros_env, out, "stop_when_done:=true", f"storage:={storage}", extra=extra
    )
    procs.append(rec)
    rec.wait_for(r"recording \d+ topic\(s\)", deadline)
    node = _trajectory(tmp_path, ros_env, duration_s, rate_factor, extra)
    procs.append(node)
    assert node.wait(deadline) == 0, node.describe() + rec.describe()
    assert rec.wait(deadline) == 0, rec.describe()
    assert "Traceback" not in rec.output, rec.describe()
    got = read_bag(out, raw=True)
    assert got.storage == storage
    assert sorted(got.topics) == sorted(TOPICS)
    for topic in TOPICS:
        n = _assert_prefix(got, want, topic)
        assert n == len(want.topics[topic].payloads), f"{topic}: lost messages\n{rec.describe()}"
    return got, rec, out


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_records_exactly_what_generate_writes(storage, bag3, procs, ros_env, tmp_path):
    """As fast as trajectory_node can publish (rate_factor 0): every message, byte-identical."""
    got, rec, out = _run_to_end(procs, ros_env, tmp_path, bag3, 3.0, 0.0, storage=storage)
    assert got.message_count == 2403
    out_log = rec.output
    assert re.search(r"recorded 2403 messages on 4 topic\(s\)", out_log), rec.describe()
    assert re.search(r"/reference/fix +601 msgs .*601 padded payloads stripped", out_log)
    for topic, n in (("/clock", 601), ("/reference/odom", 601), ("/reference/imu", 600)):
        assert re.search(rf"{re.escape(topic)} +{n} msgs", out_log), rec.describe()
    assert "stopping (every publisher is gone)" in out_log
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    custom = meta["custom_data"]
    assert custom["scenario"] == "default" and custom["recorder"] == "bag_recorder"
    # what generate writes too (dataset.bag_custom_data); this scenario has no variation
    assert custom["rate_hz"] == "200" and "variation.method" not in custom
    with AnyReader([out]) as reader:  # the publishers' offered QoS, as ros2 bag record stores it
        assert {c.topic for c in reader.connections} == set(TOPICS)
        assert all(c.ext.offered_qos_profiles == [DEFAULT_QOS] for c in reader.connections)


@pytest.mark.slow
def test_1khz_without_loss(procs, ros_env, tmp_path):
    """rate_hz 1000 in real time, then the same as a burst: 4 topics, no message lost."""
    extra = ["rate_hz=1000"]
    want = _generate(tmp_path / "gen", 4.0, *extra)
    for rate_factor in (1.0, 0.0):
        run_dir = tmp_path / f"rf{rate_factor:g}"
        run_dir.mkdir()
        got, rec, _ = _run_to_end(procs, ros_env, run_dir, want, 4.0, rate_factor, extra)
        assert got.message_count == 4 * 4000 + 3, rec.describe()


def _last_flushed(output: str) -> dict[str, int]:
    lines = re.findall(r"progress: \d+ messages received, \d+ flushed \(([^)]*)\)", output)
    assert lines, output
    return {t: int(n) for t, n in (item.rsplit(" ", 1) for item in lines[-1].split(", "))}


def _interrupted(procs, ros_env, tmp_path, storage: str):
    """Recorder + trajectory_node (30 s in real time); returns both once 2 s are flushed."""
    deadline = time.monotonic() + TIMEOUT_S
    out = tmp_path / "rec"
    rec = _recorder(
        tmp_path, ros_env, out, f"storage:={storage}", "flush_period_s:=0.5",
        "progress_period_s:=0.5",
    )  # fmt: skip
    procs.append(rec)
    rec.wait_for(r"recording \d+ topic\(s\)", deadline)
    node = _trajectory(tmp_path, ros_env, 30.0, 1.0)
    procs.append(node)
    rec.wait_for(r"progress: \d+ messages received, [1-9]\d{3,} flushed", deadline)
    return rec, node, out, deadline


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_finalizes_the_bag(sig, bag30, procs, ros_env, tmp_path):
    rec, node, out, deadline = _interrupted(procs, ros_env, tmp_path, "mcap")
    flushed = _last_flushed(rec.output)
    rec.proc.send_signal(sig)
    assert rec.wait(deadline) == 0, rec.describe()
    node.kill()
    assert f"stopping ({sig.name})" in rec.output, rec.describe()
    match = re.search(r"recorded (\d+) messages on 4 topic\(s\)", rec.output)
    assert match, rec.describe()
    assert "Traceback" not in rec.output, rec.describe()
    got = read_bag(out, raw=True)  # metadata.yaml and the MCAP summary were written
    assert got.message_count == int(match.group(1))
    for topic in TOPICS:
        n = _assert_prefix(got, bag30, topic, at_least=flushed[topic])
        assert re.search(rf"{re.escape(topic)} +{n} msgs", rec.output), rec.describe()


@pytest.mark.slow
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_sigkill_then_repair_keeps_every_flushed_message(storage, bag30, procs, ros_env, tmp_path):
    rec, node, out, _ = _interrupted(procs, ros_env, tmp_path, storage)
    time.sleep(0.7)  # between two flushes, with unflushed messages in the recorder
    flushed = _last_flushed(rec.output)
    rec.proc.send_signal(signal.SIGKILL)
    rec.proc.wait(timeout=10)
    node.kill()
    assert rec.proc.returncode == -signal.SIGKILL
    assert not (out / "metadata.yaml").exists()
    proc = nt.sim("bag", "repair", out, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"repaired {storage} bag" in proc.stdout, proc.stdout
    got = read_bag(out, raw=True)
    total = 0
    for topic in TOPICS:  # in order, byte for byte, no duplicate, nothing flushed missing
        total += _assert_prefix(got, bag30, topic, at_least=flushed[topic])
    assert got.message_count == total
    assert re.search(rf"{total} messages on 4 topics", proc.stdout), proc.stdout
    with AnyReader([out]) as reader:
        assert sum(1 for _ in reader.messages()) == total


@pytest.mark.parametrize(
    ("params", "expected"),
    [
        ([], r"parameter 'output': is required"),
        (["output:=EXISTING"], r"parameter 'output': .* exists already \(set force:=true\)"),
        (["output:=OUT", "storage:=rosbag1"], r"parameter 'storage': must be one of"),
        (["output:=OUT", "log_time:=sent"], r"parameter 'log_time': must be one of"),
        (["output:=OUT", "qos_reliability:=x"], r"parameter 'qos_reliability': must be one"),
        (["output:=OUT", "topics:=['imu']"], r"parameter 'topics': 'imu': topic names must be"),
        (
            ["output:=OUT", "topics:=['/a=foo_msgs/msg/Nope']"],
            r"parameter 'topics': /a: message type foo_msgs/msg/Nope is not available",
        ),
        (["output:=OUT", "flush_period_s:=0"], r"parameter 'flush_period_s': must be > 0"),
        (["output:=OUT", "scenario:=/nonexistent.yaml"], r"scenario file not found"),
    ],
    ids=[
        "no-output", "exists", "storage", "log-time", "qos", "relative", "type", "flush",
        "scenario",
    ],  # fmt: skip
)
def test_invalid_parameters_exit_2(params, expected, ros_env, tmp_path):
    existing = tmp_path / "existing"
    existing.mkdir()
    (existing / "notes.txt").write_text("not a bag")
    params = [
        p.replace("EXISTING", str(existing)).replace("OUT", str(tmp_path / "out")) for p in params
    ]
    rc, output = nt.node_exit("bag_recorder", ros_env, *params)
    assert rc == 2, output
    assert re.search(expected, output), output
    assert not (tmp_path / "out").exists()


def test_topics_parameter_records_only_those(bag3, procs, ros_env, tmp_path):
    """An explicit topic list (type from the graph) and receive-time log times."""
    deadline = time.monotonic() + TIMEOUT_S
    out = tmp_path / "rec"
    args = nt.node_args("bag_recorder", f"output:={out}", "topics:=['/reference/imu']",
                        "stop_when_done:=true", "log_time:=receive")  # fmt: skip
    rec = nt.launch(procs, args, ros_env, tmp_path, "bag_recorder")
    rec.wait_for(r"recording 1 topic\(s\)", deadline)
    node = _trajectory(tmp_path, ros_env, 3.0, 0.0, params=["wait_for_all_topics:=false"])
    procs.append(node)
    assert node.wait(deadline) == 0, node.describe()
    assert rec.wait(deadline) == 0, rec.describe()
    got = read_bag(out, raw=True)
    assert list(got.topics) == ["/reference/imu"]
    imu = got.topics["/reference/imu"]
    assert imu.payloads == bag3.topics["/reference/imu"].payloads
    # log times are receive times (wall clock now), not the scenario's 2026 stamps
    assert abs(imu.log_time_ns[0] * 1e-9 - time.time()) < 120
    assert "600 logged at receive time" in rec.output, rec.describe()
