"""bag_player publishes a bag's messages over real DDS with the original timing.

A bag written by ``strapdown-sim generate`` is played by ``bag_player`` (its own process, this
session's ROS domain) to a raw subscriber process (test/ros_helpers/raw_recorder.py): every
payload arrives byte-identical (up to Fast DDS' 4-byte padding), in order, paced by the log
times (``rate_factor``, ``start_offset_s``), with topic selection, remapping, ``/clock`` and
``loop``; the player reports its pacing error (p50, p99, max). A missing directory, an
interrupted recording, a truncated data file, an unknown topic are refused (exit 2) with a
message saying why; an empty bag is reported (exit 0); data found corrupt midway stops the
player (exit 1). Every wait has a timeout; children still running at the end are killed.
"""

from __future__ import annotations

import pickle
import re
import signal
import struct
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")

import node_testing as nt  # noqa: E402

from strapdown_ros.bag.incremental import IncrementalBagWriter  # noqa: E402
from strapdown_ros.bag.playback import clock_payload  # noqa: E402
from strapdown_ros.bag.writer import BagWriter  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
# the reference stream alone (no TF, no map-frame odometry: docs/interface.md)
REFERENCE = [
    "variation=null", "navigator=null", "imu_errors=null", "aided=null", "aiding=null",
    "tf.enabled=false", "tf.map_odometry=false",
]  # fmt: skip
TYPES = {
    "/reference/imu": "sensor_msgs/msg/Imu",
    "/reference/odom": "nav_msgs/msg/Odometry",
    "/reference/fix": "sensor_msgs/msg/NavSatFix",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/played/imu": "sensor_msgs/msg/Imu",  # /reference/imu remapped
}
TIMEOUT_S = 60.0
PACING = re.compile(r"pacing error over (\d+) messages: p50 (\S+) ms, p99 (\S+) ms, max (\S+) ms")


def _generate(out: Path, *overrides: str, duration_s: float = 2.0):
    return nt.generated(SCENARIO, out, duration_s, [*REFERENCE, *overrides], timeout=120)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """Reference stream, 2 s at 200 Hz, no /clock in the bag."""
    return _generate(tmp_path_factory.mktemp("gen") / "bag")


def _play(procs, ros_env, tmp_path, counts: dict[str, int], *params: str):
    """Run raw_recorder on ``counts`` and the player; return the recording and the player."""
    deadline = time.monotonic() + TIMEOUT_S
    topics = [(topic, TYPES[topic], n) for topic, n in counts.items()]
    recorder, out = nt.raw_recorder(procs, ros_env, tmp_path, topics, TIMEOUT_S - 5, "raw_recorder")
    player = nt.launch(procs, nt.node_args("bag_player", "wait_for_subscribers:=1", *params),
                       ros_env, tmp_path, "bag_player")  # fmt: skip
    assert player.wait(deadline) == 0, player.describe() + recorder.describe()
    assert recorder.wait(deadline) == 0, recorder.describe() + player.describe()
    assert "Traceback" not in player.output, player.describe()
    with open(out, "rb") as f:
        return pickle.load(f), player


def _pacing(player: nt.Proc) -> tuple[int, float, float, float]:
    match = PACING.search(player.output)
    assert match, player.describe()
    n, p50, p99, worst = match.groups()
    return int(n), float(p50), float(p99), float(worst)


def test_plays_every_message_with_the_original_timing(bag, procs, ros_env, tmp_path):
    counts = {"/reference/imu": 400, "/reference/odom": 401, "/reference/fix": 401, "/clock": 401}
    recording, player = _play(procs, ros_env, tmp_path, counts, f"bag:={bag.path}")
    for topic in ("/reference/imu", "/reference/odom", "/reference/fix"):
        got = recording["topics"][topic]
        want = bag.topics[topic].payloads
        assert got == [nt.padded(p) for p in want], topic
    # /clock: the log time before the first message of each new log time
    stamps = np.unique(np.concatenate([d.log_time_ns for d in bag.topics.values()]))
    assert recording["topics"]["/clock"] == [clock_payload(t) for t in stamps.tolist()]
    # paced in real time: 400 IMU messages 5 ms apart span 1.995 s of wall time, not a burst
    # (how late it may be: a figure of bench/bench_node_timing.py and bench_player.py)
    arrival = np.asarray(recording["arrival"]["/reference/imu"])
    span = arrival[-1] - arrival[0]
    print(f"bag_player paced: 400 IMU messages span {span:.3f} s (ideal 1.995 s)")
    assert span > 1.9, span
    assert re.search(r"played 1202 messages in \d+\.\d+ s", player.output), player.describe()
    n, p50, p99, worst = _pacing(player)
    assert n == 1202 and 0 <= p50 <= p99 <= worst
    assert "/clock: 401 (clock)" in player.output and "/reference/fix: 401" in player.output


def test_topic_selection_remap_offset_and_rate(bag, procs, ros_env, tmp_path):
    """/reference/imu only, renamed, from 1 s on (stamps 1.000..2.000 s: 201 messages), twice
    as fast: 1 s of data in 0.5 s."""
    recording, player = _play(
        procs, ros_env, tmp_path, {"/played/imu": 201, "/clock": 201},
        f"bag:={bag.path}", "topics:=['/reference/imu']", "remap:=['/reference/imu:=/played/imu']",
        "start_offset_s:=1.0", "rate_factor:=2.0",
    )  # fmt: skip
    assert recording["topics"]["/played/imu"] == bag.topics["/reference/imu"].payloads[199:]
    arrival = np.asarray(recording["arrival"]["/played/imu"])
    assert 0.45 < arrival[-1] - arrival[0] < 0.8, arrival[-1] - arrival[0]
    assert "/reference/imu -> /played/imu" in player.output, player.describe()
    assert _pacing(player)[0] == 201


def test_bag_with_clock_plays_its_own(procs, ros_env, tmp_path):
    with_clock = _generate(tmp_path / "gen", "recording.clock=true", duration_s=1.0)
    recording, player = _play(
        procs, ros_env, tmp_path, {"/clock": 201, "/reference/imu": 200},
        f"bag:={with_clock.path}", "rate_factor:=0.0", "topics:=['/clock', '/reference/imu']",
    )  # fmt: skip
    assert recording["topics"]["/clock"] == with_clock.topics["/clock"].payloads
    assert "the bag has /clock: it is played as recorded" in player.output, player.describe()
    assert "rate_factor <= 0: not paced" in player.output, player.describe()


def test_loop_until_sigint(bag, procs, ros_env, tmp_path):
    deadline = time.monotonic() + TIMEOUT_S
    player = nt.launch(
        procs, nt.node_args("bag_player", f"bag:={bag.path}", "loop:=true", "rate_factor:=4.0",
                            "topics:=['/reference/imu']", "publish_clock:=false"),
        ros_env, tmp_path, "bag_player",
    )  # fmt: skip
    player.wait_for(r"loop True", deadline)
    time.sleep(2.0)  # a 2 s bag at 4x: a pass takes 0.5 s (after the reader's start-up)
    player.proc.send_signal(signal.SIGINT)
    assert player.wait(deadline) == 0, player.describe()
    match = re.search(r"played (\d+) messages in \S+ s, (\d+) loop\(s\) \(stopped: SIGINT\)",
                      player.output)  # fmt: skip
    assert match, player.describe()
    played, loops = int(match.group(1)), int(match.group(2))
    assert loops >= 1 and played > 400, player.describe()
    assert "Traceback" not in player.output


def test_realtime_priority(bag, ros_env):
    """SCHED_FIFO for the publishing thread when allowed; otherwise a warning, same result."""
    rc, out = _refused(
        ros_env, f"bag:={bag.path}", "rate_factor:=4.0", "realtime_priority:=10",
        "topics:=['/reference/imu']",
    )  # fmt: skip
    assert rc == 0, out
    assert re.search(r"publishing thread on SCHED_FIFO priority 10|cannot use SCHED_FIFO", out)
    assert "played 400 messages" in out and PACING.search(out), out


def _refused(ros_env, *params: str) -> tuple[int, str]:
    return nt.node_exit("bag_player", ros_env, *params)


def test_missing_bag_is_refused(ros_env, tmp_path):
    rc, out = _refused(ros_env, f"bag:={tmp_path / 'nothing'}")
    assert rc == 2, out
    assert re.search(r"parameter 'bag': bag directory \S+nothing does not exist", out), out
    rc, out = _refused(ros_env)
    assert rc == 2 and "parameter 'bag': is required" in out, out


def test_empty_bag_plays_nothing(ros_env, tmp_path):
    with BagWriter(tmp_path / "empty"):
        pass
    rc, out = _refused(ros_env, f"bag:={tmp_path / 'empty'}")
    assert rc == 0, out
    assert re.search(r"bag \S+empty has no messages: nothing to play", out), out
    assert "played" not in out
    # a topic without messages
    with BagWriter(tmp_path / "silent") as w:
        w.add_topic("/reference/imu", "sensor_msgs/msg/Imu")
    rc, out = _refused(ros_env, f"bag:={tmp_path / 'silent'}")
    assert rc == 0 and "has no messages: nothing to play" in out, out


def test_truncated_bag_is_refused(bag, ros_env, tmp_path):
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "metadata.yaml").write_bytes((bag.path / "metadata.yaml").read_bytes())
    data = (bag.path / "bag.mcap").read_bytes()
    (cut / "bag.mcap").write_bytes(data[: len(data) // 2])
    rc, out = _refused(ros_env, f"bag:={cut}")
    assert rc == 2, out
    assert re.search(r"bag\.mcap is truncated \(\d+ bytes, no MCAP end magic\)", out), out
    assert f"strapdown-sim bag repair {cut}" in out, out


def test_interrupted_recording_is_refused(bag, ros_env, tmp_path):
    """A recorder killed before closing: no metadata.yaml; then repaired, it plays."""
    rec = IncrementalBagWriter(tmp_path / "rec").open()
    imu = bag.topics["/reference/imu"]
    rec.add_topic("/reference/imu", imu.msgtype)
    for t, p in zip(imu.log_time_ns.tolist(), imu.payloads, strict=True):
        rec.write("/reference/imu", t, p)
    rec.flush()
    rec.abort()
    rc, out = _refused(ros_env, f"bag:={tmp_path / 'rec'}")
    assert rc == 2, out
    assert "has no metadata.yaml" in out and "strapdown-sim bag repair" in out, out
    subprocess.run(
        [nt.executable("strapdown-sim"), "bag", "repair", str(tmp_path / "rec")],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    rc, out = _refused(ros_env, f"bag:={tmp_path / 'rec'}", "rate_factor:=0.0")
    assert rc == 0 and "played 400 messages" in out, out


def test_corrupt_data_stops_the_player(bag, ros_env, tmp_path):
    """A message record inside a chunk claims more bytes than the chunk has: exit 1, no crash."""
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "metadata.yaml").write_bytes((bag.path / "metadata.yaml").read_bytes())
    data = bytearray((bag.path / "bag.mcap").read_bytes())
    pos = data.index(b"\x05", data.index(b"\x06", 8) + 60)  # a record in the first chunk
    while struct.unpack_from("<Q", data, pos + 1)[0] > 2000:  # find a message record start
        pos = data.index(b"\x05", pos + 1)
    struct.pack_into("<Q", data, pos + 1, 1 << 40)
    (bad / "bag.mcap").write_bytes(bytes(data))
    rc, out = _refused(ros_env, f"bag:={bad}", "rate_factor:=0.0")
    assert rc in (1, 2), out  # found when opening (2) or while playing (1)
    assert re.search(r"bag \S+bad|cannot open bag", out), out
    assert re.search(r"truncated or corrupt|became unreadable", out), out


@pytest.mark.parametrize(
    ("params", "expected"),
    [
        (["topics:=['/nope']"], r"has no topic\(s\) \['/nope'\]"),
        (["remap:=['/reference/imu']"], r"parameter 'remap': '/reference/imu': expected FROM:=TO"),
        (["remap:=['/nope:=/x']"], r"cannot remap \['/nope'\]"),
        (["start_offset_s:=5.0"], r"parameter 'start_offset_s': 5 s is beyond the bag's 2 s"),
        (["start_offset_s:=-1.0"], r"parameter 'start_offset_s': must be >= 0"),
        (["duration_s:=-1.0"], r"parameter 'duration_s': must be >= 0"),
        (["clock_rate_hz:=-5.0"], r"parameter 'clock_rate_hz': must be >= 0"),
        (["realtime_priority:=100"], r"parameter 'realtime_priority': must be 0 \(off\) or"),
    ],
    ids=["topic", "remap-syntax", "remap-topic", "offset", "negative-offset", "duration",
         "clock-rate", "rt"],
)
def test_invalid_parameters_exit_2(params, expected, bag, ros_env):
    rc, out = _refused(ros_env, f"bag:={bag.path}", *params)
    assert rc == 2, out
    assert re.search(expected, out), out


def test_window_and_clock_rate(bag, procs, ros_env, tmp_path):
    """From 0.5 s for 1 s (IMU stamps 0.500..1.500 s: 201 messages), /clock at 10 Hz of bag
    time: 11 ticks, each the log time of the first message of its 100 ms (0.5, 0.6 .. 1.5 s)."""
    recording, player = _play(
        procs, ros_env, tmp_path, {"/reference/imu": 201, "/clock": 11},
        f"bag:={bag.path}", "topics:=['/reference/imu']", "start_offset_s:=0.5",
        "duration_s:=1.0", "clock_rate_hz:=10.0", "rate_factor:=2.0",
    )  # fmt: skip
    assert recording["topics"]["/reference/imu"] == bag.topics["/reference/imu"].payloads[99:300]
    t0 = int(bag.topics["/reference/odom"].log_time_ns[0])
    ticks = [clock_payload(t0 + 500_000_000 + k * 100_000_000) for k in range(11)]
    assert recording["topics"]["/clock"] == ticks
    assert "/clock: 11 (clock)" in player.output, player.describe()


def test_pacing_warning_while_playing(bag, procs, ros_env, tmp_path):
    """A threshold no publication meets (1 µs): warnings while it plays, before the summary,
    at most one a second (2 s of data at 1x: a few, not one per message)."""
    _, player = _play(
        procs, ros_env, tmp_path, {"/reference/imu": 400},
        f"bag:={bag.path}", "topics:=['/reference/imu']", "pacing_warn_ms:=0.001",
    )  # fmt: skip
    out = player.output
    warnings = [m.start() for m in re.finditer(r"pacing: \d+ message\(s\) published more than "
                                               r"0\.001 ms late", out)]  # fmt: skip
    summary = out.index("played 400 messages")
    assert warnings and warnings[0] < summary, player.describe()
    assert len(warnings) <= 5, player.describe()
