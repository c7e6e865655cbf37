"""Sensor timing errors (config/timing.py, core/timing.py, stages/timing.py) from bags on disk:
the same scenario generated with and without its ``timing`` section (same seeds), compared
message by message."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.core.timing import TimingModel, accumulate_dropped
from strapdown_ros.generate import generate_dataset
from strapdown_ros.plan import resolve_plan

T = 10_000_000
T0 = 1_767_225_600_000_000_000

SCENARIO = """
name: timing_test
rate_hz: 100
duration_s: 4
start_time_s: 1767225600.0
initial: {latitude_deg: 52.52, longitude_deg: 13.405, altitude_m: 34.0,
          velocity_ned_mps: [10.0, 0.0, 0.0], attitude_rph_deg: [0.0, 0.0, 0.0]}
trajectory: {kind: segments, segments: [{duration_s: 4, heading_rate_dps: 10, transition_s: 1}]}
variation: {}
imu_errors: {preset: tactical, seed: 3}
aiding:
  gnss: {preset: spp, rate_hz: 5, seed: 1, outages: [[2, 2.5]]}
  wheel_odometer: {preset: abs_sensor, rate_hz: 10, seed: 2}
timing:
  imu: {drops_s: [1.0, 1.01, 2.5], dropped_increment: accumulated}
  gnss: {offset_s: 0.05, drift_ppm: 100, jitter_s: 0.002, latency_s: 0.1, seed: 4}
  wheel_odometer: {drop_probability: 0.2, latency_s: 0.02, seed: 5}
"""


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("timing")
    path = root / "timing.yaml"
    path.write_text(SCENARIO)
    out = {}
    for name, sets in (("on", []), ("off", ["timing=null"]),
                       ("lost", ["timing.imu.dropped_increment=lost"])):  # fmt: skip
        scenario = load_scenario(path, sets)
        generate_dataset(scenario, root / name)
        out[name] = root / name
    out["scenario"] = path
    return out


@pytest.mark.slow
def test_dropped_imu_samples_leave_doubled_intervals_and_accumulate(bags) -> None:
    """Drops at 1.00, 1.01 and 2.50 s: the next messages follow a 3 T and a 2 T interval; with
    ``accumulated`` their rate × interval is the sum of the untimed increments (1e-17 rad
    measured), with ``lost`` the next message is the untimed one, bit for bit."""
    on, off, lost = (read_bag(bags[k], ["/variation/imu_measured"])["/variation/imu_measured"]
                     for k in ("on", "off", "lost"))  # fmt: skip
    gone = np.setdiff1d(off.stamps_ns, on.stamps_ns)
    assert ((gone - T0) / 1e9).tolist() == [1.0, 1.01, 2.5]
    assert np.array_equal(on.stamps_ns, lost.stamps_ns)
    gaps = np.diff(on.stamps_ns)
    assert sorted(gaps[gaps != T].tolist()) == [2 * T, 3 * T]
    index = {t: i for i, t in enumerate(off.stamps_ns.tolist())}
    for t, n in ((T0 + 102 * T, 3), (T0 + 251 * T, 2)):
        i = int(np.searchsorted(on.stamps_ns, t))
        j = index[t]
        dt = (on.stamps_ns[i] - on.stamps_ns[i - 1]) * 1e-9
        assert dt == pytest.approx(n * T * 1e-9, abs=0)
        for field in ("angular_velocity", "linear_acceleration"):
            summed = np.asarray(getattr(off, field))[j - n + 1 : j + 1].sum(axis=0) * T * 1e-9
            got = np.asarray(getattr(on, field))[i] * dt
            assert np.abs(got - summed).max() <= 1e-15 * max(1.0, np.abs(summed).max())
            assert np.array_equal(np.asarray(getattr(lost, field))[i],
                                  np.asarray(getattr(off, field))[j])
    # every other message is untouched
    keep = np.isin(off.stamps_ns, on.stamps_ns) & ~np.isin(off.stamps_ns, [T0 + 102 * T,
                                                                            T0 + 251 * T])
    mine = np.isin(on.stamps_ns, off.stamps_ns[keep])
    assert np.array_equal(np.asarray(on.angular_velocity)[mine],
                          np.asarray(off.angular_velocity)[keep])


@pytest.mark.slow
def test_gnss_stamps_offset_drift_jitter_and_latency(bags) -> None:
    """stamp − t = 50 ms + 100 ppm (t − t0) + jitter (2 ms): the residual after the offset and
    drift has a spread of 2 ms (18 draws: 1.2 .. 2.8 ms) and mean ~0 (|mean| < 1.5 ms); the
    log time is t + 100 ms; the fix's content is the untimed one."""
    on, off = (read_bag(bags[k], ["/gnss/fix", "/gnss/vel"]) for k in ("on", "off"))
    a, b = on["/gnss/fix"], off["/gnss/fix"]
    assert len(a) == len(b) == 18
    t = np.asarray(b.stamps_ns)
    jitter = (a.stamps_ns - t) - 50_000_000 - np.rint(100e-6 * (t - T0))
    assert 1.2e6 < np.std(jitter) < 2.8e6 and abs(np.mean(jitter)) < 1.5e6
    assert np.array_equal(on.topics["/gnss/fix"].log_time_ns - t, np.full(len(t), 100_000_000))
    assert np.array_equal(a.latitude, b.latitude) and np.array_equal(a.altitude, b.altitude)
    assert np.array_equal(on["/gnss/vel"].stamps_ns, a.stamps_ns)  # one receiver, one clock


@pytest.mark.slow
def test_wheel_drops_and_latency_and_the_truth_untouched(bags) -> None:
    """20 % drops of the wheel odometer (41 → 33 messages with seed 5), each kept one 20 ms
    late in the bag; the truth and the ideal IMU streams are identical with and without timing;
    the plan's counts are what the bag holds."""
    on, off = read_bag(bags["on"]), read_bag(bags["off"])
    w, x = on["/wheel/twist"], off["/wheel/twist"]
    assert (len(x), len(w)) == (41, 33)
    assert np.isin(w.stamps_ns, x.stamps_ns).all()
    assert np.array_equal(on.topics["/wheel/twist"].log_time_ns - w.stamps_ns,
                          np.full(len(w), 20_000_000))  # fmt: skip
    for topic in ("/reference/odom", "/reference/imu", "/variation/odom", "/variation/imu"):
        assert on[topic].equals(off[topic]), topic
    plan = resolve_plan(load_scenario(bags["scenario"]))
    assert {t: len(d) for t, d in on.topics.items()} == plan.counts()


def test_timing_model_draws_do_not_depend_on_the_pieces() -> None:
    """A sample's stamp and drop verdict are the same whether it comes alone or in a batch."""
    m = TimingModel(T0, T, T0, 7, 50.0, 1e-3, 0, 0.3, (T0 + 5 * T,), seed=9)
    t = T0 + np.arange(1, 9000) * T
    whole = m.stamps(t), m.dropped(t)
    fresh = TimingModel(T0, T, T0, 7, 50.0, 1e-3, 0, 0.3, (T0 + 5 * T,), seed=9)
    parts = [fresh.stamps(t[i : i + 1000]) for i in range(0, t.size, 1000)]
    assert np.array_equal(whole[0], np.concatenate(parts))
    assert whole[1][4] and 0.27 < whole[1].mean() < 0.33


def test_accumulate_dropped_carries_over_pieces() -> None:
    """Dropped rows add into the next kept row, across calls."""
    da = np.arange(12.0).reshape(4, 3)
    drop = np.array([False, True, False, True])
    a, v, n, pending = accumulate_dropped(da, -da, drop, None)
    assert a.tolist() == [[0, 1, 2], [9, 11, 13]] and n.tolist() == [1, 2]
    assert pending is not None and pending[2] == 1
    a2, _, n2, rest = accumulate_dropped(np.ones((1, 3)), np.ones((1, 3)), np.array([False]),
                                         pending)  # fmt: skip
    assert a2.tolist() == [[10, 11, 12]] and n2.tolist() == [2] and rest is None


def test_timing_of_a_missing_sensor_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO)
    with pytest.raises(ScenarioError, match="timing.barometer"):
        resolve_plan(load_scenario(path, ["timing.barometer={latency_s: 0.1}"]))
    with pytest.raises(ScenarioError, match="timing.imu.jitter_s"):
        load_scenario(path, ["timing.imu.jitter_s=-1"])
