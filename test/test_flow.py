"""Flow control of the live pipeline (issue 19): the progress reports and the source's gate.

The gate is driven here with hand-made reports (no ROS graph): the source may publish message k
of a topic only while every consumer that reported taking it has taken more than k - window,
nothing until every participant has reported and each of the source's topics is reported taken,
and nothing while a downstream topic's backlog exceeds the window. The whole pipeline under
flow control: test_pipeline.py.
"""

from __future__ import annotations

import pytest

from strapdown_ros.nodes.flow import FlowGate, decode_report, encode_report


class _Logger:
    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warning(self, text: str) -> None:
        self.warnings.append(text)


class _Node:
    """What FlowGate uses of a node."""

    def __init__(self) -> None:
        self.callback = None
        self.logger = _Logger()

    def create_subscription(self, msg_class, topic, callback, qos):
        self.callback = callback
        return object()

    def get_logger(self) -> _Logger:
        return self.logger


class _Msg:
    def __init__(self, data: str) -> None:
        self.data = data


def _report(node: _Node, name: str, taken: dict, published: dict | None = None) -> None:
    node.callback(_Msg(encode_report(name, taken, published or {})))


def test_report_round_trip() -> None:
    text = encode_report("variation_node", {"/reference/imu": 12, "/a/b": 0}, {"/v/imu": 7})
    assert text == "variation_node|/reference/imu=12,/a/b=0|/v/imu=7"
    assert decode_report(text) == ("variation_node", {"/reference/imu": 12, "/a/b": 0},
                                   {"/v/imu": 7})
    assert decode_report("bag_recorder||") == ("bag_recorder", {}, {})
    with pytest.raises(ValueError):
        decode_report("no separators")


def test_gate_limits_each_topic_to_the_slowest_consumer_plus_window() -> None:
    node = _Node()
    gate = FlowGate(node, ["/ref/imu", "/ref/odom"], ["bag_recorder", "variation_node"], 100)
    assert gate.limits == {"/ref/imu": 0, "/ref/odom": 0}  # nobody has reported
    _report(node, "bag_recorder", {"/ref/imu": 0, "/ref/odom": 0})
    assert gate.limits == {"/ref/imu": 0, "/ref/odom": 0}  # variation_node has not
    assert "variation_node" in gate.behind
    _report(node, "variation_node", {"/ref/imu": 0, "/ref/odom": 0}, {"/v/imu": 0})
    assert gate.limits == {"/ref/imu": 100, "/ref/odom": 100}
    _report(node, "bag_recorder", {"/ref/imu": 250, "/ref/odom": 40})
    _report(node, "variation_node", {"/ref/imu": 230, "/ref/odom": 230}, {"/v/imu": 0})
    assert gate.limits == {"/ref/imu": 330, "/ref/odom": 140}


def test_gate_stops_while_a_downstream_consumer_lags() -> None:
    node = _Node()
    gate = FlowGate(node, ["/ref/imu"], ["bag_recorder", "variation_node"], 100)
    _report(node, "variation_node", {"/ref/imu": 500}, {"/v/imu": 499})
    _report(node, "bag_recorder", {"/ref/imu": 500, "/v/imu": 399})  # exactly the window
    assert gate.limits == {"/ref/imu": 600}
    _report(node, "variation_node", {"/ref/imu": 550}, {"/v/imu": 549})  # 150 behind now
    assert gate.limits == {"/ref/imu": 0}
    assert gate.behind == "bag_recorder is 150 messages behind on /v/imu"
    _report(node, "bag_recorder", {"/ref/imu": 550, "/v/imu": 549})
    assert gate.limits == {"/ref/imu": 650} and gate.behind == ""


def test_gate_waits_until_each_own_topic_is_reported_taken() -> None:
    """A recorder's report sent before it subscribed a topic does not open that topic."""
    node = _Node()
    gate = FlowGate(node, ["/clock", "/ref/imu"], ["bag_recorder"], 10)
    _report(node, "bag_recorder", {"/ref/imu": 0})
    assert gate.limits == {"/clock": 0, "/ref/imu": 0}
    assert "/clock" in gate.behind
    _report(node, "bag_recorder", {"/ref/imu": 3, "/clock": 0})
    assert gate.limits == {"/clock": 10, "/ref/imu": 13}


def test_gate_ignores_malformed_reports_and_wait_returns_when_allowed() -> None:
    node = _Node()
    gate = FlowGate(node, ["/ref/imu"], ["bag_recorder"], 5)
    node.callback(_Msg("garbage"))
    assert node.logger.warnings and gate.limits == {"/ref/imu": 0}
    spins: list[float] = []

    def spin(timeout_s: float) -> None:  # the report arrives while the source spins
        spins.append(timeout_s)
        if len(spins) == 3:
            _report(node, "bag_recorder", {"/ref/imu": 0})

    waited = gate.wait("/ref/imu", 4, spin, lambda: True)
    assert len(spins) == 3 and waited >= 0 and gate.stalls == 1
    assert gate.wait("/ref/imu", 4, spin, lambda: True) >= 0 and len(spins) == 3
    # a signal (ok() false) ends a wait that the consumers would never end
    assert gate.wait("/ref/imu", 5, spin, lambda: False) >= 0
