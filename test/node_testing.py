"""Helpers shared by the node tests: executables and their command lines, child processes,
``strapdown-sim generate`` / ``run``, the helper scripts of ``ros_helpers/``, payload comparison."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
HELPERS = REPO / "test" / "ros_helpers"
#: ros_helpers/raw_recorder.py: records raw payloads of topics (see its docstring).
RAW_RECORDER = HELPERS / "raw_recorder.py"
#: ros_helpers/reference_replay.py: replays a bag's Imu/Odometry pair with faults.
REFERENCE_REPLAY = HELPERS / "reference_replay.py"


def executable(name: str) -> str:
    local = Path(sys.executable).parent / name
    found = str(local) if local.exists() else shutil.which(name)
    if not found:
        pytest.skip(f"{name} is not installed (make setup)")
    return found


def node_args(name: str, *params: str) -> list[str]:
    """The command line of node ``name`` (its console script) with ``-p`` parameters."""
    args = [executable(name), "--ros-args"]
    for p in params:
        args += ["-p", p]
    return args


def node_exit(name: str, env: dict[str, str], *params: str, timeout: float = 60) -> tuple[int, str]:
    """Run node ``name`` with ``-p`` parameters to its end: ``(exit status, its output)``; the
    output must hold no traceback."""
    proc = subprocess.run(node_args(name, *params), env=env, capture_output=True, text=True,
                          timeout=timeout, cwd=REPO)  # fmt: skip
    output = proc.stdout + proc.stderr
    assert "Traceback" not in output, output
    return proc.returncode, output


def list_param(name: str, items) -> str:
    """A string-array node parameter, ``name:=['a','b']``."""
    return f"{name}:=[" + ",".join(f"'{i}'" for i in items) + "]"


def sim(
    *args: object, env: dict[str, str] | None = None, timeout: float = 180
) -> subprocess.CompletedProcess:
    """``strapdown-sim ARGS`` (the venv's), output captured, from the repository root."""
    cmd = [executable("strapdown-sim"), *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=REPO)


def generate(scenario: Path, out: Path, *args: object, timeout: float = 180) -> None:
    """``strapdown-sim generate SCENARIO --out OUT --quiet ARGS``; it must succeed."""
    proc = sim("generate", scenario, "--out", out, "--quiet", *args, timeout=timeout)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def generated(scenario: Path, out: Path, duration_s: float, overrides=(), timeout: float = 180):
    """The bag of ``strapdown-sim generate`` for ``duration_s`` with ``--set`` ``overrides``,
    read back raw (:class:`~strapdown_ros.bag.reader.BagContents`)."""
    from strapdown_ros.bag.reader import read_bag

    args: list[object] = ["--duration", duration_s]
    for o in overrides:
        args += ["--set", o]
    generate(scenario, out, *args, timeout=timeout)
    return read_bag(out, raw=True)


#: A wall-clock run whose own source published this late (ms) ran on a starved machine: in
#: such a CI run every node's CPU time doubled for the same work (the trajectory node's 7.7 s
#: became 15.7 s) and the source fell 1 050 ms behind its clock, against 39 ms on this machine
#: otherwise. ``run_live(starved_retry=True)`` runs such a case once more, never a loss whose
#: source kept its clock.
STARVED_SOURCE_MS = 250.0


def source_lateness_ms(text: str) -> float | None:
    """The trajectory node's max pacing lateness (ms) in a ``run`` summary, if printed."""
    m = re.search(r"max lateness ([0-9.]+) ms", text)
    return float(m.group(1)) if m else None


def run_live(
    scenario: Path, out: Path, env: dict[str, str], *args: str, timeout: float = 300,
    starved_retry: bool = False,
) -> subprocess.CompletedProcess:
    """``strapdown-sim run SCENARIO --out OUT ARGS`` in the session's ROS domain; it must
    succeed with zero loss. ``starved_retry``: a failed run whose source itself was more than
    :data:`STARVED_SOURCE_MS` late is run once more (and must then succeed)."""

    def once() -> subprocess.CompletedProcess:
        return sim("run", scenario, "--out", out, *args, "--domain-id", env["ROS_DOMAIN_ID"],
                   env=env, timeout=timeout)  # fmt: skip

    proc = once()
    late = source_lateness_ms(proc.stdout + proc.stderr)
    if starved_retry and proc.returncode != 0 and late is not None and late > STARVED_SOURCE_MS:
        print(f"starved machine: the source was {late:.0f} ms late; run once more\n"
              + proc.stdout)  # fmt: skip
        shutil.rmtree(out, ignore_errors=True)
        shutil.rmtree(out.with_name(out.name + ".logs"), ignore_errors=True)
        proc = once()
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "zero loss" in proc.stdout, proc.stdout
    return proc


def assert_recorded_as_generated(live: Path, gen: Path) -> None:
    """The bag ``live`` has every topic of ``gen`` with the same payloads in the same order;
    ``/tf``, which three nodes publish, in any interleaving (the same log times)."""
    from strapdown_ros.bag.reader import read_bag

    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    assert set(a.topics) == set(b.topics)
    assert "/tf" in b.topics and "/tf_static" in b.topics  # TF recorded live too
    for topic, data in b.topics.items():
        got = [bytes(p) for p in a.topics[topic].payloads]
        want = [bytes(p) for p in data.payloads]
        assert len(got) == len(want), topic
        if topic == "/tf":
            got, want = sorted(got), sorted(want)
            np.testing.assert_array_equal(
                np.sort(a.topics[topic].log_time_ns), np.sort(data.log_time_ns)
            )
        assert got == want, topic


class Proc:
    """A child process whose stdout/stderr go to files (no pipe can fill up)."""

    def __init__(self, args: list[str], env: dict[str, str], log_dir: Path, name: str) -> None:
        self.name = name
        self.out_path = log_dir / f"{name}.out"
        self.err_path = log_dir / f"{name}.err"
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen(
                args, env=env, stdin=subprocess.DEVNULL, stdout=out, stderr=err, cwd=REPO
            )

    @property
    def output(self) -> str:
        return self.out_path.read_text() + self.err_path.read_text()

    def wait_for(self, pattern: str, deadline: float) -> None:
        """Block until the output matches ``pattern`` (regex); fail at ``deadline`` or exit."""
        while not re.search(pattern, self.output):
            if self.proc.poll() is not None and not re.search(pattern, self.output):
                pytest.fail(f"{self.name} exited before {pattern!r}:\n{self.describe()}")
            if time.monotonic() > deadline:
                pytest.fail(f"timeout waiting for {pattern!r} from {self.name}:\n{self.describe()}")
            time.sleep(0.05)

    def wait(self, deadline: float) -> int:
        try:
            return self.proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            pytest.fail(f"timeout waiting for {self.name} to exit:\n{self.describe()}")

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)

    def describe(self) -> str:
        return f"--- {self.name} (pid {self.proc.pid}, rc {self.proc.poll()})\n{self.output}"


def launch(procs: list, args: list[str], env: dict[str, str], log_dir: Path, name: str) -> Proc:
    """A :class:`Proc` of ``args``, added to ``procs`` (the fixture that kills what is left)."""
    proc = Proc(args, env, log_dir, name)
    procs.append(proc)
    return proc


def wait_ok(deadline: float, *procs: Proc) -> None:
    """Each process exits 0 by ``deadline``, in order; a failure shows every one's output."""
    for p in procs:
        rc = p.wait(deadline)
        assert rc == 0, "".join(q.describe() for q in (p, *(q for q in procs if q is not p)))


def assert_clean(*procs: Proc, warnings: bool = True) -> None:
    """No traceback in the processes' output (nor a warning unless ``warnings``)."""
    for p in procs:
        assert "Traceback" not in p.output, p.describe()
        assert warnings or "WARN" not in p.output, p.describe()


def load_recording(path: Path) -> dict:
    """What ``ros_helpers/raw_recorder.py`` pickled: ``{"topics": ..., "arrival": ...}``."""
    import pickle

    with open(path, "rb") as f:
        return pickle.load(f)


def stamp_regex(t0_ns: int, period_ns: int, m: int) -> str:
    """The regex of the logged stamp ``sec.nanosec`` of cycle ``m`` (``t0 + m T``)."""
    t = t0_ns + m * period_ns
    return re.escape(f"{t // 1_000_000_000}.{t % 1_000_000_000:09d}")


def raw_recorder(
    procs: list, env: dict[str, str], tmp_path: Path, topics, timeout_s: float,
    name: str = "recorder",
) -> tuple[Proc, Path]:
    """``ros_helpers/raw_recorder.py`` on ``topics`` (``(topic, msgtype, count)`` triples);
    returns the process and the pickle it writes."""
    out = tmp_path / "recording.pkl"
    args = [sys.executable, str(RAW_RECORDER), "--out", str(out), "--timeout", str(timeout_s)]
    for topic, msgtype, count in topics:
        args += ["--topic", f"{topic}={msgtype}={count}"]
    return launch(procs, args, env, tmp_path, name), out


def reference_replay(
    procs: list, env: dict[str, str], tmp_path: Path, bag: Path, *args: str
) -> Proc:
    """``ros_helpers/reference_replay.py --bag BAG ARGS``."""
    cmd = [sys.executable, str(REFERENCE_REPLAY), "--bag", str(bag), *args]
    return launch(procs, cmd, env, tmp_path, "replay")


def padded(payload: bytes) -> bytes:
    """``payload`` as a subscriber in another process receives it from Fast DDS.

    RTPS submessages are 4-byte aligned and the reader takes the serialized payload's length
    from the submessage, so a payload whose length is not a multiple of 4 (NavSatFix: 133
    bytes) arrives with 1-3 zero bytes appended, whoever published it (rclpy's own serializer
    too). The CDR content is unchanged.
    """
    return bytes(payload) + bytes(-len(payload) % 4)


def bitwise_equal(a, b) -> bool:
    """Field containers equal bit for bit (dtype, shape and bytes of every array)."""
    if type(a) is not type(b):
        return False
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, str) or isinstance(y, str):
            if x != y:
                return False
            continue
        x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            return False
    return True


def scenario_without_tf(path: Path, *, aiding: bool = True) -> Path:
    """A copy of scenario ``path`` with ``tf: {enabled: false, map_odometry: false}`` (and
    without its ``aiding`` section when ``aiding`` is false).

    The node tests compare a node's own streams with ``generate``'s; TF and the map-frame
    odometry (published beside them by every node) are tested by test_tf.py (against truth) and
    test_pipeline.py (``run`` equals ``generate``). Same file name, so the scenario name stays.
    """
    import os
    import tempfile

    import yaml

    doc = yaml.safe_load(path.read_text())
    doc.setdefault("name", path.stem)
    doc["tf"] = {"enabled": False, "map_odometry": False}
    if not aiding:
        doc.pop("aiding", None)
    tag = "" if aiding else "_no_aiding"
    out = Path(tempfile.gettempdir()) / f"strapdown_no_tf{tag}_{os.getpid()}" / path.name
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out
