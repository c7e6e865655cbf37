"""Interrupted recordings and ``strapdown-sim bag repair`` (no ROS graph needed).

A writer process (:class:`~strapdown_ros.bag.incremental.IncrementalBagWriter`) is SIGKILLed
after some flushes; the bag it leaves (no metadata.yaml, no MCAP summary/footer, or a hot SQLite
journal) is refused by the reader with a message naming ``bag repair``; ``strapdown-sim bag
repair`` makes it readable again (our reader and ``rosbags``' AnyReader) with every message up
to the last flush, byte for byte, in order. MCAP files cut at arbitrary bytes are repaired to
their complete records. Also: payload padding/stamps (:mod:`strapdown_ros.bag.payload`), the
scenario topic list (:mod:`strapdown_ros.topics`) against ``generate``'s bag, ``bag info``.
"""

from __future__ import annotations

import pickle
import re
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag.batches import Batch
from strapdown_ros.bag.incremental import IncrementalBagWriter
from strapdown_ros.bag.payload import PayloadInspector
from strapdown_ros.bag.reader import BagReadError, read_bag
from strapdown_ros.bag.repair import BagRepairError, bag_info, repair_bag
from strapdown_ros.bag.writer import DEFAULT_QOS, BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.topics import produced_topics

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
TS = get_typestore(Stores.ROS2_JAZZY)


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "strapdown_ros.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A generated bag (default scenario, 2 s, with /clock): the messages the tests write."""
    out = tmp_path_factory.mktemp("gen") / "bag"
    proc = _cli(
        "generate", str(SCENARIO), "--out", str(out), "--duration", "2",
        "--set", "recording.clock=true", "--quiet",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return read_bag(out, raw=True)


def _messages(contents) -> list[tuple[int, str, str, bytes]]:
    """(log time, topic, type, payload) of every message, in log-time order (stable)."""
    items = [
        (int(t), topic, d.msgtype, p)
        for topic, d in contents.topics.items()
        for t, p in zip(d.log_time_ns, d.payloads, strict=True)
    ]
    items.sort(key=lambda x: x[0])
    return items


_WRITER = textwrap.dedent(
    """
    import pickle, sys, time
    from strapdown_ros.bag.incremental import IncrementalBagWriter
    out, storage, src, flush_every, stop_after = sys.argv[1:6]
    items = pickle.load(open(src, "rb"))
    bag = IncrementalBagWriter(out, storage=storage).open()
    for i, (t, topic, msgtype, payload) in enumerate(items[: int(stop_after)], 1):
        bag.add_topic(topic, msgtype)
        bag.write(topic, t, payload)
        if i % int(flush_every) == 0:
            bag.flush()
            print("FLUSHED", i, flush=True)
    print("WAITING", flush=True)
    time.sleep(60)
    """
)


def _killed_recording(tmp_path: Path, source, storage: str, flush_every: int, stop: int) -> int:
    """Write ``stop`` messages with a flush every ``flush_every``, SIGKILL; returns the flushed."""
    items = _messages(source)
    src = tmp_path / "items.pkl"
    src.write_bytes(pickle.dumps(items))
    out = tmp_path / "rec"
    proc = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(out), storage, str(src), str(flush_every), str(stop)],
        stdout=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )
    flushed = 0
    try:
        for line in proc.stdout:  # type: ignore[union-attr]
            if line.startswith("FLUSHED"):
                flushed = int(line.split()[1])
            if line.startswith("WAITING"):
                break
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    return flushed


def _check_prefix(bag_dir: Path, source, at_least: int, at_most: int | None = None) -> int:
    """The bag holds, per topic, a prefix of the source's messages, in order; returns the total."""
    got = read_bag(bag_dir, raw=True)
    total = 0
    expected = _messages(source)
    for topic, data in got.topics.items():
        want = source.topics[topic]
        n = len(data.payloads)
        assert data.payloads == want.payloads[:n], topic
        assert data.log_time_ns.tolist() == want.log_time_ns[:n].tolist(), topic
        total += n
    # exactly the first `total` messages of the written sequence (nothing skipped)
    first = {}
    for _, topic, _, _ in expected[:total]:
        first[topic] = first.get(topic, 0) + 1
    assert {t: len(d.payloads) for t, d in got.topics.items() if len(d.payloads)} == first
    assert total >= at_least
    if at_most is not None:
        assert total <= at_most
    assert got.message_count == total
    with AnyReader([bag_dir]) as reader:
        n = 0
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            n += 1
        assert n == total
    return total


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_sigkilled_writer_is_repaired_up_to_the_last_flush(storage, source, tmp_path):
    flushed = _killed_recording(tmp_path, source, storage, flush_every=700, stop=2000)
    assert flushed == 1400
    bag = tmp_path / "rec"
    assert not (bag / "metadata.yaml").exists()
    with pytest.raises(BagReadError, match=r"no metadata\.yaml.*strapdown-sim bag repair"):
        read_bag(bag)
    if storage == "sqlite3":
        assert (bag / "rec.db3-journal").exists()  # the unfinished transaction
    proc = _cli("bag", "repair", str(bag))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"repaired {storage} bag, 1400 messages" in proc.stdout, proc.stdout
    # unflushed messages: in memory (mcap chunk) or rolled back (sqlite): exactly the flushed
    assert _check_prefix(bag, source, at_least=1400, at_most=1400) == 1400
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["message_count"] == 1400
    assert meta["storage_identifier"] == storage
    topic_meta = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    imu = topic_meta["/reference/imu"]["topic_metadata"]
    assert imu["type"] == "sensor_msgs/msg/Imu"
    assert imu["type_description_hash"] == TS.hash_rihs01("sensor_msgs/msg/Imu")
    assert imu["offered_qos_profiles"][0]["reliability"] == "reliable"
    # a second repair finds nothing to do and leaves the files alone
    data = sorted(bag.glob("rec.*"))[0]
    before = data.read_bytes()
    again = repair_bag(bag)
    assert not again.repaired and again.message_count == 1400
    assert data.read_bytes() == before


def test_incremental_writer_closed_bag_matches_source(source, tmp_path):
    """Closed normally: metadata as BagWriter writes it, all messages, DEFAULT_QOS stored."""
    items = _messages(source)
    out = tmp_path / "inc"
    bag = IncrementalBagWriter(out, custom_data={"k": "v"}).open()
    for i, (t, topic, msgtype, payload) in enumerate(items):
        bag.add_topic(topic, msgtype)
        bag.write(topic, t, payload)
        if i % 500 == 0:
            bag.flush()
    counts = bag.message_counts
    bag.close()
    got = read_bag(out, raw=True)
    assert got.custom_data == {"k": "v"}
    assert {t: len(d.payloads) for t, d in got.topics.items()} == counts
    for topic, data in got.topics.items():
        assert data.payloads == source.topics[topic].payloads
    with AnyReader([out]) as reader:
        assert all(c.ext.offered_qos_profiles == [DEFAULT_QOS] for c in reader.connections)


def test_mcap_cut_at_any_byte_is_repaired_to_its_complete_records(source, tmp_path):
    full = tmp_path / "full"
    items = _messages(source)
    bag = IncrementalBagWriter(full).open()
    for i, (t, topic, msgtype, payload) in enumerate(items, 1):
        bag.add_topic(topic, msgtype)
        bag.write(topic, t, payload)
        if i % 400 == 0:
            bag.flush()
    bag.close()
    data = (full / "full.mcap").read_bytes()
    rng = np.random.default_rng(7)
    cuts = [9, 40, 300, len(data) // 3, len(data) // 2, len(data) - 2000, len(data) - 30]
    cuts = sorted(cuts + rng.integers(100, len(data), size=5).tolist())
    totals = []
    for cut in cuts:
        bag_dir = tmp_path / f"cut{cut}"
        bag_dir.mkdir()
        (bag_dir / "full.mcap").write_bytes(data[:cut])
        report = repair_bag(bag_dir)
        total = _check_prefix(bag_dir, source, at_least=0)
        assert report.message_count == total
        totals.append(total)
    assert totals[:2] == [0, 0]  # cut inside the first chunk's schema records
    assert totals == sorted(totals) and totals[-1] == len(items)  # the last cut: summary only
    # a chunk cut short keeps its complete messages (uncompressed): a cut in the middle of the
    # file leaves more than the complete chunks before it (multiples of the 400-message flush)
    assert any(t % 400 for t in totals[2:-1]), totals


def test_repair_refuses_what_is_not_a_bag(tmp_path):
    with pytest.raises(BagRepairError, match="does not exist"):
        repair_bag(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagRepairError, match="no .mcap or .db3"):
        repair_bag(tmp_path / "empty")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(BagRepairError, match="not an MCAP file"):
        repair_bag(tmp_path / "junk")
    proc = _cli("bag", "repair", str(tmp_path / "missing"))
    assert proc.returncode == 1
    assert "does not exist" in proc.stderr and "Traceback" not in proc.stderr


def test_repair_of_an_empty_recording(tmp_path):
    """Killed before the first message: an empty bag with no topics."""
    bag = IncrementalBagWriter(tmp_path / "e").open()
    bag.abort()
    assert not (tmp_path / "e" / "metadata.yaml").exists()
    report = repair_bag(tmp_path / "e")
    assert report.message_count == 0 and report.topics == {}
    assert read_bag(tmp_path / "e").topics == {}


def test_bag_info(source, tmp_path):
    out = tmp_path / "b"
    d = source.topics["/reference/imu"]
    with BagWriter(out) as w:
        w.write_batches([Batch("/reference/imu", d.msgtype, d.log_time_ns, d.payloads)])
    text = bag_info(out)
    assert "storage:   mcap" in text and "messages:  400" in text
    assert re.search(r"/reference/imu +400  sensor_msgs/msg/Imu  \[reliable\]", text), text
    proc = _cli("bag", "info", str(out))
    assert proc.returncode == 0 and "duration:  1.995 s" in proc.stdout, proc.stdout
    (out / "metadata.yaml").unlink()
    proc = _cli("bag", "info", str(out))
    assert proc.returncode == 1 and "bag repair" in proc.stderr, proc.stderr


# ---------------------------------------------------------------------------------------------
# payloads


def test_padding_is_stripped_to_the_true_cdr_length(source):
    fix = PayloadInspector("sensor_msgs/msg/NavSatFix")
    assert fix.may_be_padded and fix.has_stamp
    for p in source.topics["/reference/fix"].payloads[:50]:
        assert len(p) == 133
        padded = p + b"\x00" * 3
        assert fix.strip(padded) == p
        assert fix.strip(p) is p
    for msgtype in ("sensor_msgs/msg/Imu", "nav_msgs/msg/Odometry", "rosgraph_msgs/msg/Clock"):
        assert not PayloadInspector(msgtype).may_be_padded, msgtype
    imu = PayloadInspector("sensor_msgs/msg/Imu")
    d = source.topics["/reference/imu"]
    assert [imu.stamp_ns(p) for p in d.payloads] == d.log_time_ns.tolist()
    clock = PayloadInspector("rosgraph_msgs/msg/Clock")
    c = source.topics["/clock"]
    assert [clock.stamp_ns(p) for p in c.payloads] == c.log_time_ns.tolist()


@pytest.mark.parametrize("n", range(9))
def test_true_length_of_generic_types(n):
    """Strings, sequences, nested messages: any length mod 4, padded or not."""
    T = TS.types
    layout = T["std_msgs/msg/MultiArrayLayout"](
        dim=[T["std_msgs/msg/MultiArrayDimension"](label="x" * n, size=n, stride=1)] * (n % 3),
        data_offset=n,
    )
    msgs = {
        "std_msgs/msg/String": T["std_msgs/msg/String"](data="é" * n),
        "std_msgs/msg/UInt8MultiArray": T["std_msgs/msg/UInt8MultiArray"](
            layout=layout, data=np.arange(n, dtype=np.uint8)
        ),
        "std_msgs/msg/Int16MultiArray": T["std_msgs/msg/Int16MultiArray"](
            layout=layout, data=np.arange(n, dtype=np.int16)
        ),
        "diagnostic_msgs/msg/KeyValue": T["diagnostic_msgs/msg/KeyValue"](key="k" * n, value="v"),
    }
    for msgtype, msg in msgs.items():
        raw = bytes(TS.serialize_cdr(msg, msgtype))
        ins = PayloadInspector(msgtype)
        assert ins.true_length(raw) == len(raw), msgtype
        assert ins.strip(raw + bytes(-len(raw) % 4)) == raw, msgtype
        assert ins.stamp_ns(raw) is None


def test_log_message_stamp():
    T = TS.types
    msg = T["rcl_interfaces/msg/Log"](
        stamp=T["builtin_interfaces/msg/Time"](sec=12, nanosec=34), level=20, name="n",
        msg="m", file="f", function="g", line=1,
    )  # fmt: skip
    raw = bytes(TS.serialize_cdr(msg, "rcl_interfaces/msg/Log"))
    assert PayloadInspector("rcl_interfaces/msg/Log").stamp_ns(raw) == 12_000_000_034


# ---------------------------------------------------------------------------------------------
# topic list


@pytest.mark.parametrize(
    "overrides",
    [
        [],
        ["navigator=null"],
        ["navigator=null", "imu_errors=null", "variation=null", "recording.clock=true"],
        ["navigator=null", "imu_errors.output_topic=/measured/imu"],
    ],
    ids=["default", "no-navigator", "reference-with-clock", "measured-renamed"],
)
def test_produced_topics_are_what_generate_writes(overrides, tmp_path):
    out = tmp_path / "bag"
    args = ["generate", str(SCENARIO), "--out", str(out), "--duration", "1", "--quiet"]
    for o in overrides:
        args += ["--set", o]
    proc = _cli(*args)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    written = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type"]
        for t in meta["topics_with_message_count"]
    }
    assert produced_topics(load_scenario(SCENARIO, overrides)) == written
