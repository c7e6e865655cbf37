"""What a bag gets: topic selection, MCAP chunk compression and the sensors' TF frames.

One small scenario (2 s at 100 Hz, a static variation, a navigator, four aiding sensors with
lever arms) is generated in full, then again through the command line's options with a topic
selection and each chunk compression. Read back from disk:

* the selected bag holds exactly the selected topics, with the payloads and log times of the
  full bag (the excluded topics were still computed where a stage needs them: the navigator's
  output depends on the variation streams it reads);
* zstd and lz4 bags carry the same messages as the uncompressed one, read by the project's
  reader, by rosbags and by the ``mcap`` library, whose chunk index says the compression;
* ``/tf_static`` has ``base_link → <frame>`` for each aiding sensor, the frame id its messages
  carry and the translation its lever arm converted to FLU by hand here (x, −y, −z), and the
  GNSS antenna position of the fix equals the reference pose composed with that transform.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag.incremental import IncrementalBagWriter
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.selection import SelectionError, TopicSelection
from strapdown_ros.bag.writer import BagWriteError, BagWriter
from strapdown_ros.cli import _recording_overrides, build_parser
from strapdown_ros.config import ScenarioError, load_scenario, parse_scenario
from strapdown_ros.generate import generate_dataset

TS = get_typestore(Stores.ROS2_JAZZY)
WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563

#: lever arms, body FRD (m), from the reference IMU
GNSS_LEVER = [1.0, -0.4, -1.2]
BARO_LEVER = [2.0, 0.5, 0.3]
WHEEL_LEVER = [0.0, -0.8, 0.45]

SCENARIO = {
    "name": "selection",
    "rate_hz": 100,
    "start_time_s": 1767225600.0,
    "initial": {
        "latitude_deg": 45.0, "longitude_deg": 7.5, "altitude_m": 300.0,
        "velocity_ned_mps": [10.0, 5.0, 0.0], "attitude_rph_deg": [2.0, 1.0, 30.0],
    },
    "trajectory": {"kind": "segments", "segments": [
        {"duration_s": 2.0, "heading_rate_dps": 10.0, "roll_rate_dps": 2.0},
    ]},
    "variation": {"method": 2, "lever_arm_m": [0.3, 0.1, -0.2]},
    "navigator": {"mode": "exact", "n": 2, "imu_topic": "/variation/imu",
                  "truth_topic": "/variation/odom"},
    "aiding": {
        "gnss": {"rate_hz": 10, "lever_arm_m": GNSS_LEVER, "seed": 1},  # no preset: no errors
        "barometer": {"rate_hz": 10, "lever_arm_m": BARO_LEVER, "preset": "mems", "seed": 2},
        "magnetometer": {"rate_hz": 10, "frame_id": "mag", "seed": 3},
        "wheel_odometer": {"rate_hz": 10, "lever_arm_m": WHEEL_LEVER, "frame_id": "wheel_rl",
                           "preset": "encoder", "seed": 4},
    },
}  # fmt: skip

SELECT = ["--topics", "/tf_static", "/gnss/fix", "/reference/odom", "--regex", "/navigator/.*",
          "--exclude-regex", ".*_map", "--exclude-topics", "/navigator/fix"]  # fmt: skip
SELECTED = {"/tf_static", "/gnss/fix", "/reference/odom", "/navigator/odom",
            "/navigator/error/position", "/navigator/error/velocity",
            "/navigator/error/attitude"}  # fmt: skip


def _generate(path: Path, out: Path, *options: str):
    """``strapdown-sim generate`` in-process: the command line's options, then the writer."""
    args = build_parser().parse_args(["generate", str(path), "--out", str(out), *options])
    scenario = load_scenario(args.scenario, [*args.overrides, *_recording_overrides(args)])
    return generate_dataset(scenario, out)


def _messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """(log time, payload) per topic, read with rosbags."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, bytes(raw)))
    return out


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("selection")
    path = tmp / "selection.yaml"
    path.write_text(yaml.safe_dump(SCENARIO))
    out = {"yaml": path}
    for name, options in (("full", []), ("selected", SELECT), ("zstd", ["--compression", "zstd"]),
                          ("lz4", ["--compression", "lz4"])):  # fmt: skip
        out[name] = tmp / name
        _generate(path, out[name], *options)
    return out


@pytest.mark.slow
def test_the_selected_bag_holds_only_the_selected_topics_unchanged(bags):
    full, selected = _messages(bags["full"]), _messages(bags["selected"])
    assert set(selected) == SELECTED
    for topic in SELECTED:  # same bytes, same log times as the full bag
        assert selected[topic] == full[topic], topic
    assert len(full) > len(SELECTED) + 10  # the scenario makes many more


@pytest.mark.slow
@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_compressed_bags_read_back_by_three_readers(bags, compression):
    plain = _messages(bags["full"])
    assert _messages(bags[compression]) == plain  # rosbags
    ours = read_bag(bags[compression], raw=True)  # the project's reader
    for topic, items in plain.items():
        assert [bytes(p) for p in ours.topics[topic].payloads] == [p for _, p in items]
        assert list(ours.topics[topic].log_time_ns) == [t for t, _ in items]
    (data,) = bags[compression].glob("*.mcap")
    with data.open("rb") as f:  # the mcap library: chunk compression and every message
        reader = make_reader(f)
        kinds = {c.compression for c in reader.get_summary().chunk_indexes}
        seen: dict[str, list[tuple[int, bytes]]] = {}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            seen.setdefault(channel.topic, []).append((message.log_time, message.data))
    assert kinds == {compression}
    assert {t: sorted(v) for t, v in seen.items()} == {t: sorted(v) for t, v in plain.items()}
    size = {k: sum(f.stat().st_size for f in bags[k].glob("*.mcap")) for k in ("full", compression)}
    assert size[compression] < 0.8 * size["full"], size


@pytest.mark.slow
def test_tf_static_has_each_sensor_at_its_lever_arm(bags):
    static = {}
    with Reader(bags["selected"]) as reader:  # rosbags' own deserializer
        for conn, _, raw in reader.messages():
            if conn.topic == "/tf_static":
                for tr in TS.deserialize_cdr(raw, conn.msgtype).transforms:
                    v, q = tr.transform.translation, tr.transform.rotation
                    static[(tr.header.frame_id, tr.child_frame_id)] = (
                        [v.x, v.y, v.z], [q.x, q.y, q.z, q.w])  # fmt: skip
    flu = {  # FRD → FLU by hand: (x, −y, −z)
        "gnss": [1.0, 0.4, 1.2],
        "baro": [2.0, -0.5, -0.3],
        "mag": [0.0, 0.0, 0.0],  # the magnetometer has no lever arm
        "wheel_rl": [0.0, 0.8, -0.45],
    }
    for frame, translation in flu.items():
        p, q = static[("base_link", frame)]
        assert p == translation, frame  # exact: a sign change
        assert q == [0.0, 0.0, 0.0, 1.0], frame
    # the frame ids the aiding messages carry (full bag: every sensor's topic)
    contents = read_bag(bags["full"])
    ids = {contents[t].frame_id for t in ("/gnss/fix", "/baro/pressure", "/mag", "/wheel/twist")
           if t in contents.topics}  # fmt: skip
    assert ids == set(flu), ids


def _ecef(lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
    e2 = WGS84_F * (2 - WGS84_F)
    n = WGS84_A / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1 - e2) + h) * np.sin(lat)], -1)  # fmt: skip


def _dcm(q: np.ndarray) -> np.ndarray:
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)  # fmt: skip


@pytest.mark.slow
def test_the_gnss_fix_is_the_reference_pose_composed_with_the_antenna_frame(bags):
    contents = read_bag(bags["selected"])
    fix, odom = contents["/gnss/fix"], contents["/reference/odom"]
    rows = np.searchsorted(np.asarray(odom.stamps_ns), np.asarray(fix.stamps_ns))
    c_flu_e = _dcm(np.asarray(odom.orientation)[rows])
    antenna = np.asarray(odom.position)[rows] + c_flu_e @ np.array([1.0, 0.4, 1.2])
    measured = _ecef(np.radians(fix.latitude), np.radians(fix.longitude), np.asarray(fix.altitude))
    err = np.abs(measured - antenna).max()
    assert err < 1e-8, err  # measured 9.3e-10 m: one ulp of an ECEF coordinate (6.4e6 m)


# -- the selection and the settings without a bag -----------------------------------------------


def test_patterns_match_whole_names_and_unmatched_ones_are_errors():
    topics = ["/reference/imu", "/reference/imu_dv", "/navigator/odom", "/navigator/odom_map"]
    sel = TopicSelection.of(["/reference/imu", "/navigator/.*"], [".*_map"])
    assert sel.select(topics) == ["/reference/imu", "/navigator/odom"]
    assert TopicSelection().select(topics) == topics and TopicSelection().everything
    with pytest.raises(SelectionError, match=r"recording\.include\.1: '/nav/.\*' matches none"):
        TopicSelection.of(["/reference/imu", "/nav/.*"], None).check(topics)
    with pytest.raises(SelectionError, match=r"recording\.exclude\.0"):
        TopicSelection.of(None, ["/typo"]).check(topics)
    with pytest.raises(SelectionError, match="leaves no topic"):
        TopicSelection.of(["/reference/imu"], ["/reference/.*"]).check(topics)
    assert sel.counts(dict.fromkeys(topics, 3)) == {"/reference/imu": 3, "/navigator/odom": 3}


def test_recording_keys_are_validated_once():
    base = {k: SCENARIO[k] for k in ("rate_hz", "initial", "trajectory")}
    for recording, message in (
        ({"include": ["("]}, r"recording\.include\.0: '\(' is not a regular expression"),
        ({"exclude": []}, r"recording\.exclude: must be a non-empty list"),
        ({"compression": "lz4", "storage": "sqlite3"}, r"recording\.compression: lz4 .* mcap"),
        ({"compression": "gzip"}, r"recording\.compression"),
    ):
        with pytest.raises(ScenarioError, match=message):
            parse_scenario({**base, "recording": recording})
    with pytest.raises(ScenarioError, match=r"aiding\.barometer\.frame_id: 'gnss' is already"):
        parse_scenario({**base, "aiding": {"gnss": {}, "barometer": {"frame_id": "gnss"}}})
    with pytest.raises(ScenarioError, match=r"aiding\.gnss\.frame_id: 'base_link'"):
        parse_scenario({**base, "aiding": {"gnss": {"frame_id": "base_link"}}})


def test_command_line_options_become_the_recording_keys(tmp_path):
    args = build_parser().parse_args(["run", "s.yaml", "--out", "o", *SELECT, "--compression",
                                      "zstd"])  # fmt: skip
    overrides = _recording_overrides(args)
    doc = {k: SCENARIO[k] for k in ("rate_hz", "initial", "trajectory")}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    rec = load_scenario(path, overrides).recording
    assert rec.compression == "zstd"
    assert rec.include == ["/tf_static", "/gnss/fix", "/reference/odom", "/navigator/.*"]
    assert rec.exclude == ["/navigator/fix", ".*_map"]


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_the_recorders_writer_compresses_each_flushed_chunk(tmp_path, compression):
    out = tmp_path / "rec"
    bag = IncrementalBagWriter(out, compression=compression).open()
    conn = bag.add_topic("/x", "std_msgs/msg/String")
    payloads = [bytes(TS.serialize_cdr(TS.types["std_msgs/msg/String"](data="a" * 200 + str(i)),
                                       "std_msgs/msg/String")) for i in range(50)]  # fmt: skip
    for i, p in enumerate(payloads):
        bag.write_connection(conn, 1000 + i, p)
        if i % 10 == 9:
            bag.flush()
    bag.close()
    with (out / "rec.mcap").open("rb") as f:
        reader = make_reader(f)
        assert {c.compression for c in reader.get_summary().chunk_indexes} == {compression}
        assert [m.data for _, _, m in reader.iter_messages()] == payloads
    with pytest.raises(BagWriteError, match="needs storage mcap"):
        BagWriter(tmp_path / "db", storage="sqlite3", compression="zstd")
    with pytest.raises(BagWriteError, match="unknown compression"):
        BagWriter(tmp_path / "db", compression="gzip")
