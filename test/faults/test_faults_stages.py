"""Fault injection into the stage objects the nodes run (no ROS): a generated bag's messages,
altered per case, fed through ``on_batch`` as the nodes feed them. The checks are written once
in the stages, so these cases cover ``generate`` and the nodes alike (docs/reliability.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.config import load_scenario
from strapdown_ros.stages.intake import InputEvents, nonfinite_rows

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
DURATION_S = 3.0
T = 5_000_000


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO, [], DURATION_S)


@pytest.fixture(scope="module")
def contents(tmp_path_factory, scenario):
    from strapdown_ros.generate import generate_dataset

    out = tmp_path_factory.mktemp("stages") / "bag"
    generate_dataset(scenario, out)
    return read_bag(out, raw=True)


def _with_nan(msgtype: str, payload: bytes, field: str) -> bytes:
    fields = cdr.deserialize(msgtype, [payload])
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values[field] = np.array(values[field], dtype=np.float64)
    values[field][0, -1] = np.inf
    return bytes(cdr.serialize(type(fields)(**values))[0])


def _live(contents, imu_topic, odom_topic, kinds=("imu", "odom"), *, nan_imu=(), nan_odom=(),
          drop_odom=(), drop_imu=(), jump=None):  # fmt: skip
    """``(kind, payload)`` in live order (per stamp: Odometry, then Imu) with faults by cycle."""
    imu, odom = contents.topics[imu_topic], contents.topics[odom_topic]
    by_stamp = dict(zip(imu.fields.stamps_ns.tolist(), imu.payloads, strict=True))
    cycles = []
    for m, (stamp, p) in enumerate(zip(odom.fields.stamps_ns.tolist(), odom.payloads,
                                       strict=True)):  # fmt: skip
        items = []
        if m not in drop_odom:
            items.append((kinds[1], _with_nan(cdr.ODOMETRY, p, "twist_linear")
                          if m in nan_odom else bytes(p)))  # fmt: skip
        if stamp in by_stamp and m not in drop_imu:
            q = by_stamp[stamp]
            items.append((kinds[0], _with_nan(cdr.IMU, q, "linear_acceleration")
                          if m in nan_imu else bytes(q)))  # fmt: skip
        cycles.append(items)
    order = list(range(len(cycles)))
    if jump:
        order = list(range(jump[0] + 1)) + list(range(jump[1], len(cycles)))
    return [item for m in order for item in cycles[m]]


def _feed(stage, items, size=7):
    out: dict[str, list[tuple[int, bytes]]] = {}
    for k in range(0, len(items), size):
        for topic, stamp, data in stage.on_batch(items[k : k + size]):
            out.setdefault(topic, []).append((stamp, bytes(data)))
    return out


class _Log:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, line: str) -> None:
        self.lines.append(line)


def _finite(out, msgtypes) -> None:
    for topic, msgtype in msgtypes.items():
        fields = cdr.deserialize(msgtype, [p for _, p in out[topic]])
        assert nonfinite_rows(fields) is None, topic


# ---------------------------------------------------------------------------------------------


def test_events_one_line_each_flood_limited_per_class() -> None:
    now = [0.0]
    log = _Log()
    events = InputEvents(log, log, burst=3, window_s=1.0, clock=lambda: now[0])
    for _ in range(10):
        events("gap", "a gap")
    events("non-finite", "a NaN")  # another class is never held back by the flood of gaps
    assert log.lines == ["a gap"] * 3 + ["a NaN"]
    now[0] = 2.0
    events("gap", "a gap")
    assert "7 more 'gap' line(s) held back" in log.lines[-1]
    assert events.counts == {"gap": 11, "non-finite": 1}
    assert events.summary() == "input events: gap 11, non-finite 1"


def _navigator(scenario, log):
    from strapdown_ros.config import navigator_spec
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.navigator import NavigatorStage

    spec = navigator_spec(scenario)
    return NavigatorStage.for_scenario(
        scenario, spec, end_ns=resolve_plan(scenario).last_stamp(spec.imu_topic), info=log,
        warn=log, error=log,
    )  # fmt: skip


NAV = {"/navigator/odom": cdr.ODOMETRY, "/navigator/error/position": cdr.VECTOR3_STAMPED}


def test_navigator_nan_burst_one_line(scenario, contents) -> None:
    """30 consecutive IMU messages with an infinity: one line, one event, nothing non-finite
    published, a new run from the truth after them that reaches the end."""
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"),
                  nan_imu=range(100, 130))  # fmt: skip
    out = _feed(stage, items, size=1000)  # one batch holds the whole burst
    _finite(out, NAV)
    assert stage.events.counts == {"non-finite": 1}, log.lines
    assert sum("NaN or infinity" in line for line in log.lines) == 1
    assert stage.finished and stage.runs == 2


def test_navigator_lost_truth_runs_on(scenario, contents) -> None:
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"),
                  drop_odom=[200, 400], nan_odom=[300])  # fmt: skip
    out = _feed(stage, items)
    ref = [bytes(p) for p in contents.topics["/navigator/odom"].payloads]
    assert [p for _, p in out["/navigator/odom"]] == ref  # ran on from its own state
    assert len(out["/navigator/error/position"]) == len(ref) - 3
    assert stage.events.counts == {"truth lost": 3, "non-finite": 1}, log.lines
    assert stage.runs == 1 and stage.finished


def test_navigator_period_not_from_one_interval(scenario, contents) -> None:
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"), drop_imu=[2])
    out = _feed(stage, items)
    assert stage.period_ns == T, log.lines
    stamps = [s for s, _ in out["/navigator/odom"]]
    assert np.all(np.diff(stamps) == 10 * T) and stage.finished


def test_navigator_restarted_source(scenario, contents) -> None:
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"),
                  jump=(400, 100))  # fmt: skip
    out = _feed(stage, items)
    _finite(out, NAV)
    assert stage.events.counts == {"restart": 1}, log.lines
    assert stage.runs == 2 and stage.finished


VAR = {"/variation/imu": cdr.IMU, "/variation/odom": cdr.ODOMETRY}


def _variation(scenario, log):
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.stages.variation import VariationStage

    cycles = resolve_plan(scenario).cycles
    return VariationStage(scenario, cycles, info=log, warn=log, error=log)


@pytest.mark.parametrize("fault", ["nan_imu", "nan_odom"])
def test_variation_nonfinite(scenario, contents, fault) -> None:
    log = _Log()
    stage = _variation(scenario, log)
    items = _live(contents, "/reference/imu", "/reference/odom", **{fault: [150]})
    out = _feed(stage, items)
    _finite(out, VAR)
    assert stage.events.counts == {"non-finite": 1}, log.lines
    assert stage.finished


def test_variation_restarted_source(scenario, contents) -> None:
    log = _Log()
    stage = _variation(scenario, log)
    out = _feed(stage, _live(contents, "/reference/imu", "/reference/odom", jump=(300, 50)))
    _finite(out, VAR)
    assert stage.events.counts.get("restart") == 1, log.lines
    assert stage.finished


def test_measurement_nonfinite_and_restart(scenario, contents) -> None:
    from strapdown_ros.stages.imu_errors import ImuErrorsStage

    log = _Log()
    stream = ImuErrorsStage(scenario, info=log, warn=log, error=log)
    payloads = [bytes(p) for p in contents.topics["/variation/imu"].payloads]
    payloads[50] = _with_nan(cdr.IMU, payloads[50], "angular_velocity")
    payloads = payloads[:300] + payloads[100:]  # the source restarts at cycle ~100
    out = []
    for k in range(0, len(payloads), 9):
        out += stream.on_payloads(payloads[k : k + 9])
    assert nonfinite_rows(cdr.deserialize(cdr.IMU, out)) is None
    assert stream.events.counts == {"non-finite": 1, "restart": 1}, log.lines
    assert stream.runs == 2


def _huge(payload: bytes) -> bytes:
    fields = cdr.deserialize(cdr.IMU, [payload])
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values["linear_acceleration"] = np.full((1, 3), 1.7e308)
    return bytes(cdr.serialize(type(fields)(**values))[0])


def test_navigator_never_publishes_a_diverged_solution(scenario, contents) -> None:
    """Finite but absurd input makes the solution overflow: the non-finite outputs are not
    published (logged as one event per stretch)."""
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"))
    k = next(i for i, (kind, _) in enumerate(items) if kind == "imu" and i > 400)
    items[k] = ("imu", _huge(items[k][1]))
    out = _feed(stage, items)
    _finite(out, NAV)
    assert stage.events.counts.get("non-finite output", 0) == 1, log.lines
    assert stage.runs == 2 and stage.finished  # a new run from the truth reaches the end


def _reframed(payload: bytes, frame_id: str) -> bytes:
    fields = cdr.deserialize(cdr.IMU, [payload])
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values["frame_id"] = frame_id
    return bytes(cdr.serialize(type(fields)(**values))[0])


@pytest.mark.parametrize("size", [1, 7])
def test_navigator_imu_frame_change(scenario, contents, size) -> None:
    """The Imu frame changes mid-stream (another body): one event, the run ends, a new run from
    the truth reaches the end."""
    log = _Log()
    stage = _navigator(scenario, log)
    items = _live(contents, "/variation/imu", "/variation/odom", ("imu", "truth"))
    items = items[:500] + [(k, _reframed(p, "other_imu") if k == "imu" else p)
                           for k, p in items[500:]]  # fmt: skip
    out = _feed(stage, items, size=size)
    _finite(out, NAV)
    assert stage.events.counts == {"wrong frame": 1}, log.lines
    assert stage.runs == 2 and stage.finished
