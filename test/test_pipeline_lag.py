"""The real-time lag lines of ``run``: the recorder's per-topic lag, attributed to the nodes."""

from __future__ import annotations

from strapdown_ros.bag.recording import Recording
from strapdown_ros.pipeline.lag import LagWatch, attribute
from strapdown_ros.plan.chain import LiveNode

NODES = [
    LiveNode("trajectory", "trajectory_node", (), ("/ref",), ("/tf",)),
    LiveNode("variation", "variation_node", ("/ref",), ("/var",), ()),
    LiveNode("navigator", "navigator_node", ("/var",), ("/nav",), ()),
]


def test_each_node_gets_what_it_added():
    line = attribute({"/ref": 5.0, "/tf": 4.0, "/var": 5.5, "/nav": 9.0}, NODES, 0.6)
    assert "up to 9.0 s at the recorder (/nav)" in line
    assert "trajectory_node 0.6 s late publishing" in line
    assert "bag_recorder 4.4 s behind it" in line
    assert "variation_node +0.5 s" in line and "navigator_node +3.5 s" in line


def test_a_node_behind_alone():
    line = attribute({"/nav": 2.0}, NODES, 0.0)
    assert "navigator_node +2.0 s" in line and "variation_node" not in line


def test_watch_reads_the_logs_as_they_grow(tmp_path):
    rec, src = tmp_path / "rec.log", tmp_path / "src.log"
    rec.write_text("")
    src.write_text("[WARN] behind real time: publishing 1.50 s late (3.0 s of data published)\n")
    said: list[str] = []
    watch = LagWatch(rec, src, NODES, said.append)
    watch.poll()
    assert said == []
    with open(rec, "a") as f:
        f.write("[WARN] [x] [bag_recorder]: behind real time: /nav 3.00 s, /ref 2.00 s\n")
        f.write("[WARN] behind real time: /nav 4.0")  # a partial line: not yet
    watch.poll()
    assert len(said) == 1 and "navigator_node +3.0 s" in said[0]
    assert "trajectory_node 1.5 s late publishing" in said[0]
    with open(rec, "a") as f:
        f.write("0 s\n")
    watch.poll()
    assert len(said) == 2 and "up to 4.0 s" in said[1]


class _Writer:
    def add_topic(self, topic, msgtype, qos):
        return topic

    def sink(self, conn):
        return lambda t, payload: None


def test_recording_lags_against_the_wall_clock():
    rec = Recording(_Writer())  # type: ignore[arg-type]
    fast = rec.handler("/a", "std_msgs/msg/Header", lambda: [])
    slow = rec.handler("/b", "std_msgs/msg/Header", lambda: [])

    def header(t_ns: int) -> bytes:
        return b"\x00\x01\x00\x00" + (t_ns // 10**9).to_bytes(4, "little") + (
            t_ns % 10**9
        ).to_bytes(4, "little") + b"\x01\x00\x00\x00\x00\x00\x00\x00"

    s = 10**9
    for k in range(5):  # /a in real time from wall 100 s, /b 2 s late: received up to 104 s
        fast(header(k * s), 100 * s + k * s)
        if k <= 2:
            slow(header(k * s), 102 * s + k * s)
    lags = rec.lags_s(104 * s)
    assert abs(lags["/a"]) < 1e-9 and abs(lags["/b"] - 2.0) < 1e-9
    assert abs(rec.lags_s(106 * s + s // 2)["/a"] - 2.5) < 1e-9
