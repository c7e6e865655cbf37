"""The player's /clock schedule and its pacing warnings, without ROS (bag/playback.py)."""

from __future__ import annotations

from strapdown_ros.bag.playback import ClockTicks, PacingWatch


def test_clock_ticks_once_per_period_of_bag_time():
    ticks = ClockTicks(100, 1000)
    times = [1000, 1000, 1050, 1099, 1100, 1180, 1350, 1351, 1400]
    assert [t for t in times if ticks.due(t)] == [1000, 1100, 1350, 1400]
    every = ClockTicks(0, 0)  # every new log time
    assert [t for t in [5, 5, 6, 7, 7] if every.due(t)] == [5, 6, 7]
    ticks.restart(1000)  # a loop pass starts over
    assert ticks.due(1000)


def test_pacing_watch_warns_at_once_then_at_most_once_an_interval():
    watch = PacingWatch(0.010, interval_s=1.0)
    assert watch.observe(0.005, 0.0) is None
    first = watch.observe(0.020, 0.1)  # the first late publication is told at once
    assert first is not None and "1 message(s)" in first and "worst 20.0 ms" in first
    assert watch.observe(0.030, 0.2) is None and watch.observe(0.012, 0.9) is None
    later = watch.observe(0.011, 1.3)  # an interval after the first untold one
    assert later is not None and "3 message(s)" in later and "worst 30.0 ms" in later
    assert watch.observe(0.001, 5.0) is None  # nothing pending
    assert PacingWatch(0.0).observe(10.0, 0.0) is None  # off
