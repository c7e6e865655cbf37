"""The nodes' shared helpers that need no ROS graph: input batches and pacing.

:class:`~strapdown_ros.nodes.batching.InputBatch` decides when a node processes what its
callbacks buffered: after a quiet spin (a 200 Hz cycle has arrived: processed at once) or when
the oldest message has waited ``period_s`` (kHz input keeps coming: batches). Driven here with a
fake ``spin`` that delivers scripted messages and advances nothing but the real clock.
"""

from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")

from strapdown_ros.nodes.batching import InputBatch  # noqa: E402
from strapdown_ros.nodes.pacing import Pacer  # noqa: E402


def _spinner(batch: InputBatch, arrivals: list[int]):
    """A spin that delivers ``arrivals[k]`` messages on its k-th call (then none)."""
    calls = iter(arrivals)

    def spin(timeout_s: float) -> None:
        n = next(calls, 0)
        for _ in range(n):
            batch.add(object())
        if not n:
            time.sleep(timeout_s)

    return spin


def test_quiet_spin_releases_the_batch() -> None:
    batch = InputBatch(period_s=1.0, quiet_s=0.001)
    spin = _spinner(batch, [1, 1, 0])  # a cycle's two messages, then quiet
    batch.spin(spin)
    assert not batch.due()  # a message arrived during this spin: the burst may go on
    batch.spin(spin)
    assert not batch.due()
    batch.spin(spin)
    assert batch.due() and len(batch.take()) == 2
    batch.spin(spin)
    assert not batch.due()  # nothing waits


def test_continuous_input_is_batched_by_period() -> None:
    batch = InputBatch(period_s=0.02, quiet_s=0.002)
    spin = _spinner(batch, [1] * 10_000)  # never quiet
    sizes = []
    start = time.monotonic()
    while time.monotonic() - start < 0.1:
        batch.spin(spin)
        if batch.due():
            sizes.append(len(batch.take()))
        time.sleep(0.001)
    assert 1 <= len(sizes) <= 6  # at most one batch per 20 ms (fewer if the machine stalls)
    assert min(sizes) >= 2  # never a message processed alone while input keeps coming


def test_quiet_never_exceeds_the_period() -> None:
    assert InputBatch(period_s=0.001, quiet_s=0.002).quiet_s == 0.001
    assert InputBatch(period_s=0.01).quiet_s == InputBatch.QUIET_S


def test_pacer_due_times_and_as_fast_as_possible() -> None:
    p = Pacer(2.0, t0_ns=1_000_000_000, start=100.0)
    assert p.due(1_000_000_000) == 100.0 and p.due(3_000_000_000) == pytest.approx(101.0)
    fast = Pacer(0.0, t0_ns=0, start=5.0)
    assert fast.due(10**12) == 5.0
    fast.wait(10**12, spin=lambda t: pytest.fail("must not wait"))


def test_pacer_groups_release_at_the_group_end_never_early() -> None:
    """Groups of 10 ms of data at rate 2: stamp t is released at the due time of
    t0 + ceil((t - t0) / 10 ms) * 10 ms, i.e. (that - t0) / 2 after the start."""
    ms = 1_000_000
    p = Pacer(2.0, t0_ns=7 * ms, start=100.0, group_ns=10 * ms)
    want = {7 * ms: 100.0, 8 * ms: 100.005, 17 * ms: 100.005, 18 * ms: 100.010}
    for stamp, release in want.items():
        assert p.release(stamp) == pytest.approx(release, abs=1e-12)
        assert p.release(stamp) >= p.due(stamp)
    assert Pacer(2.0, t0_ns=7 * ms, start=100.0).release(8 * ms) == p.due(8 * ms)
    with pytest.raises(ValueError, match="group_ns"):
        Pacer(1.0, t0_ns=0, group_ns=-1)


def test_pacer_groups_wake_once_per_group() -> None:
    """40 stamps 1 ms apart in groups of 10 ms, real time: no message goes before its due time
    and the waits end at 5 distinct release times (t0 and 4 group ends)."""
    ms = 1_000_000
    p = Pacer(1.0, t0_ns=0, group_ns=10 * ms)
    released = []
    for stamp in range(0, 40 * ms, ms):
        p.wait(stamp, spin=lambda t: None)
        now = time.monotonic()
        assert now >= p.due(stamp)
        released.append(p.release(stamp))
    assert len(set(released)) == 5
