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
    """This process's spool directories (other test workers may run a generate meanwhile)."""
    roots = [Path("/dev/shm"), Path(os.environ.get("TMPDIR", "/tmp"))]  # noqa: S108
    return {
        str(p) for r in roots if r.is_dir()
        for p in r.glob(f"strapdown-generate-{os.getpid()}-*")
    }  # fmt: skip


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


def test_spool_root_needs_free_space(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A small /dev/shm (containers mount 64 MB) is not used: the temporary directory is."""
    from strapdown_ros import producer

    assert producer._spool_root(str(tmp_path / "missing")) is None
    assert producer._spool_root(str(tmp_path)) in (str(tmp_path), None)
    monkeypatch.setattr(producer, "SHM_MIN_FREE", 1 << 62)  # more than any disk
    assert producer._spool_root(str(tmp_path)) is None
    monkeypatch.setattr(producer, "SHM_MIN_FREE", 0)
    assert producer._spool_root(str(tmp_path)) == str(tmp_path)
    # and the producer works from the fallback
    monkeypatch.setattr(producer, "SHM_MIN_FREE", 1 << 62)
    p = Producer(iter([_piece(0)]))
    try:
        (got,) = list(p)
    finally:
        p.close()
    assert list(got.batches[0].payloads) == list(_piece(0).batches[0].payloads)


def test_spool_of_a_killed_generate_is_removed(tmp_path: Path) -> None:
    """A generate killed with SIGKILL leaves its spool; the next one removes it (dead pid only)."""
    import subprocess
    import sys

    from strapdown_ros import producer

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    stale = tmp_path / f"strapdown-generate-{dead.stdout.strip()}-abc"
    alive = tmp_path / f"strapdown-generate-{os.getppid()}-abc"
    for d in (stale, alive):
        d.mkdir()
        (d / "piece0.bin").write_bytes(b"x" * 10)
    producer._remove_stale_spools(tmp_path)
    assert not stale.exists() and alive.exists()


_STOPPED_AT_ONCE = """
import os, signal, sys, time
from strapdown_ros.producer import Producer

class Stopped(KeyboardInterrupt):
    pass

def stop(signum, frame):  # a command's handler, as strapdown_ros.cli installs it
    raise Stopped(signum)

signal.signal(signal.SIGTERM, stop)
os.register_at_fork(after_in_child=lambda: time.sleep(0.3))  # widen the fork's window
p = Producer(iter([]))
p.close()  # SIGTERM reaches the child before it has its own handler
print("closed", p._worker.exitcode)
"""


def test_a_worker_stopped_right_after_the_fork_prints_no_traceback() -> None:
    """Why: a generate stopped at once (read-only destination) printed the worker's traceback
    ``Process ForkProcess-1: ... Stopped: SIGTERM``: the child ran the parent's handler."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", _STOPPED_AT_ONCE], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "Stopped" not in proc.stderr, proc.stderr
    assert proc.stdout.split() == ["closed", str(128 + 15)]


@pytest.mark.parametrize("setting", [None, "thread"])
def test_thread_setting_runs_the_items_in_this_process(setting, monkeypatch) -> None:
    """``STRAPDOWN_PRODUCER=thread`` (the mutation runs): the items run in the calling process;
    otherwise (Linux) in a forked worker."""
    from strapdown_ros.producer import THREAD_ENV

    if setting is None:
        monkeypatch.delenv(THREAD_ENV, raising=False)
    else:
        monkeypatch.setenv(THREAD_ENV, setting)
    pids = []

    def items():
        for k in range(2):
            pids.append(os.getpid())  # only a thread's appends reach this list
            yield _piece(k)

    producer = Producer(items())
    try:
        assert [p.cycles for p in producer] == [1, 2]
    finally:
        producer.close()
    assert pids == ([os.getpid()] * 2 if setting else [])
