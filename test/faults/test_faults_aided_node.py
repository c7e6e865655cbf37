"""Faults into the live ``aided_node`` over DDS: the inputs of a generated aided bag (measured
IMU, truth, GNSS, barometer, magnetometer), one GNSS fix altered, are played by ``bag_player``
into the node and its ``/aided/*`` output is recorded by ``bag_recorder``.

* **out of order**: the fix of 2.0 s arrives 1 s late, after five later fixes;
* **NaN**: the fix of 2.0 s has a NaN latitude.

Either way the fix is dropped, named in one log line and counted in the node's summary; the
filter goes on without it: no non-finite number is published, the outputs before it are the
bytes ``generate`` writes, one GNSS position innovation and NIS fewer, and the node exits 0.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from node_testing import launch, list_param, node_args, wait_ok

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "test" / "data" / "aided_default_noisy.yaml"
DURATION_S = 6.0
FAULT_S = 2.0
TIMEOUT_S = 600.0
INPUTS = ("/reference/imu_measured", "/reference/odom", "/gnss/fix", "/gnss/vel",
          "/baro/pressure", "/mag")  # fmt: skip

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    from strapdown_ros.config import load_scenario
    from strapdown_ros.generate import generate_dataset

    scenario = load_scenario(SCENARIO, [], DURATION_S)
    out = tmp_path_factory.mktemp("aided_faults") / "bag"
    generate_dataset(scenario, out)
    return scenario, read_bag(out, raw=True)


def _faulted_inputs(contents, t_fault: int, fault: str, out: Path) -> None:
    """The input topics of ``contents`` into the bag ``out``, the fix stamped ``t_fault``
    altered by ``fault``."""
    batches = []
    for topic in INPUTS:
        data = contents.topics[topic]
        log = np.array(data.log_time_ns, dtype=np.int64)
        payloads = [bytes(p) for p in data.payloads]
        if topic == "/gnss/fix":
            fields = cdr.deserialize(data.msgtype, payloads)
            (i,) = np.flatnonzero(np.asarray(fields.stamps_ns) == t_fault)
            if fault == "out-of-order":
                log[i] += 1_000_000_000
            else:
                lat = np.array(fields.latitude, dtype=np.float64)
                lat[i] = np.nan
                payloads[i] = bytes(cdr.serialize(replace(fields, latitude=lat))[i])
        order = np.argsort(log, kind="stable")
        batches.append(Batch(topic, data.msgtype, log[order], [payloads[j] for j in order]))
    with BagWriter(out) as writer:
        writer.write_batches(batches)


@pytest.mark.parametrize(
    ("fault", "said", "event"),
    [
        ("out-of-order", "not after an earlier one; dropped", "out-of-order stamp 1"),
        ("nan", "NaN or infinity; dropped", "non-finite 1"),
    ],
)
def test_bad_fix_is_dropped_and_said(generated, tmp_path, ros_env, procs, fault, said,
                                     event) -> None:  # fmt: skip
    from strapdown_ros.stages.aided import aided_topic_types
    from strapdown_ros.stages.intake import format_stamp, nonfinite_rows

    scenario, contents = generated
    t_fault = scenario.start_time_ns + int(FAULT_S * 1e9)
    inputs, recorded = tmp_path / "inputs", tmp_path / "recorded"
    _faulted_inputs(contents, t_fault, fault, inputs)
    outputs = aided_topic_types(scenario)
    env = dict(ros_env)
    deadline = time.monotonic() + TIMEOUT_S
    recorder = launch(procs, node_args(
        "bag_recorder", f"output:={recorded}", "stop_when_done:=true",
        list_param("topics", [f"{t}={m}" for t, m in outputs.items()]),
    ), env, tmp_path, "recorder")  # fmt: skip
    node = launch(procs, node_args(
        "aided_node", f"scenario:={SCENARIO}", f"duration_s:={DURATION_S}", "qos_depth:=10000",
        list_param("subscribers_per_topic", [f"{t}=1" for t in outputs]),
        "wait_timeout_s:=300.0", "idle_timeout_s:=60.0",
    ), env, tmp_path, "aided_node")  # fmt: skip
    node.wait_for("subscribed to", deadline)
    player = launch(procs, node_args(
        "bag_player", f"bag:={inputs}", "publish_clock:=false", "wait_for_subscribers:=1",
        "wait_timeout_s:=300.0", "rate_factor:=2.0", "qos_depth:=10000",
    ), env, tmp_path, "player")  # fmt: skip
    wait_ok(deadline, player, node, recorder)
    log = node.output
    assert "Traceback" not in log, log
    line = f"/gnss/fix (gnss_position): stamp {format_stamp(t_fault)}"
    assert sum(line in x and said in x for x in log.splitlines()) == 1, log
    assert event in log, log  # the summary's input events

    got = read_bag(recorded, raw=True)
    assert set(got.topics) == set(outputs), log
    for topic in outputs:
        fields = got[topic]
        assert nonfinite_rows(fields) is None, f"{topic}: non-finite values published\n{log}"
    want_nis = np.asarray(contents["/aided/nis/gnss_position"].stamps_ns)
    got_nis = np.asarray(got["/aided/nis/gnss_position"].stamps_ns)
    assert list(got_nis) == [t for t in want_nis if t != t_fault], log
    for topic in ("/aided/odom", "/aided/nis/gnss_velocity", "/aided/nis/mag"):
        assert len(got.topics[topic].payloads) == len(contents.topics[topic].payloads), topic
    # before the fault: generate's bytes; from it on the filter has one update fewer
    stamps = np.asarray(contents["/aided/odom"].stamps_ns)
    a = [bytes(p) for p in got.topics["/aided/odom"].payloads]
    b = [bytes(p) for p in contents.topics["/aided/odom"].payloads]
    before = int(np.sum(stamps < t_fault))
    assert a[:before] == b[:before], log
    assert a[before:] != b[before:], "the fix was used"
