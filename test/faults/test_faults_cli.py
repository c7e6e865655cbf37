"""Fault injection into the command line: unreadable scenarios, read-only and full file
systems (small tmpfs mounts, unmounted afterwards; skipped where mounting is not allowed),
Ctrl-C, errors in the worker process, bags that are not bags. No traceback may reach the user
(docs/reliability.md).

``STRAPDOWN_FAULTS_CLI_PATH=/path/to/checkout`` runs ``strapdown-sim`` (and the nodes it starts)
from another checkout's package, e.g. the commit before the fixes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: Every case starts strapdown-sim (a few seconds of CPU each): out of make test-fast.
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
CLI = "import sys; from strapdown_ros.cli import main; sys.exit(main())"
#: Working directory of the commands: not the repository, whose package would shadow
#: STRAPDOWN_FAULTS_CLI_PATH's (``python -c`` puts the working directory first on sys.path).
NEUTRAL = "/"


def _env(base: dict[str, str] | None = None) -> dict[str, str]:
    env = dict(os.environ if base is None else base)
    other = os.environ.get("STRAPDOWN_FAULTS_CLI_PATH")
    if other:
        env["PYTHONPATH"] = other + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _cli(*args: str, env: dict[str, str] | None = None, timeout: float = 300):
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], capture_output=True, text=True, cwd=NEUTRAL,
        env=_env(env), timeout=timeout,
    )  # fmt: skip


def _no_traceback(text: str) -> None:
    assert "Traceback" not in text, text


@pytest.fixture
def tmpfs(tmp_path):
    """``mount(size, read_only=False) -> Path``: a small tmpfs, unmounted at teardown."""
    mounted: list[Path] = []

    def mount(size: str, read_only: bool = False) -> Path:
        where = tmp_path / f"mnt{len(mounted)}"
        where.mkdir()
        opts = f"size={size}" + (",ro" if read_only else "")
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(where)],
                              capture_output=True, text=True)  # fmt: skip
        if proc.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], check=False)


# ---------------------------------------------------------------------------------------------
# scenario files
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "content",
    [b"\xff\xfe\x00\x01binary\x00\x00", "rate_hz: 200\nname: caf\xe9\n".encode("latin-1")],
    ids=["binary", "latin-1"],
)
@pytest.mark.parametrize("command", ["validate", "generate"])
def test_scenario_not_text(tmp_path, content, command) -> None:
    path = tmp_path / "scenario.yaml"
    path.write_bytes(content)
    extra = ["--out", str(tmp_path / "bag")] if command == "generate" else []
    proc = _cli(command, str(path), *extra)
    _no_traceback(proc.stderr)
    assert proc.returncode == 2 and "UTF-8" in proc.stderr, proc.stderr


def test_scenario_is_a_directory(tmp_path) -> None:
    proc = _cli("validate", str(tmp_path))
    _no_traceback(proc.stderr)
    assert proc.returncode == 2, proc.stderr


# ---------------------------------------------------------------------------------------------
# destinations
# ---------------------------------------------------------------------------------------------


def test_generate_read_only_destination(tmpfs) -> None:
    """Why (3): generate on a read-only file system printed a traceback."""
    where = tmpfs("1m", read_only=True)
    proc = _cli("generate", str(SCENARIO), "--duration", "2", "--out", str(where / "bag"),
                "--quiet")  # fmt: skip
    _no_traceback(proc.stderr)
    assert proc.returncode == 1 and "read-only" in proc.stderr, proc.stderr


def test_generate_full_disk(tmpfs) -> None:
    """Why (3): generate on a full file system printed a traceback; nothing half-written may be
    left."""
    where = tmpfs("2m")
    proc = _cli("generate", str(SCENARIO), "--duration", "60", "--out", str(where / "bag"),
                "--quiet")  # fmt: skip
    _no_traceback(proc.stderr)
    assert proc.returncode == 1 and "disk is full" in proc.stderr, proc.stderr
    assert os.listdir(where) == [], os.listdir(where)


# ---------------------------------------------------------------------------------------------
# Ctrl-C
# ---------------------------------------------------------------------------------------------


def _interrupt(args: list[str], after: float, env: dict[str, str], tmp_path: Path,
               wait_for: str | None = None, timeout: float = 240.0) -> str:  # fmt: skip
    """Start ``strapdown-sim args`` in its own session (``FAULTS_TMP`` = ``tmp_path``, which
    receives its stderr.txt), press Ctrl-C (SIGINT to its process group) ``after`` s (after
    ``wait_for`` appears on stderr, if given); check that it stopped with status 130 saying
    "interrupted", without a traceback; return its stderr."""
    env["FAULTS_TMP"] = str(tmp_path)
    err_path = tmp_path / "stderr.txt"
    with open(err_path, "w") as err:
        proc = subprocess.Popen(
            [sys.executable, "-c", CLI, *args], stdout=subprocess.DEVNULL, stderr=err,
            cwd=NEUTRAL, env=env, start_new_session=True,
        )  # fmt: skip
    deadline = time.monotonic() + timeout
    if wait_for:
        while wait_for not in err_path.read_text(errors="replace"):
            if proc.poll() is not None or time.monotonic() > deadline:
                break
            time.sleep(0.1)
    time.sleep(after)
    os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=max(deadline - time.monotonic(), 30))
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        pytest.fail("the command did not stop after Ctrl-C")
    err_text = err_path.read_text(errors="replace")
    _no_traceback(err_text)
    assert proc.returncode == 130 and "interrupted" in err_text, err_text
    return err_text


def _processes_with(marker: bytes) -> list[int]:
    """Pids of live processes whose environment contains ``marker``."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker in (entry / "environ").read_bytes():
                pids.append(int(entry.name))
        except OSError:
            continue
    return pids


def test_generate_ctrl_c(tmp_path) -> None:
    out = tmp_path / "bag"
    _interrupt(["generate", str(SCENARIO), "--out", str(out)], 3.0, _env(), tmp_path)
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["stderr.txt"]
    time.sleep(0.5)
    assert not _processes_with(f"FAULTS_TMP={tmp_path}".encode()), "a worker outlived generate"


def test_run_ctrl_c(tmp_path, ros_env) -> None:
    """Why (3): Ctrl-C on ``strapdown-sim run`` printed a KeyboardInterrupt traceback and the
    node logs ended in tracebacks. Now: children stopped, bag closed and readable, a summary,
    exit status 130, no process left, no traceback anywhere."""
    from strapdown_ros.bag.reader import read_bag

    out = tmp_path / "bag"
    _interrupt(
        ["run", str(SCENARIO), "--duration", "60", "--out", str(out)], 4.0, _env(ros_env),
        tmp_path, wait_for="trajectory_node",
    )  # fmt: skip
    read_bag(out)  # closed and readable
    logs = out.parent / f"{out.name}.logs"
    for log in logs.glob("*.log"):
        _no_traceback(log.read_text(errors="replace"))
    time.sleep(1.0)
    assert not _processes_with(f"FAULTS_TMP={tmp_path}".encode()), "orphan processes"


# ---------------------------------------------------------------------------------------------
# worker errors, bags that are not bags
# ---------------------------------------------------------------------------------------------


class _OddError(Exception):
    """An exception that does not survive pickling (its constructor takes two arguments)."""

    def __init__(self, what: str, why: str) -> None:
        super().__init__(f"{what}: {why}")


def _raising(exc: BaseException):
    yield 1
    raise exc


@pytest.mark.parametrize("kind", ["scenario", "odd"])
def test_worker_errors_reach_the_user(kind) -> None:
    """An error raised in generate's worker process arrives with the same message."""
    from strapdown_ros.config import ScenarioError
    from strapdown_ros.producer import Producer

    exc = ScenarioError("trajectory.kind", "bad") if kind == "scenario" else _OddError("a", "b")
    producer = Producer(_raising(exc))
    try:
        with pytest.raises(Exception) as info:
            list(producer)
    finally:
        producer.close()
    assert str(exc) in str(info.value)
    if kind == "scenario":
        assert type(info.value) is ScenarioError


@pytest.mark.parametrize("command", [["check"], ["bag", "info"], ["report"]])
@pytest.mark.parametrize("bag", ["empty", "garbage", "metadata"])
def test_not_a_bag(tmp_path, command, bag) -> None:
    path = tmp_path / "bag"
    path.mkdir()
    if bag == "garbage":
        (path / "bag_0.mcap").write_bytes(os.urandom(4096))
    elif bag == "metadata":
        (path / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2\n")
    proc = _cli(*command, str(path), timeout=120)
    _no_traceback(proc.stderr + proc.stdout)
    if command == ["bag", "info"]:  # a report of what is there, with the reason it does not read
        assert "does not read" in proc.stdout or "not" in proc.stdout, proc.stdout
    else:
        assert proc.returncode != 0 and proc.stderr.strip(), proc.stdout + proc.stderr


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("faults_cli") / "bag"
    proc = _cli("generate", str(SCENARIO), "--duration", "20", "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    return out


def test_replay_ctrl_c(small_bag, tmp_path, ros_env) -> None:
    """Ctrl-C on ``replay``: exit 130, what was recorded summarized, no traceback, no process
    left."""
    out = tmp_path / "replayed"
    _interrupt(
        ["replay", str(small_bag), "--into", "navigator", "--out", str(out)], 2.0,
        _env(ros_env), tmp_path, wait_for="playing",
    )  # fmt: skip
    for log in (out.parent / f"{out.name}.logs").glob("*.log"):
        _no_traceback(log.read_text(errors="replace"))
    time.sleep(1.0)
    assert not _processes_with(f"FAULTS_TMP={tmp_path}".encode()), "orphan processes"


def test_interrupted_recording_gives_reasons(small_bag, tmp_path) -> None:
    """A bag whose recording was interrupted (no metadata.yaml): check, report and bag info say
    why and name ``bag repair``; after the repair it checks out."""
    import shutil

    bag = tmp_path / "bag"
    shutil.copytree(small_bag, bag)
    (bag / "metadata.yaml").unlink()
    for command in (["check"], ["report"], ["bag", "info"]):
        proc = _cli(*command, str(bag), timeout=120)
        _no_traceback(proc.stderr + proc.stdout)
        assert "repair" in proc.stderr + proc.stdout, (command, proc.stdout + proc.stderr)
    proc = _cli("bag", "repair", str(bag), timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = _cli("check", str(bag), timeout=120)
    _no_traceback(proc.stderr)
    assert proc.returncode == 0, proc.stdout + proc.stderr
