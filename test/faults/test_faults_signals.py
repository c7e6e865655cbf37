"""Stop signals other than Ctrl-C, as processes: SIGTERM (what ``kill``, systemd, docker and
launch send) and SIGHUP (a closed terminal) to ``strapdown-sim generate``, ``run`` and
``campaign`` and to a node stop them like Ctrl-C: children stopped, temporary bags
(``.bag.tmp-*``) and spools (``/dev/shm/strapdown-generate-*``) removed, the destination
complete or absent, no traceback, no process left. SIGKILL of ``generate`` cannot be handled,
but its forked producer dies with it and removes its spool (docs/reliability.md).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_faults_cli import CLI, NEUTRAL, SCENARIO, _env, _no_traceback, _processes_with  # noqa: E402

#: Every case starts strapdown-sim or a node (seconds of CPU each): out of make test-fast.
pytestmark = pytest.mark.slow

STOPS = [signal.SIGTERM, signal.SIGHUP]
IDS = [s.name for s in STOPS]
SPOOL_ROOTS = [Path("/dev/shm"), Path(tempfile.gettempdir())]  # noqa: S108 - only listed


def _spools(pid: int) -> list[Path]:
    """Spool directories of the ``generate`` process ``pid``."""
    return [d for root in SPOOL_ROOTS if root.is_dir()
            for d in root.glob(f"strapdown-generate-{pid}-*")]  # fmt: skip


def _start(args: list[str], env: dict[str, str], err_path: Path) -> subprocess.Popen:
    with open(err_path, "w") as err:
        return subprocess.Popen(
            [sys.executable, "-c", CLI, *args], stdout=subprocess.DEVNULL, stderr=err,
            cwd=NEUTRAL, env=env, start_new_session=True,
        )  # fmt: skip


def _wait_text(path: Path, text: str, proc: subprocess.Popen, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while text not in path.read_text(errors="replace"):
        if proc.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"no '{text}' before the signal:\n{path.read_text(errors='replace')}")
        time.sleep(0.1)


def _stop(proc: subprocess.Popen, sig: int, timeout: float = 120.0) -> int:
    """``sig`` to the process only (as ``kill PID`` does, not to its group); its exit status."""
    proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        pytest.fail(f"the command did not stop after {signal.Signals(sig).name}")


def _no_process_left(marker: str, grace_s: float = 10.0) -> None:
    deadline = time.monotonic() + grace_s
    while _processes_with(marker.encode()):
        if time.monotonic() > deadline:
            pytest.fail(f"processes left: {_processes_with(marker.encode())}")
        time.sleep(0.2)


def _generate(tmp_path: Path) -> tuple[subprocess.Popen, Path, Path, dict[str, str]]:
    env = _env()
    env["FAULTS_TMP"] = str(tmp_path)
    out, err = tmp_path / "bag", tmp_path / "stderr.txt"
    proc = _start(["generate", str(SCENARIO), "--out", str(out)], env, err)
    deadline = time.monotonic() + 120
    while not (_spools(proc.pid) and any(tmp_path.glob(".bag.tmp-*"))):
        if proc.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"generate did not start writing:\n{err.read_text()}")
        time.sleep(0.05)
    time.sleep(1.0)  # pieces in flight
    return proc, out, err, env


@pytest.mark.parametrize("sig", STOPS, ids=IDS)
def test_generate_stopped(tmp_path, sig) -> None:
    """Why: SIGTERM left the forked producer alive and blocked, a half-written ``.bag.tmp-*``
    and a spool of hundreds of MB in /dev/shm. Now as Ctrl-C: exit 128 + signal, nothing at
    the destination, no temporary file, spool or process."""
    proc, out, err, _ = _generate(tmp_path)
    rc = _stop(proc, sig)
    text = err.read_text(errors="replace")
    _no_traceback(text)
    assert rc == 128 + sig and f"stopped by {sig.name}" in text, text
    assert "nothing written" in text, text
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stderr.txt"], list(tmp_path.iterdir())
    assert not _spools(proc.pid)
    _no_process_left(f"FAULTS_TMP={tmp_path}")


def test_generate_killed_producer_follows(tmp_path) -> None:
    """SIGKILL of ``generate`` (nothing can be handled in it): the forked producer dies too
    (``PR_SET_PDEATHSIG``) and removes its spool; the destination is absent (only the
    temporary bag is left, which ``generate --force`` or a new output replaces)."""
    proc, out, err, _ = _generate(tmp_path)
    workers = [p for p in _processes_with(f"FAULTS_TMP={tmp_path}".encode()) if p != proc.pid]
    assert workers, "no producer process seen"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    _no_process_left(f"FAULTS_TMP={tmp_path}", grace_s=30.0)
    assert not _spools(proc.pid)
    assert not out.exists()


#: A parent whose producer never finishes a piece (blocked in a sleep): prints the worker's
#: pid and the spool, then waits to be killed.
BLOCKED_PRODUCER = """
import time
from strapdown_ros.producer import Producer

def items():
    time.sleep(3600)
    yield None

p = Producer(items())
print(p._worker.pid, p._spool, flush=True)
time.sleep(3600)
"""


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_producer_dies_with_its_parent(tmp_path, sig) -> None:
    """The forked producer of a parent killed by anything (SIGKILL, or SIGTERM without a
    handler in the parent) ends within seconds and removes its spool, even when it is blocked
    (here: in a sleep; before, it lived on for good)."""
    env = _env()
    env["FAULTS_TMP"] = str(tmp_path)
    proc = subprocess.Popen([sys.executable, "-c", BLOCKED_PRODUCER], stdout=subprocess.PIPE,
                            text=True, cwd=NEUTRAL, env=env, start_new_session=True)  # fmt: skip
    try:
        worker, spool = proc.stdout.readline().split()
        assert Path(spool).is_dir() and Path(f"/proc/{worker}").exists()
        os.kill(proc.pid, sig)
        proc.wait(timeout=30)
        _no_process_left(f"FAULTS_TMP={tmp_path}")
        assert not Path(spool).exists(), spool
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.parametrize("sig", STOPS, ids=IDS)
def test_run_stopped(tmp_path, ros_env, sig) -> None:
    """``run`` stopped by SIGTERM/SIGHUP: the nodes are stopped in order, the bag is closed and
    readable, exit 128 + signal, no traceback in any log, no process left."""
    from strapdown_ros.bag.reader import read_bag

    env = _env(ros_env)
    env["FAULTS_TMP"] = str(tmp_path)
    out, err = tmp_path / "bag", tmp_path / "stderr.txt"
    proc = _start(["run", str(SCENARIO), "--duration", "60", "--out", str(out)], env, err)
    _wait_text(err, "trajectory_node", proc, 240)
    time.sleep(4.0)
    rc = _stop(proc, sig)
    text = err.read_text(errors="replace")
    _no_traceback(text)
    assert rc == 128 + sig and f"stopped by {sig.name}" in text, text
    read_bag(out)  # closed and readable
    for log in (tmp_path / "bag.logs").glob("*.log"):
        _no_traceback(log.read_text(errors="replace"))
    assert not list(tmp_path.glob("*.tmp-*"))
    _no_process_left(f"FAULTS_TMP={tmp_path}")


def _campaign(tmp_path: Path, runs: int, stderr: str) -> tuple[subprocess.Popen, Path, Path]:
    env = _env()
    env["FAULTS_TMP"] = str(tmp_path)
    out, err = tmp_path / "campaign", tmp_path / stderr
    args = ["campaign", str(SCENARIO), "--runs", str(runs), "--duration", "20", "--out",
            str(out), "--workers", "2"]  # fmt: skip
    proc = _start(args, env, err)
    deadline = time.monotonic() + 240
    while not (out / "runs").is_dir() or not any((out / "runs").glob("*/summary.json")):
        if proc.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"the campaign finished no run:\n{err.read_text()}")
        time.sleep(0.2)
    return proc, out, err


@pytest.mark.parametrize("how", ["SIGINT-group", "SIGTERM"])
def test_campaign_stopped(tmp_path, how) -> None:
    """Why: Ctrl-C on a campaign gave a ``KeyboardInterrupt`` traceback from every Dask worker
    (they got the terminal's SIGINT) and the closing message called the campaign directory
    "the bag ... closed and readable". Now the workers ignore the terminal's SIGINT (the client
    stops them), the message names the directory and how to resume, nothing is left."""
    proc, out, err = _campaign(tmp_path, 60, "stderr.txt")
    if how == "SIGINT-group":  # Ctrl-C in a terminal: the whole foreground process group
        os.killpg(proc.pid, signal.SIGINT)
        rc, want = proc.wait(timeout=120), 130
    else:
        rc, want = _stop(proc, signal.SIGTERM), 128 + signal.SIGTERM
    text = err.read_text(errors="replace")
    _no_traceback(text)
    assert "KeyboardInterrupt" not in text, text
    assert rc == want, text
    assert f"the campaign directory {out} keeps its" in text, text
    assert "run the same command again" in text and "bag" not in text.split("keeps its")[1], text
    _no_process_left(f"FAULTS_TMP={tmp_path}", grace_s=20.0)


@pytest.mark.parametrize(
    ("name", "sig"),
    [("navigator_node", signal.SIGTERM), ("navigator_node", signal.SIGHUP),
     ("variation_node", signal.SIGHUP), ("aiding_node", signal.SIGHUP),
     ("imu_model_node", signal.SIGHUP)],
    ids=lambda v: v if isinstance(v, str) else signal.Signals(v).name,
)  # fmt: skip
def test_node_stopped(tmp_path, ros_env, name, sig) -> None:
    """A node waiting for input (none comes: a private ROS domain): SIGTERM and SIGHUP end it
    with status 0 and no traceback (SIGHUP killed it before, without its summary)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import node_testing as nt

    node = nt.Proc(
        nt.node_args(name, f"scenario:={SCENARIO}", "idle_timeout_s:=60"),
        ros_env, tmp_path, name,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        node.wait_for(r"subscribed to ", deadline)
        node.proc.send_signal(sig)
        assert node.wait(time.monotonic() + 20) == 0, node.describe()
        assert "Traceback" not in node.output, node.describe()
    finally:
        node.kill()
