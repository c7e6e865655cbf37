"""Faults into the transfer-alignment stage (no ROS), fed as ``transfer_node`` feeds it: the
inputs of a generated bag, in batches of 0.1 s, one slave IMU message removed or made NaN, or
a NaN in a master Odometry message the filter uses. The stage stops with an error naming the
topic and the stamp; the epochs before the bad input are published as ``generate`` wrote them
(nothing before it is lost), none after it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from node_testing import generated as generated_bag

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, header_stamps_ns
from strapdown_ros.config import load_scenario
from strapdown_ros.stages.intake import format_stamp

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment.yaml"
DURATION_S = 3.0
FAULT_S = 1.5  # not on an epoch (every 0.1 s) and not a master cycle the filter needs
EPOCH_NS = 100_000_000

pytestmark = pytest.mark.slow  # generates a bag and compiles the filter's kernels


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """The scenario and its ``generate`` bag, read back raw."""
    out = tmp_path_factory.mktemp("transfer_faults") / "bag"
    return load_scenario(SCENARIO, [], DURATION_S), generated_bag(SCENARIO, out, DURATION_S)


def _with_nan(msgtype: str, payload: bytes, field: str) -> bytes:
    fields = cdr.deserialize(msgtype, [payload])
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values[field] = np.array(values[field], dtype=np.float64)
    values[field][0, 0] = np.nan
    return bytes(cdr.serialize(type(fields)(**values))[0])


def _feed(scenario, contents, topic: str, stamp: int, fault: str):
    """Run the stage on the inputs in 0.1 s batches with the fault; (stage, outputs)."""
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.transfer import TransferStage, transfer_input_topics

    stage = TransferStage(scenario, resolve_plan(scenario).variation_cycles)
    inputs = {}
    for t in transfer_input_topics(scenario):
        d = contents.topics[t]
        payloads = [bytes(p) for p in d.payloads]
        stamps = header_stamps_ns(Batch(t, d.msgtype, np.asarray(d.log_time_ns), payloads))
        if t == topic:
            (i,) = np.flatnonzero(stamps == stamp)
            if fault == "missing":
                del payloads[i]
                stamps = np.delete(stamps, i)
            else:
                field = "linear_acceleration" if d.msgtype == cdr.IMU else "twist_linear"
                payloads[i] = _with_nan(d.msgtype, payloads[i], field)
        inputs[t] = (d.msgtype, stamps, payloads)
    out: dict[str, list[bytes]] = {}
    t0 = scenario.start_time_ns
    for k in range(int(DURATION_S * 10) + 1):
        lo, hi = t0 + k * EPOCH_NS, t0 + (k + 1) * EPOCH_NS
        batches = []
        for t, (msgtype, stamps, payloads) in inputs.items():
            sel = np.flatnonzero((stamps >= lo) & (stamps < hi))
            batches.append(Batch(t, msgtype, stamps[sel], [payloads[j] for j in sel]))
        for b in stage.feed_batches(batches):
            out.setdefault(b.topic, []).extend(bytes(p) for p in b.payloads)
    return stage, out


@pytest.mark.parametrize(
    ("topic", "fault", "said"),
    [
        ("/variation/imu_measured", "missing", "missing, the next is"),
        ("/variation/imu_measured", "nan", "NaN or infinity"),
        ("/reference/odom", "nan", "NaN or infinity"),
    ],
    ids=["imu-gap", "imu-nan", "master-nan"],
)
def test_bad_input_stops_the_filter_and_keeps_what_came_before(generated, topic, fault, said):
    scenario, contents = generated
    stamp = scenario.start_time_ns + int(FAULT_S * 1e9)
    if topic == "/reference/odom":  # a master cycle the filter uses: one before an epoch
        stamp -= scenario.period_ns
    stage, out = _feed(scenario, contents, topic, stamp, fault)
    assert stage.error is not None and said in stage.error, stage.error
    assert topic in stage.error and format_stamp(stamp) in stage.error, stage.error
    odom = "/transfer/odom"
    want = [bytes(p) for p in contents.topics[odom].payloads]
    stamps = np.asarray(contents[odom].stamps_ns)
    before = int(np.sum(stamps < stamp))  # the epochs before the bad input
    assert out[odom] == want[:before]
    for t in stage.topics.values():  # every output: generate's messages up to the fault
        if t in out:
            got = out[t]
            assert got == [bytes(p) for p in contents.topics[t].payloads][:len(got)], t


def test_repeated_imu_messages_are_ignored(generated):
    """A slave IMU message delivered twice (a DDS redelivery) changes nothing."""
    scenario, contents = generated
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.transfer import TransferStage, transfer_input_topics

    stage = TransferStage(scenario, resolve_plan(scenario).variation_cycles)
    batches = []
    for t in transfer_input_topics(scenario):
        d = contents.topics[t]
        payloads = [bytes(p) for p in d.payloads]
        if d.msgtype == cdr.IMU:
            payloads = payloads[:100] + payloads[90:]  # ten repeated
        batches.append(Batch(t, d.msgtype, np.zeros(len(payloads), np.int64), payloads))
    out = {b.topic: [bytes(p) for p in b.payloads] for b in stage.feed_batches(batches)}
    assert stage.error is None
    for t, got in out.items():
        assert got == [bytes(p) for p in contents.topics[t].payloads], t
