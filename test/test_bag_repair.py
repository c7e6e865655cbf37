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
import struct
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.records import Message, MessageIndex
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag.batches import Batch
from strapdown_ros.bag.incremental import IncrementalBagWriter
from strapdown_ros.bag.payload import PayloadInspector
from strapdown_ros.bag.reader import BagReadError, bag_info, read_bag
from strapdown_ros.bag.repair import BagRepairError, repair_bag
from strapdown_ros.bag.writer import DEFAULT_QOS, BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.plan import resolve_plan

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


@pytest.mark.slow
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_sigkilled_writer_is_repaired_up_to_the_last_flush(storage, source, tmp_path):
    flushed = _killed_recording(tmp_path, source, storage, flush_every=700, stop=2000)
    assert flushed == 1400
    bag = tmp_path / "rec"
    assert not (bag / "metadata.yaml").exists()
    with pytest.raises(BagReadError, match=r"no metadata\.yaml.*strapdown-sim bag repair"):
        read_bag(bag)
    text = _info(bag)
    assert re.search(r"status: .*has no metadata\.yaml.*strapdown-sim bag repair", text), text
    if storage == "sqlite3":
        assert (bag / "rec.db3-journal").exists()  # the unfinished transaction
        assert "rollback journal" in text, text
    else:  # the 600 unflushed messages were in the writer's memory
        assert re.search(r"the data files hold:(.|\n)*messages: +1400\n", text), text
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_mcap_cut_at_any_byte_is_repaired_to_its_complete_records(source, recorded, tmp_path):
    """Random cuts too: each repaired bag is a prefix, in order, byte for byte (our reader and
    rosbags' AnyReader), of exactly the message records complete before the cut."""
    full, recs, _ = recorded
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
        assert report.message_count == total == sum(r.end <= cut for r in recs), cut
        totals.append(total)
    assert totals[:2] == [0, 0]  # cut inside the first chunk's schema records
    assert totals == sorted(totals) and totals[-1] == len(recs)  # the last cut: summary only
    # a chunk cut short keeps its complete messages (uncompressed): a cut in the middle of the
    # file leaves more than the complete chunks before it (multiples of the 400-message flush)
    assert any(t % 400 for t in totals[2:-1]), totals


# ---------------------------------------------------------------------------------------------
# MCAP files cut at chosen bytes, checked against the complete file's own indexes


@dataclass(frozen=True)
class _Rec:
    """A message record of the complete file."""

    end: int  #: file offset just after the record
    topic: str
    log_time: int
    data: bytes


@pytest.fixture(scope="module")
def recorded(source, tmp_path_factory):
    """The source's messages written by IncrementalBagWriter with generate's custom_data (a
    flush, i.e. a chunk, every 400 messages), closed normally; its message records located
    through the file's chunk and message indexes (mcap library, not a scan); its chunk
    indexes."""
    out = tmp_path_factory.mktemp("rec") / "full"
    assert source.custom_data.get("scenario") == "default"  # what generate stores
    bag = IncrementalBagWriter(out, custom_data=source.custom_data).open()
    for i, (t, topic, msgtype, payload) in enumerate(_messages(source), 1):
        bag.add_topic(topic, msgtype)
        bag.write(topic, t, payload)
        if i % 400 == 0:
            bag.flush()
    bag.close()
    recs: list[_Rec] = []
    with (out / "full.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
        for ci in summary.chunk_indexes:
            assert ci.compression == ""
            fh.seek(ci.chunk_start_offset)
            chunk = next(StreamReader(fh, skip_magic=True, emit_chunks=True).records)
            records_start = ci.chunk_start_offset + 9 + 8 + 8 + 8 + 4 + 4 + 8  # + compression ""
            for cid, offset in ci.message_index_offsets.items():
                fh.seek(offset)
                index = next(StreamReader(fh, skip_magic=True).records)
                assert isinstance(index, MessageIndex) and index.channel_id == cid
                for log_time, o in index.records:
                    (length,) = struct.unpack_from("<Q", chunk.data, o + 1)
                    payload = chunk.data[o + 9 + 22 : o + 9 + length]
                    end = records_start + o + 9 + length
                    recs.append(_Rec(end, summary.channels[cid].topic, log_time, payload))
    recs.sort(key=lambda r: r.end)
    assert [(r.topic, r.log_time, r.data) for r in recs] == [
        (topic, t, p) for t, topic, _, p in _messages(source)
    ]
    return out, recs, summary.chunk_indexes


def _chosen_cuts(recs: list[_Rec], chunks, size: int) -> dict[str, int]:
    second = chunks[1]
    return {
        "in-header": 9,
        "in-first-message": recs[0].end - 1,
        "after-first-message": recs[0].end,  # mid-chunk, at a record boundary
        "mid-chunk-in-record": recs[555].end - 7,
        "mid-chunk-after-record": recs[1234].end,
        "in-chunk-fields": second.chunk_start_offset + 20,
        "in-message-index": second.chunk_start_offset + second.chunk_length + 5,
        "after-last-message": recs[-1].end,
        "in-summary": size - 60,
        "in-end-magic": size - 3,
    }


def _mcap_view(f: Path):
    """Schemas, channels, messages and metadata of an MCAP file through its summary."""
    with f.open("rb") as fh:
        reader = make_reader(fh, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        msgs = [
            (ch.topic, m.log_time, m.data)
            for _, ch, m in reader.iter_messages(log_time_order=False)
        ]
        metadata = list(reader.iter_metadata())
    with f.open("rb") as fh:  # every record, chunk CRCs checked, up to the footer and magic
        kinds = {type(r).__name__ for r in StreamReader(fh, validate_crcs=True).records}
    assert {"Header", "DataEnd", "Footer"} <= kinds
    return summary, msgs, metadata


@pytest.mark.parametrize(
    "with_metadata",
    [False, pytest.param(True, marks=pytest.mark.slow)],  # ~7 s: every cut again, metadata kept
    ids=["killed", "metadata-kept"],
)
def test_mcap_cut_at_chosen_bytes(recorded, with_metadata, tmp_path):
    """Every message complete before the cut is back with identical payload bytes, in order,
    in a valid MCAP file (summary, statistics, indexes, CRCs) with the original schemas and
    channels; custom_data is kept from metadata.yaml or the 'rosbag2' record when there is one,
    and the file's 'rosbag2' record is the repaired bag's metadata."""
    full, recs, chunks = recorded
    data = (full / "full.mcap").read_bytes()
    full_summary, _, full_meta = _mcap_view(full / "full.mcap")
    original = yaml.safe_load((full / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (rosbag2_index,) = full_summary.metadata_indexes  # where rosbags put the 'rosbag2' record
    rosbag2_record_end = rosbag2_index.offset + rosbag2_index.length
    for name, cut in _chosen_cuts(recs, chunks, len(data)).items():
        bag = tmp_path / name
        bag.mkdir()
        (bag / "full.mcap").write_bytes(data[:cut])
        if with_metadata:
            (bag / "metadata.yaml").write_bytes((full / "metadata.yaml").read_bytes())
        expected = [(r.topic, r.log_time, r.data) for r in recs if r.end <= cut]
        report = repair_bag(bag)
        assert report.repaired and report.message_count == len(expected), name
        summary, msgs, metadata = _mcap_view(bag / "full.mcap")
        assert msgs == expected, name
        stats = summary.statistics
        assert stats.message_count == len(expected) and stats.chunk_count == len(
            summary.chunk_indexes
        )
        assert (stats.message_start_time, stats.message_end_time) == (
            (min(m[1] for m in expected), max(m[1] for m in expected)) if expected else (0, 0)
        )
        for cid, ch in summary.channels.items():  # as the recorder wrote them
            (orig,) = [c for c in full_summary.channels.values() if c.topic == ch.topic]
            assert (ch.message_encoding, ch.metadata) == (orig.message_encoding, orig.metadata)
            s, o = summary.schemas[ch.schema_id], full_summary.schemas[orig.schema_id]
            assert (s.name, s.encoding, s.data) == (o.name, o.encoding, o.data)
            n = sum(1 for m in expected if m[0] == ch.topic)
            assert stats.channel_message_counts.get(cid, 0) == n
        assert {m[0] for m in expected} <= {c.topic for c in summary.channels.values()}
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        assert meta["message_count"] == len(expected)
        # custom_data: from metadata.yaml, or from the rosbag2 record the writer left at close
        custom = dict(meta["custom_data"])
        assert custom.pop("repaired_by") == "strapdown-sim bag repair"
        kept = with_metadata or cut >= rosbag2_record_end
        assert custom == (original["custom_data"] if kept else {}), name
        # the rosbag2 record: one, holding the repaired bag's metadata
        (record,) = [m for m in metadata if m.name == "rosbag2"]
        assert yaml.safe_load(record.metadata["serialized_metadata"]) == meta
        assert len(full_meta) == 1 and full_meta[0].name == "rosbag2"
        assert read_bag(bag).message_count == len(expected)


@pytest.mark.parametrize("length", ["huge", "below-header", "beyond-chunk"])
def test_corrupt_record_in_a_complete_chunk(recorded, length, tmp_path):
    """A message record whose length field is corrupt (beyond the file, below the 22-byte
    message header, beyond its chunk): the messages before it in its chunk and every other
    chunk are kept, the rest of that chunk is dropped with a note — never a garbage message.
    (A corrupt length that stays inside its chunk cannot be told from a real one: rosbags
    writes no chunk CRC.)"""
    full, recs, chunks = recorded
    data = bytearray((full / "full.mcap").read_bytes())
    bad = 500  # the 101st message of the second chunk (a flush every 400 messages)
    start = recs[bad].end - (9 + 22 + len(recs[bad].data))
    assert data[start] == 0x05
    chunk_end = chunks[1].chunk_start_offset + chunks[1].chunk_length
    assert recs[799].end <= chunk_end < recs[800].end
    value = {"huge": 1 << 40, "below-header": 5, "beyond-chunk": chunk_end - start + 40}[length]
    struct.pack_into("<Q", data, start + 1, value)
    bag = tmp_path / "bad"
    bag.mkdir()
    (bag / "full.mcap").write_bytes(bytes(data))
    report = repair_bag(bag)
    assert any("corrupt record" in n for n in report.notes), report.notes
    expected = [(r.topic, r.log_time, r.data) for i, r in enumerate(recs) if not 500 <= i < 800]
    _, msgs, _ = _mcap_view(bag / "full.mcap")
    assert msgs == expected
    assert report.message_count == len(expected)


def test_repaired_bag_decodes_with_mcap_ros2(recorded, tmp_path):
    """Independent check: mcap_ros2's decoder (from the schemas in the file) reads every
    message of a bag repaired from a cut in the middle of a chunk as rosbags does."""
    full, recs, _ = recorded
    cut = recs[2345].end + 11
    bag = tmp_path / "cut"
    bag.mkdir()
    (bag / "rec.mcap").write_bytes((full / "full.mcap").read_bytes()[:cut])
    assert repair_bag(bag).message_count == 2346
    types = {t: d.msgtype for t, d in read_bag(bag).topics.items()}
    n = 0
    with (bag / "rec.mcap").open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert schema.name == types[channel.topic]
            ours = TS.deserialize_cdr(message.data, schema.name)
            if channel.topic == "/clock":
                got, want = decoded.clock, ours.clock
            elif schema.name == "tf2_msgs/msg/TFMessage":  # stamped by its first transform
                got, want = decoded.transforms[0].header.stamp, ours.transforms[0].header.stamp
                assert [t.child_frame_id for t in decoded.transforms] == [
                    t.child_frame_id for t in ours.transforms
                ]
            else:
                got, want = decoded.header.stamp, ours.header.stamp
                assert decoded.header.frame_id == ours.header.frame_id
            assert (got.sec, got.nanosec) == (want.sec, want.nanosec)
            assert got.sec * 1_000_000_000 + got.nanosec == message.log_time  # stamp = log time
            if schema.name == "sensor_msgs/msg/Imu":
                w, v = decoded.angular_velocity, ours.angular_velocity
                assert (w.x, w.y, w.z) == (v.x, v.y, v.z)
            assert (message.data, message.log_time) == (recs[n].data, recs[n].log_time)
            n += 1
    assert n == 2346


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_custom_data_and_forced_repair_of_a_closed_bag(source, storage, tmp_path):
    """A closed bag that lost its metadata.yaml gets generate's custom_data back from inside the
    data file (mcap: the 'rosbag2' metadata record; sqlite3: the metadata table); ``force``
    rebuilds a complete bag keeping every message and custom_data."""
    out = tmp_path / "b"
    d = source.topics["/reference/odom"]
    with BagWriter(out, storage=storage, custom_data=source.custom_data) as w:
        w.write_batches([Batch("/reference/odom", d.msgtype, d.log_time_ns, d.payloads)])
    want = {**source.custom_data, "repaired_by": "strapdown-sim bag repair"}
    (out / "metadata.yaml").unlink()
    report = repair_bag(out)
    assert report.custom_data == want and report.message_count == len(d)
    assert not any("no custom_data" in n for n in report.notes)
    got = read_bag(out, raw=True)
    assert got.custom_data == want
    assert got.topics["/reference/odom"].payloads == d.payloads
    assert not repair_bag(out).repaired  # complete now
    forced = repair_bag(out, force=True)
    assert forced.repaired and forced.message_count == len(d)
    got = read_bag(out, raw=True)
    assert got.custom_data == want
    assert got.topics["/reference/odom"].payloads == d.payloads


def _foreign_mcap(f: Path, source, compression) -> list[bytes]:
    """An MCAP file written by the mcap library (its own profile, ROS 2 schema and CDR
    payloads, no rosbag2 channel metadata), and no metadata.yaml."""
    d = source.topics["/reference/imu"]
    msgdef, _ = TS.generate_msgdef("sensor_msgs/msg/Imu", ros_version=2)
    with f.open("wb") as fh:
        w = McapWriter(fh, chunk_size=30_000, compression=compression)
        w.start()
        sid = w.register_schema("sensor_msgs/msg/Imu", "ros2msg", msgdef.encode())
        cid = w.register_channel("/imu", "cdr", sid)
        for i, (t, p) in enumerate(zip(d.log_time_ns.tolist(), d.payloads, strict=True)):
            w.add_message(cid, t, p, t, i)
        w.finish()
    return d.payloads


@pytest.mark.slow
def test_foreign_mcap_is_described_and_repaired(source, tmp_path):
    bag = tmp_path / "foreign"
    bag.mkdir()
    payloads = _foreign_mcap(bag / "foreign.mcap", source, CompressionType.ZSTD)
    data = (bag / "foreign.mcap").read_bytes()
    proc = _cli("bag", "info", str(bag))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert "has no metadata.yaml" in proc.stdout and "bag repair" in proc.stdout, proc.stdout
    assert "mcap-python" in proc.stdout and "complete, with summary" in proc.stdout
    assert re.search(r"/imu +400  sensor_msgs/msg/Imu", proc.stdout), proc.stdout
    # cut in a chunk: that compressed chunk is lost (noted), the ones before it are kept
    with (bag / "foreign.mcap").open("rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) >= 3
    k = len(chunks) // 2
    complete = chunks[:k]
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "foreign.mcap").write_bytes(
        data[: chunks[k].chunk_start_offset + chunks[k].chunk_length // 2]
    )
    with (bag / "foreign.mcap").open("rb") as fh:
        n = 0
        for c in complete:
            fh.seek(c.chunk_start_offset)
            chunk = next(StreamReader(fh, skip_magic=True, emit_chunks=True).records)
            n += sum(isinstance(r, Message) for r in breakup_chunk(chunk))
    proc = _cli("bag", "info", str(cut))
    assert proc.returncode == 0 and "cut short" in proc.stdout, proc.stdout + proc.stderr
    report = repair_bag(cut)
    assert report.message_count == n and report.salvaged == 0
    assert any("zstd-compressed" in note for note in report.notes), report.notes
    assert read_bag(cut, raw=True).topics["/imu"].payloads == payloads[:n]
    # the complete file: every message, readable by our reader, rosbags and mcap_ros2
    report = repair_bag(bag)
    assert report.message_count == 400 and any("profile ''" in n for n in report.notes)
    got = read_bag(bag, raw=True)
    assert got.topics["/imu"].payloads == payloads
    with AnyReader([bag]) as reader:
        assert sum(1 for _ in reader.messages()) == 400
    with (bag / "foreign.mcap").open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        stamps = [
            dec.header.stamp.sec * 10**9 + dec.header.stamp.nanosec
            for _, _, _, dec in reader.iter_decoded_messages()
        ]
    assert stamps == source.topics["/reference/imu"].log_time_ns.tolist()


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


def _info(path: Path) -> str:
    """``strapdown-sim bag info``: exit 0, no traceback; and the same text as bag_info."""
    proc = _cli("bag", "info", str(path))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    # bag_info's description, then what the commands can do with the bag
    assert proc.stdout.strip().startswith(bag_info(path)), proc.stdout
    return proc.stdout


@pytest.mark.slow
def test_bag_info(source, recorded, tmp_path):
    out = tmp_path / "b"
    d = source.topics["/reference/imu"]
    with BagWriter(out, custom_data=source.custom_data) as w:
        w.write_batches([Batch("/reference/imu", d.msgtype, d.log_time_ns, d.payloads)])
    text = _info(out)
    assert "status:    complete: metadata.yaml and data files check" in text
    assert "storage:   mcap" in text and "messages:  400" in text
    assert "duration:  1.995 s" in text and "scenario=default" in text
    assert re.search(r"/reference/imu +400  sensor_msgs/msg/Imu  \[reliable\]", text), text
    # an interrupted recording (no metadata.yaml): the reason, and what the data file holds
    (out / "metadata.yaml").unlink()
    text = _info(out)
    assert re.search(r"status: .*has no metadata\.yaml.*strapdown-sim bag repair", text), text
    assert "metadata.yaml: none" in text and re.search(r"messages: +400\n", text), text
    # repaired
    repair_bag(out)
    text = _info(out)
    assert "status:    complete: metadata.yaml and data files check" in text
    assert "repaired_by=strapdown-sim bag repair" in text
    assert "scenario=default" in text  # from the file's rosbag2 record
    # truncated in the middle of a chunk, metadata.yaml still there
    full, recs, _ = recorded
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "metadata.yaml").write_bytes((full / "metadata.yaml").read_bytes())
    size = recs[1000].end + 5
    (cut / "full.mcap").write_bytes((full / "full.mcap").read_bytes()[:size])
    text = _info(cut)
    assert re.search(r"status: .*full\.mcap is truncated.*bag repair", text), text
    assert f"messages:  {len(recs)}" in text  # what metadata.yaml says
    assert "cut short" in text and "complete messages in a chunk cut short" in text, text
    assert re.search(rf"the data files hold:(.|\n)*messages: +{1001}\n", text), text
    # an empty directory, a directory of something else, a missing one
    (tmp_path / "empty").mkdir()
    assert "status:    not a bag: an empty directory" in _info(tmp_path / "empty")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("x")
    assert "status:    not a bag: a directory without" in _info(tmp_path / "other")
    proc = _cli("bag", "info", str(tmp_path / "missing"))
    assert proc.returncode == 1 and "does not exist" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    with pytest.raises(BagReadError, match="does not exist"):
        bag_info(tmp_path / "missing")


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


@pytest.mark.slow
@pytest.mark.parametrize(
    "overrides",
    [
        [],
        ["navigator=null"],
        ["navigator=null", "imu_errors=null", "aided=null", "variation=null",
         "recording.clock=true"],
        ["navigator=null", "imu_errors.0.output_topic=/measured/imu"],
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
    assert resolve_plan(load_scenario(SCENARIO, overrides)).topic_types() == written
