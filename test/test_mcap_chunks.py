"""The recorder's bulk MCAP chunk writer (bag/mcap_chunks.py) against rosbags' per-message one.

The same messages written both ways, with flushes at odd places, topics added mid-stream and
chunks past 1 MiB, must give the same file byte for byte (the bag's own name aside); the bulk
file must read back with rosbags and with the mcap library (CRCs checked, every message decoded
by mcap_ros2 from the schemas in the file) and pass the package's checker.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag.incremental import IncrementalBagWriter

TS = get_typestore(Stores.ROS2_JAZZY)
Time = TS.types["builtin_interfaces/msg/Time"]
Header = TS.types["std_msgs/msg/Header"]
Vector3 = TS.types["geometry_msgs/msg/Vector3"]
Vector3Stamped = TS.types["geometry_msgs/msg/Vector3Stamped"]
NavSatFix = TS.types["sensor_msgs/msg/NavSatFix"]
NavSatStatus = TS.types["sensor_msgs/msg/NavSatStatus"]


def _messages(n: int) -> list[tuple[str, str, int, bytes]]:
    """``(topic, type, stamp_ns, payload)``: three topics, the third starting late, payloads of
    several sizes (frame ids of varying length)."""
    rng = np.random.default_rng(4)
    out = []
    for k in range(n):
        stamp = 1_767_225_600_000_000_000 + k * 5_000_000
        header = Header(Time(stamp // 10**9, stamp % 10**9), "f" * int(rng.integers(1, 600)))
        vec = Vector3Stamped(header, Vector3(*rng.normal(size=3)))
        out.append(("/a", "geometry_msgs/msg/Vector3Stamped", stamp,
                    bytes(TS.serialize_cdr(vec, vec.__msgtype__))))  # fmt: skip
        if k % 3 == 0:
            fix = NavSatFix(header, NavSatStatus(0, 1), *rng.normal(size=3),
                            rng.normal(size=9), 2)  # fmt: skip
            data = bytes(TS.serialize_cdr(fix, fix.__msgtype__))
            out.append(("/fix", fix.__msgtype__, stamp, data))
        if k > n // 2 and k % 7 == 0:  # a topic whose first message comes mid-stream
            out.append(("/late", vec.__msgtype__, stamp + 1,
                        bytes(TS.serialize_cdr(vec, vec.__msgtype__))))  # fmt: skip
    return out


def _write(path: Path, messages, bulk: bool, flush_at: set[int], compression: str) -> Path:
    bag = IncrementalBagWriter(path, bulk=bulk, compression=compression).open()
    sinks = {}
    for k, (topic, msgtype, stamp, payload) in enumerate(messages):
        if topic not in sinks:
            sinks[topic] = bag.sink(bag.add_topic(topic, msgtype))
        sinks[topic](stamp, payload)
        if k in flush_at:
            bag.flush()
    bag.close()
    return path


@pytest.mark.parametrize("compression", ["none", "zstd"])
def test_bulk_chunks_write_the_per_message_file(tmp_path, compression):
    messages = _messages(6000)  # ~1.9 MB: chunks closed at 1 MiB between the flushes too
    flush_at = {0, 1, 2, 500, 501, 4000, len(messages) - 1}
    a = _write(tmp_path / "a", messages, False, flush_at, compression)
    b = _write(tmp_path / "b", messages, True, flush_at, compression)
    fa, fb = (a / "a.mcap").read_bytes(), (b / "b.mcap").read_bytes()
    assert fb.count(b"b.mcap") == fa.count(b"a.mcap") > 0  # the metadata names the file
    assert fb.replace(b"b.mcap", b"a.mcap") == fa
    assert (b / "metadata.yaml").read_text().replace("b.mcap", "a.mcap") == (
        a / "metadata.yaml"
    ).read_text()
    with open(b / "b.mcap", "rb") as fh:
        assert len(make_reader(fh).get_summary().chunk_indexes) > len(flush_at) - 2


def test_bulk_chunks_read_back_with_mcap_and_rosbags(tmp_path):
    messages = _messages(3000)
    bag = _write(tmp_path / "b", messages, True, {10, 2000}, "none")
    expected = sorted((m[2], m[0], m[3]) for m in messages)
    with open(bag / "b.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()], validate_crcs=True)
        got = []
        for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            stamp = decoded.header.stamp.sec * 10**9 + decoded.header.stamp.nanosec
            assert message.log_time in (stamp, stamp + 1)
            got.append((message.log_time, channel.topic, message.data))
    assert sorted(got) == expected
    with Reader(bag) as reader:
        assert reader.message_count == len(messages)
        got = sorted((t, c.topic, bytes(raw)) for c, t, raw in reader.messages())
    assert got == expected


def test_queue_limit_frames_without_a_flush(tmp_path, monkeypatch):
    import strapdown_ros.bag.incremental as incremental

    monkeypatch.setattr(incremental, "QUEUE_LIMIT", 100)
    messages = _messages(1000)
    a = _write(tmp_path / "a", messages, False, set(), "none")
    b = _write(tmp_path / "b", messages, True, set(), "none")
    assert (b / "b.mcap").read_bytes().replace(b"b.mcap", b"a.mcap") == (a / "a.mcap").read_bytes()
