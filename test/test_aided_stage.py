"""The aided stage's behaviour on bags read back from disk (test/data/aided_default_noisy.yaml:
tactical measured reference IMU, SBAS GNSS, MEMS barometer and magnetometer).

* the χ² gate rejects a GNSS fix moved 100 m (logged with its stamp, NIS z = 0) and accepts
  the others;
* latency: with the GNSS delayed (on and off the IMU grid) the GNSS innovations and every
  output whose inputs are the same as without delay are bit-identical to the zero-latency run
  (rollback + re-run is exact), innovations are logged at stamp + latency;
* the output bytes do not depend on the chunking or the interleaving of the topics;
* a NaN measurement or a repeated one is dropped (logged) and the result is that of the bag
  without it; an IMU gap stops the filter (logged), nothing is integrated across it;
* P stays symmetric positive definite at every output epoch.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_aided_exact import bag_batches, in_log_order, run_stage

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset
from strapdown_ros.stages.aided import (
    AidedStage,
    aided_expected_counts,
    aided_input_topics,
    aided_topic_plans,
    aided_topic_types,
)

DATA = Path(__file__).resolve().parent / "data"
DURATION_S = 12.0


def _scenario(*overrides: str):
    return load_scenario(DATA / "aided_default_noisy.yaml", overrides, duration_s=DURATION_S)


def _bag(tmp_path_factory, *overrides: str):
    scenario = _scenario(*overrides)
    path = tmp_path_factory.mktemp("aided") / "bag"
    summary = generate_dataset(scenario, path)
    return scenario, summary.cycles, bag_batches(path, aided_input_topics(scenario))


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    return _bag(tmp_path_factory)


@pytest.fixture(scope="module")
def plain_out(plain):
    scenario, _, batches = plain
    return run_stage(scenario, [batches])


def _replace(batches: list[Batch], topic: str, index: int, change) -> list[Batch]:
    """The batches with message ``index`` of ``topic`` decoded, changed and re-serialized
    (``change`` returning None: the message removed)."""
    out = []
    for b in batches:
        if b.topic != topic:
            out.append(b)
            continue
        f = cdr.deserialize(b.msgtype, [b.payloads[index]])
        new = change(f)
        payloads = list(b.payloads)
        stamps = list(np.asarray(b.stamps_ns))
        if new is None:
            del payloads[index], stamps[index]
        else:
            payloads[index] = cdr.serialize(new)[0]
        out.append(Batch(b.topic, b.msgtype, np.array(stamps, dtype=np.int64), payloads))
    return out


def _vec(out, topic):
    return cdr.deserialize(cdr.VECTOR3_STAMPED, out[topic][0])


def test_counts_and_types(plain, plain_out):
    scenario, cycles, _ = plain
    assert {k: len(v[0]) for k, v in plain_out.items()} == aided_expected_counts(scenario, cycles)
    types = aided_topic_types(scenario)
    assert set(types) == set(plain_out)
    assert types["/aided/odom"] == cdr.ODOMETRY and types["/aided/fix"] == cdr.NAVSATFIX
    assert types["/aided/vel"] == cdr.TWIST_WITH_COVARIANCE_STAMPED
    assert types["/aided/nis/mag"] == cdr.VECTOR3_STAMPED


def test_gate_rejects_a_fix_100_m_off(plain, plain_out):
    scenario, _, batches = plain
    index = 30

    def move(f):
        # 100 m north: Δφ = 100 m / (R_N + h); the aiding is well below 1 m here
        f.latitude[0] += math.degrees(100.0 / 6.3674e6)
        return f

    moved = _replace(batches, "/gnss/fix", index, move)
    fix = cdr.deserialize(cdr.NAVSATFIX, [p for b in batches if b.topic == "/gnss/fix"
                                          for p in b.payloads][index : index + 1])  # fmt: skip
    stamp = int(fix.stamps_ns[0])
    warnings: list[str] = []
    out = run_stage(scenario, [moved], warn=warnings.append)
    nis = _vec(out, "/aided/nis/gnss_position")
    v = np.asarray(nis.vector)
    rejected = np.flatnonzero(v[:, 2] == 0.0)
    assert np.asarray(nis.stamps_ns)[rejected].tolist() == [stamp]
    assert v[rejected[0], 0] > 1e3  # NIS of a 100 m error against a ~1 m σ
    assert v[rejected[0], 1] == 3.0
    sec = f"{stamp // 1_000_000_000}.{stamp % 1_000_000_000:09d}"
    assert [w for w in warnings if "rejected by the χ² gate" in w and sec in w]
    # the normal fixes (with and without the moved one) pass the gate
    assert np.all(np.asarray(_vec(plain_out, "/aided/nis/gnss_position").vector)[:, 2] == 1.0)


@pytest.mark.parametrize("latency_s", [0.05, 0.0123])
def test_latency_is_exact(tmp_path_factory, plain, plain_out, latency_s):
    """Delayed GNSS: its innovations equal the zero-latency run's bit for bit (first
    application with the same earlier measurements), as do the outputs at the epochs whose
    inputs are the same (no GNSS epoch in (t - latency, t])."""
    scenario, _, batches = _bag(tmp_path_factory, f"aiding.gnss.latency_s={latency_s}")
    out = run_stage(scenario, [batches])
    lat_ns = round(latency_s * 1e9)
    for topic in ("/aided/innovation/gnss_position", "/aided/nis/gnss_velocity"):
        pay, log = out[topic]
        ref_pay, ref_log = plain_out[topic]
        k = len(pay)
        assert k >= len(ref_pay) - 1 and k > 10
        assert pay == ref_pay[:k]
        np.testing.assert_array_equal(np.array(log), np.array(ref_log[:k]) + lat_ns)
    odom = cdr.deserialize(cdr.ODOMETRY, out["/aided/odom"][0])
    stamps = np.asarray(odom.stamps_ns)
    period = 200_000_000  # GNSS epochs
    same = (stamps % period) >= lat_ns
    same &= stamps <= stamps[-1] - period  # the last fix of the run is never released
    assert same.sum() > 20 and (~same).sum() > 20
    for topic in ("/aided/odom", "/aided/fix", "/aided/error/position", "/aided/nees"):
        pay = np.array(out[topic][0], dtype=object)
        ref = np.array(plain_out[topic][0], dtype=object)
        assert list(pay[same]) == list(ref[same]), topic
        assert list(pay[~same]) != list(ref[~same]), topic  # the others do differ


def _interleaved(batches: list[Batch], seed: int) -> list[list[Batch]]:
    """The topics' messages in random chunk sizes, the topics interleaved at random (each
    topic in its own order), one topic per call."""
    rng = np.random.default_rng(seed)
    pos = {b.topic: 0 for b in batches}
    by = {b.topic: b for b in batches}
    calls = []
    while any(pos[t] < len(by[t].payloads) for t in pos):
        t = rng.choice([t for t in pos if pos[t] < len(by[t].payloads)])
        n = int(rng.integers(1, 400))
        a, b = pos[t], min(pos[t] + n, len(by[t].payloads))
        calls.append([Batch(t, by[t].msgtype, np.asarray(by[t].stamps_ns)[a:b],
                            by[t].payloads[a:b])])  # fmt: skip
        pos[t] = b
    return calls


def test_output_does_not_depend_on_chunking_or_interleaving(tmp_path_factory):
    scenario, _, batches = _bag(tmp_path_factory, "aiding.gnss.latency_s=0.0123",
                                "duration_s=6")  # fmt: skip
    whole = run_stage(scenario, [batches])
    one_by_one = run_stage(scenario, in_log_order(batches, 1))
    assert one_by_one == whole
    for seed in (1, 2):
        assert run_stage(scenario, _interleaved(batches, seed)) == whole


def test_nan_or_repeated_measurement_is_dropped(plain, plain_out):
    scenario, _, batches = plain
    index = 40
    baro = [p for b in batches if b.topic == "/baro/pressure" for p in b.payloads]
    stamp = int(cdr.deserialize(cdr.FLUID_PRESSURE, baro[index : index + 1]).stamps_ns[0])

    def nan(f):
        f.fluid_pressure[0] = np.nan
        return f

    warnings: list[str] = []
    out = run_stage(scenario, [_replace(batches, "/baro/pressure", index, nan)],
                    warn=warnings.append)  # fmt: skip
    without = run_stage(scenario, [_replace(batches, "/baro/pressure", index, lambda f: None)])
    assert out == without
    assert stamp not in np.asarray(_vec(out, "/aided/nis/baro").stamps_ns)
    sec = f"{stamp // 1_000_000_000}.{stamp % 1_000_000_000:09d}"
    assert [w for w in warnings if "NaN" in w and sec in w]
    # a repeated message (sent twice) is dropped as out of order
    twice = [b if b.topic != "/baro/pressure" else Batch(
        b.topic, b.msgtype, np.concatenate([b.stamps_ns[: index + 1], b.stamps_ns[index:]]),
        [*b.payloads[: index + 1], *b.payloads[index:]]) for b in batches]  # fmt: skip
    warnings.clear()
    assert run_stage(scenario, in_log_order(twice, 500), warn=warnings.append) == plain_out
    assert [w for w in warnings if "not after" in w and sec in w]


def test_imu_gap_stops_the_filter(plain, plain_out):
    scenario, _, batches = plain
    index = 1000  # cycle 1001, t0 + 5.005 s
    errors: list[str] = []
    out = run_stage(scenario, [_replace(batches, "/reference/imu_measured", index,
                                        lambda f: None)], error=errors.append)  # fmt: skip
    assert [e for e in errors if "IMU gap" in e]
    odom = cdr.deserialize(cdr.ODOMETRY, out["/aided/odom"][0])
    gap = scenario.start_time_ns + (index + 1) * scenario.period_ns
    assert np.asarray(odom.stamps_ns).max() < gap
    k = len(out["/aided/odom"][0])
    assert out["/aided/odom"][0] == plain_out["/aided/odom"][0][:k]


def test_covariance_is_symmetric_positive_definite_at_every_output(plain):
    scenario, _, batches = plain
    seen = []

    class Recording(AidedStage):
        def _state_fields(self, snaps):
            seen.append(snaps.p.copy())
            return super()._state_fields(snaps)

    stage = Recording(scenario)
    stage.feed_batches(batches)
    stage.flush()
    p = np.concatenate(seen)
    assert len(p) == int(DURATION_S * 10) + 1
    np.testing.assert_array_equal(p, np.swapaxes(p, -1, -2))
    np.linalg.cholesky(p)  # raises if one is not positive definite


def test_topic_plans_match_the_output(plain, plain_out):
    """The chain rows (count, first and last stamp) describe what the stage published."""
    scenario, cycles, _ = plain
    rows = aided_topic_plans(scenario, cycles)
    assert {r.topic for r in rows} == set(plain_out)
    for row in rows:
        payloads, log = plain_out[row.topic]
        assert len(payloads) == row.count, row.topic
        stamps = np.asarray(cdr.deserialize(row.msgtype, payloads).stamps_ns)
        np.testing.assert_array_equal(np.asarray(log) - stamps, row.log_delay_ns)
        if row.first_ns is not None:
            assert (int(stamps[0]), int(stamps[-1])) == (row.first_ns, row.last_ns), row.topic
