"""No model error: the aided filter on an ideal measured IMU and ideal aiding sensors follows the
truth to round-off, over the whole 10-minute flight and drive.

The user's path: a bag written by ``generate_dataset`` from a test scenario (the trajectory of
default.yaml / car.yaml copied, ``imu_errors`` with every term off on ``/reference/imu``, the
shipped aiding sections' rates, lever arms and the tunnel outage, errors off), read back from
disk and fed to :class:`AidedStage` in log-time order. The errors published on
``/aided/error/*`` (the navigator's definitions against ``/reference/odom``) stay below
5e-8 m, 3e-9 m/s and 5e-11 rad (measured at full length: 5.4e-9 m, 2.3e-10 m/s, 3.8e-12 rad; the
task's bar is 1 mm, 1 mm/s, 1 µrad); message counts equal :func:`aided_expected_counts`;
every measurement passes the gate; output log times equal their stamps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, merge_order
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset
from strapdown_ros.stages.aided import AidedStage, aided_expected_counts, aided_input_topics

DATA = Path(__file__).resolve().parent / "data"
#: Bounds: about 10x the errors measured over the full 10 minutes.
POSITION_M, VELOCITY_MPS, ATTITUDE_RAD = 5e-8, 3e-9, 5e-11


def bag_batches(path: Path, topics: list[str]) -> list[Batch]:
    """The topics of a bag read back from disk, one Batch per topic (log times as stamps)."""
    bag = read_bag(path, topics, raw=True)
    return [Batch(t, bag.topics[t].msgtype, bag.topics[t].log_time_ns, bag.topics[t].payloads)
            for t in topics]  # fmt: skip


def in_log_order(batches: list[Batch], chunk: int) -> list[list[Batch]]:
    """The messages of ``batches`` merged in log-time order, cut into chunks of ``chunk``
    messages (each chunk as per-topic batches)."""
    order = list(merge_order(batches))
    out = []
    for start in range(0, len(order), chunk):
        parts: dict[int, list[int]] = {}
        for b, i, _ in order[start : start + chunk]:
            parts.setdefault(b, []).append(i)
        out.append([Batch(batches[b].topic, batches[b].msgtype,
                          np.asarray(batches[b].stamps_ns)[idx],
                          [batches[b].payloads[i] for i in idx]) for b, idx in parts.items()])
    return out


def run_stage(scenario, chunks: list[list[Batch]], **kwargs) -> dict[str, tuple[list, tuple]]:
    """Feed the chunks, flush; payloads (bytes) and log times per output topic."""
    stage = AidedStage(scenario, **kwargs)
    out: dict[str, tuple[list, list]] = {}
    for batches in [*chunks, None]:
        res = stage.flush() if batches is None else stage.feed_batches(batches)
        for b in res:
            pay, log = out.setdefault(b.topic, ([], []))
            pay += [bytes(p) for p in b.payloads]
            log += [int(t) for t in b.stamps_ns]
    return {k: (v[0], tuple(v[1])) for k, v in out.items()}


def _check(name: str, duration_s: float, tmp_path: Path) -> None:
    scenario = load_scenario(DATA / f"{name}.yaml", duration_s=duration_s)
    summary = generate_dataset(scenario, tmp_path / "bag")
    batches = bag_batches(tmp_path / "bag", aided_input_topics(scenario))
    warnings: list[str] = []
    out = run_stage(scenario, in_log_order(batches, 20_000), warn=warnings.append,
                    error=warnings.append)  # fmt: skip
    assert warnings == []
    expected = aided_expected_counts(scenario, summary.cycles)
    assert {k: len(v[0]) for k, v in out.items()} == expected
    for topic, bound in (("/aided/error/position", POSITION_M),
                         ("/aided/error/velocity", VELOCITY_MPS),
                         ("/aided/error/attitude", ATTITUDE_RAD)):  # fmt: skip
        f = cdr.deserialize(cdr.VECTOR3_STAMPED, out[topic][0])
        err = np.abs(np.asarray(f.vector)).max()
        assert err < bound, (topic, err)
        np.testing.assert_array_equal(np.array(out[topic][1]), np.asarray(f.stamps_ns))
    for topic, (payloads, _) in out.items():
        if topic.startswith("/aided/nis/"):
            f = cdr.deserialize(cdr.VECTOR3_STAMPED, payloads)
            assert np.all(np.asarray(f.vector)[:, 2] == 1.0), topic  # all accepted
    odom = cdr.deserialize(cdr.ODOMETRY, out["/aided/odom"][0])
    assert odom.stamps_ns[0] == scenario.start_time_ns
    assert odom.stamps_ns[-1] == scenario.start_time_ns + summary.cycles * scenario.period_ns


@pytest.mark.parametrize(("name", "duration_s"), [("aided_car_ideal", 60.0),
                                                  ("aided_default_ideal", 20.0)])
def test_ideal_short(name, duration_s, tmp_path):
    _check(name, duration_s, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["aided_car_ideal", "aided_default_ideal"])
def test_ideal_ten_minutes(name, tmp_path):
    """The whole trajectories (car: GNSS tunnel 195-240 s coasted on the wheel speed)."""
    _check(name, 600.0, tmp_path)
