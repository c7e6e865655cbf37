"""generate's producer: pieces computed in a forked worker arrive unchanged, the spool is removed.

The payloads cross the process boundary through a spool file (docs/benchmarks.md); these tests
check that what the writing process receives is equal, object type included, to what the
worker computed, for fixed-size and variable-size payloads and empty batches, that at most
``depth`` pieces are in flight, and that nothing is left on disk after an error.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag.batches import Batch
from strapdown_ros.producer import Piece, Producer


def _piece(k: int) -> Piece:
    rng = np.random.default_rng(k)
    fixed = [rng.bytes(52) for _ in range(1000 + k)]
    varying = [rng.bytes(int(n)) for n in rng.integers(0, 300, 257)]
    batches = [
        Batch("/a", "sensor_msgs/msg/Imu", np.arange(len(fixed), dtype=np.int64) + k, fixed),
        Batch("/b", "tf2_msgs/msg/TFMessage", np.arange(257, dtype=np.int64), varying),
        Batch("/c", "nav_msgs/msg/Odometry", np.zeros(0, dtype=np.int64), []),
    ]
    return Piece(k + 1, {"reference": np.full(3, float(k))}, batches, {"pos_m": 0.5 * k})


def _spool_dirs() -> set[str]:
    roots = [Path("/dev/shm"), Path(os.environ.get("TMPDIR", "/tmp"))]  # noqa: S108
    return {
        str(p) for r in roots if r.is_dir() for p in r.glob("strapdown-generate-*")
    }


def test_pieces_arrive_equal() -> None:
    before = _spool_dirs()
    expected = [_piece(k) for k in range(5)]
    producer = Producer(iter([_piece(k) for k in range(5)]))
    try:
        got = list(producer)
    finally:
        producer.close()
    assert len(got) == len(expected)
    for g, e in zip(got, expected, strict=True):
        assert g.cycles == e.cycles and g.nav_errors == e.nav_errors
        assert np.array_equal(g.residuals["reference"], e.residuals["reference"])
        for gb, eb in zip(g.batches, e.batches, strict=True):
            assert (gb.topic, gb.msgtype) == (eb.topic, eb.msgtype)
            assert np.array_equal(gb.stamps_ns, eb.stamps_ns)
            assert list(gb.payloads) == list(eb.payloads)
            assert all(type(p) is bytes for p in gb.payloads)
    assert _spool_dirs() == before


def _failing():
    yield _piece(0)
    raise ValueError("bad piece 1")


def test_error_in_worker_reaches_the_caller_and_spool_is_removed() -> None:
    before = _spool_dirs()
    producer = Producer(_failing())
    try:
        it = iter(producer)
        assert next(it).cycles == 1
        with pytest.raises(ValueError, match="bad piece 1"):
            next(it)
    finally:
        producer.close()
    assert _spool_dirs() == before


def test_close_mid_run_removes_spooled_pieces() -> None:
    before = _spool_dirs()
    producer = Producer(iter([_piece(k) for k in range(6)]), depth=2)
    it = iter(producer)
    next(it)  # the worker runs ahead by at most `depth` pieces, then waits
    producer.close()
    assert _spool_dirs() == before
