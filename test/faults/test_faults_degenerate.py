"""Finite but degenerate input, and the output check, in the stages (no DDS): a zero-norm
orientation quaternion in a truth or reference Odometry message (finite numbers, so a
non-finite check passes) reached a division by its norm; now the shared intake drops it with
one ``degenerate`` event and nothing non-finite is published. Every output goes through
``bag.batches.batch``, which never serializes a non-finite message. A lost first IMU interval
is reported (docs/reliability.md).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import batch, finite_outputs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_faults_stages import (  # noqa: E402
    NAV,
    VAR,
    T,
    _feed,
    _finite,
    _live,
    _Log,
    _navigator,
    _variation,
    contents,  # noqa: F401 - fixture
    scenario,  # noqa: F401 - fixture
)


def _zero_quaternion(payload: bytes) -> bytes:
    """An Odometry message whose orientation quaternion is (0, 0, 0, 0)."""
    fields = cdr.deserialize(cdr.ODOMETRY, [payload])
    fields = dataclasses.replace(fields, orientation=np.zeros((1, 4)))
    return bytes(cdr.serialize(fields)[0])


def _with_zero_odom(items, kind: str, cycles: set[int]):
    """``items`` with the Odometry (``kind``) messages of ``cycles`` given a zero quaternion."""
    out, m = [], -1
    for k, p in items:
        if k == kind:
            m += 1
            if m in cycles:
                p = _zero_quaternion(p)
        out.append((k, p))
    return out


# ---------------------------------------------------------------------------------------------
# the output check
# ---------------------------------------------------------------------------------------------


def test_batch_never_serializes_a_nonfinite_output() -> None:
    """Rows with a NaN or an infinity are left out of the batch, their log times with them;
    one line per stretch naming the topic and stamps; the other rows serialize as before."""
    from strapdown_ros.messages import ImuFields

    n = 8
    stamps = np.arange(n, dtype=np.int64) * T + 1_000_000_000
    imu = ImuFields(
        stamps_ns=stamps, frame_id="imu", orientation=np.tile([0.0, 0, 0, 1], (n, 1)),
        orientation_covariance=np.full((n, 9), -1.0), angular_velocity=np.ones((n, 3)),
        angular_velocity_covariance=np.zeros((n, 9)), linear_acceleration=np.ones((n, 3)),
        linear_acceleration_covariance=np.zeros((n, 9)),
    )  # fmt: skip
    good = batch("/x/imu", imu)
    acc = np.array(imu.linear_acceleration)
    acc[[2, 3, 6], 1] = [np.nan, np.inf, -np.inf]
    bad = dataclasses.replace(imu, linear_acceleration=acc)
    lines: list[str] = []
    log_ns = stamps + 7
    got = batch("/x/imu", bad, log_ns=log_ns, log=lines.append)
    keep = [0, 1, 4, 5, 7]
    assert got.stamps_ns.tolist() == log_ns[keep].tolist()
    assert [bytes(p) for p in got.payloads] == [bytes(good.payloads[k]) for k in keep]
    assert len(lines) == 2 and all(line.startswith("/x/imu: stamp ") for line in lines), lines
    assert "(2 messages)" in lines[0] and "not published" in lines[0], lines
    # all rows bad: an empty batch (nothing leaves), still one line per stretch
    lines.clear()
    acc[:] = np.nan
    empty = batch("/x/imu", dataclasses.replace(imu, linear_acceleration=acc), log=lines.append)
    assert len(empty.payloads) == 0 and len(empty.stamps_ns) == 0 and len(lines) == 1
    assert finite_outputs("/x/imu", imu)[1] is None  # the common case: nothing to say


# ---------------------------------------------------------------------------------------------
# a zero-norm quaternion in truth / reference messages
# ---------------------------------------------------------------------------------------------


def test_navigator_degenerate_truth(scenario, contents) -> None:  # noqa: F811
    """Why: the navigator published NaN on its error topics. Now the truth message is dropped
    as lost (the odometry runs on, the same bytes), one line, one ``degenerate`` event."""
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"))
    out = _feed(stage, _with_zero_odom(items, "truth", {300}))
    _finite(out, NAV)
    ref = [bytes(p) for p in contents.topics["/navigator/odom"].payloads]
    assert [p for _, p in out["/navigator/odom"]] == ref
    assert stage.events.counts == {"degenerate": 1, "truth lost": 1}, log.lines
    assert sum("quaternion of norm far from 1" in line for line in log.lines) == 1
    assert stage.finished


@pytest.mark.parametrize("size", [7, 1000])
def test_variation_degenerate_reference(scenario, contents, size) -> None:  # noqa: F811
    """Why: the variation stage had its own non-finite check only, and a zero quaternion gave
    NaN on all five topics for 25 messages. Now the shared intake drops the message (one
    ``degenerate`` event), the solution restarts after it, nothing non-finite leaves."""
    log = _Log()
    stage = _variation(scenario, log)
    items = _live(contents, "/reference/imu", "/reference/odom")
    out = _feed(stage, _with_zero_odom(items, "odom", {151}), size=size)
    _finite(out, VAR)
    assert stage.events.counts == {"degenerate": 1}, log.lines
    assert sum("quaternion of norm far from 1" in line for line in log.lines) == 1, log.lines
    assert stage.finished


def test_aiding_degenerate_truth(scenario, contents) -> None:  # noqa: F811
    """Why: the aiding stage published NaN on every sensor topic. Now the truth message is
    dropped (its epochs skipped), one ``degenerate`` event, every output finite."""
    from strapdown_ros.stages.aiding import AidingStage
    from strapdown_ros.stages.intake import nonfinite_rows

    if scenario.aiding is None:
        pytest.skip("the scenario has no aiding section")
    lines: list[str] = []
    stage = AidingStage(scenario, warn=lines.append, error=lines.append)
    payloads = [bytes(p) for p in contents.topics["/reference/odom"].payloads]
    payloads[200] = _zero_quaternion(payloads[200])  # t = 1.0 s: an epoch of every sensor
    out: dict[str, list[bytes]] = {}
    types: dict[str, str] = {}
    for k in range(0, len(payloads), 50):
        for b in stage.on_payloads(payloads[k : k + 50]):
            out.setdefault(b.topic, []).extend(bytes(p) for p in b.payloads)
            types[b.topic] = b.msgtype
    assert out, "no aiding output"
    for topic, got in out.items():
        assert nonfinite_rows(cdr.deserialize(types[topic], got)) is None, topic
    assert stage.events.counts.get("degenerate") == 1, lines
    assert sum("quaternion of norm far from 1" in line for line in lines) == 1, lines


# ---------------------------------------------------------------------------------------------
# a lost first interval
# ---------------------------------------------------------------------------------------------


def test_navigator_lost_first_interval(scenario, contents) -> None:  # noqa: F811
    """Why: with the second IMU message lost (first interval 2T) the navigator learned T from
    the next intervals and said nothing about the missing message. Now: one ``gap`` event
    naming the stamps and what is not used; T still right, the output rate unchanged."""
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"), drop_imu=[2])
    out = _feed(stage, items)
    assert stage.period_ns == T, log.lines
    assert stage.events.counts == {"gap": 1}, log.lines
    t0 = int(np.asarray(contents.topics["/variation/odom"].fields.stamps_ns)[0])
    line = next(x for x in log.lines if "before the IMU period was known" in x)
    assert f"{(t0 + 3 * T) // 10**9}.{(t0 + 3 * T) % 10**9:09d} follows" in line, line
    assert "after 2 T" in line and "1 message(s) missing" in line, line
    stamps = [s for s, _ in out["/navigator/odom"]]
    assert np.all(np.diff(stamps) == 10 * T) and stage.finished
    # an uninterrupted start says nothing
    clean = _navigator(scenario, _Log())
    _feed(clean, _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth")))
    assert clean.events.counts == {}
