"""Fault injection into the live nodes (DDS): a generated bag's messages, altered per case, are
published into ``navigator_node`` / ``variation_node`` / ``imu_model_node`` and their output is
recorded (``ros_helpers/reference_replay.py``). The node must keep running, never publish a
non-finite number, resume correct output, log one line per event and count it in its summary
(docs/reliability.md).

``STRAPDOWN_FAULTS_NODE_PATH=/path/to/checkout`` runs the nodes from another checkout's package
(its ``strapdown_ros`` first on ``PYTHONPATH``), e.g. a commit before the fixes, on which the
"Why" cases fail.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.reader import read_bag

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from node_testing import padded  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
HELPER = Path(__file__).resolve().parents[1] / "ros_helpers" / "reference_replay.py"
DURATION_S = 3.0
TIMEOUT_S = 120.0
NAV_OUT = {
    "/navigator/odom": cdr.ODOMETRY,
    "/navigator/fix": cdr.NAVSATFIX,
    "/navigator/error/position": cdr.VECTOR3_STAMPED,
}
VAR_OUT = {"/variation/imu": cdr.IMU, "/variation/odom": cdr.ODOMETRY}
MEASURED = {"/variation/imu_measured": cdr.IMU}


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    from strapdown_ros.config import load_scenario
    from strapdown_ros.generate import generate_dataset

    out = tmp_path_factory.mktemp("faults") / "bag"
    generate_dataset(load_scenario(SCENARIO, [], DURATION_S), out)
    return out, read_bag(out, raw=True)


def _node_env(ros_env: dict[str, str]) -> dict[str, str]:
    env = dict(ros_env)
    other = os.environ.get("STRAPDOWN_FAULTS_NODE_PATH")
    if other:
        env["PYTHONPATH"] = other + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _start_node(name: str, params: list[str], env, log: Path) -> subprocess.Popen:
    code = f"import sys; from strapdown_ros.nodes.{name} import main; sys.exit(main())"
    args = [sys.executable, "-c", code, "--ros-args", "-r", f"__node:={name}"]
    for p in [f"scenario:={SCENARIO}", f"duration_s:={DURATION_S}", "idle_timeout_s:=4.0",
              *params]:  # fmt: skip
        args += ["-p", p]
    with open(log, "w") as f:
        # cwd: not the repository, whose package would shadow STRAPDOWN_FAULTS_NODE_PATH's
        return subprocess.Popen(args, env=env, stdout=f, stderr=subprocess.STDOUT, cwd=log.parent)


def _wait_for(log: Path, text: str, proc: subprocess.Popen, deadline: float) -> None:
    while text not in log.read_text(errors="replace"):
        if proc.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"no '{text}' from the node:\n{log.read_text(errors='replace')}")
        time.sleep(0.05)


def _drive(tmp_path, ros_env, procs, node: str, inputs: tuple[str, str], record: dict[str, str],
           bag_path: Path, faults: list[str], params: list[str] = ()):  # fmt: skip
    """Start ``node``, replay the bag with ``faults``; return (outputs by topic, node log,
    exit status)."""
    log = tmp_path / f"{node}.log"
    deadline = time.monotonic() + TIMEOUT_S
    proc = _start_node(node, list(params), _node_env(ros_env), log)
    procs.append(_Killable(proc))
    _wait_for(log, "subscribed to", proc, deadline)
    out = tmp_path / "out.pkl"
    cmd = [sys.executable, str(HELPER), "--bag", str(bag_path), "--imu-topic", inputs[0],
           "--odom-topic", inputs[1], "--out", str(out), "--timeout", "90",
           "--interval", "0.0005", *faults]  # fmt: skip
    for topic, msgtype in record.items():
        cmd += ["--record", f"{topic}={msgtype}"]
    helper = subprocess.run(cmd, env=ros_env, capture_output=True, text=True, timeout=150)
    assert helper.returncode == 0, helper.stdout + helper.stderr
    try:
        proc.wait(timeout=max(deadline - time.monotonic(), 10))
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    with open(out, "rb") as f:
        got = pickle.load(f)
    return got, log.read_text(errors="replace"), proc.returncode


class _Killable:
    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)


def _decoded(got: dict[str, list[bytes]], msgtypes: dict[str, str]):
    return {t: cdr.deserialize(msgtypes[t], got[t]) for t in msgtypes if got.get(t)}


def _all_finite(fields) -> bool:
    from strapdown_ros.stages.intake import nonfinite_rows

    return nonfinite_rows(fields) is None


def _stamps(fields) -> list[int]:
    return np.asarray(fields.stamps_ns).tolist()


#: The node under test, its (Imu, Odometry) inputs and the outputs recorded.
NAV = ("navigator_node", ("/variation/imu", "/variation/odom"), NAV_OUT)
VAR = ("variation_node", ("/reference/imu", "/reference/odom"), VAR_OUT)
MODEL = ("imu_model_node", ("/variation/imu", "/variation/odom"), MEASURED)


def _run_case(bag, tmp_path, ros_env, procs, target, faults: list[str]):
    """:func:`_drive` of ``target`` (NAV, VAR, MODEL); returns (outputs by topic, decoded,
    node log, exit status)."""
    node, inputs, outputs = target
    got, log, rc = _drive(tmp_path, ros_env, procs, node, inputs, outputs, bag[0], faults)
    return got, _decoded(got, outputs), log, rc


# ---------------------------------------------------------------------------------------------
# a NaN in one input message, every node
# ---------------------------------------------------------------------------------------------


def _navigator_resumes(got, dec, contents, log) -> None:
    """Why (1): old code published NaN odometry and errors. It resumes: the last output is the
    bag's last one."""
    assert set(dec) == set(NAV_OUT), log
    last = _stamps(contents.topics["/navigator/odom"].fields)[-1]
    assert _stamps(dec["/navigator/odom"])[-1] >= last, log
    assert "NaN or infinity" in log and "input events: non-finite 1\n" in log + "\n", log


def _navigator_odometry_unchanged(got, dec, contents, log) -> None:
    """A NaN truth is dropped as lost: odometry goes on, the same bytes."""
    ref = [padded(p) for p in contents.topics["/navigator/odom"].payloads]
    assert got["/navigator/odom"] == ref, log


def _variation_resumes(got, dec, contents, log) -> None:
    """Why (1): old code published NaN variation data."""
    assert set(dec) == set(VAR_OUT), log
    want = _stamps(contents.topics["/variation/odom"].fields)[-1]
    assert _stamps(dec["/variation/odom"])[-1] == want, log
    assert "NaN or infinity" in log, log


def _one_measured_message_less(got, dec, contents, log) -> None:
    """No measured message for the NaN input; the model goes on."""
    want = len(contents.topics["/variation/imu_measured"].fields) - 1
    assert len(dec["/variation/imu_measured"]) == want, log


def _nothing_else(got, dec, contents, log) -> None:
    """Only what every case checks."""


@pytest.mark.parametrize(
    ("target", "faults", "check"),
    [
        pytest.param(NAV, ["--nan-imu", "205"], _navigator_resumes, id="navigator-imu"),
        pytest.param(NAV, ["--nan-odom", "300"], _navigator_odometry_unchanged,
                     id="navigator-truth"),
        pytest.param(VAR, ["--nan-imu", "150"], _variation_resumes, id="variation-imu"),
        pytest.param(VAR, ["--nan-odom", "151"], _nothing_else, id="variation-odom"),
        pytest.param(MODEL, ["--nan-imu", "100", "--no-wait-odom"], _one_measured_message_less,
                     id="imu_model-imu"),
    ],
)  # fmt: skip
def test_nan_input_never_published(bag, tmp_path, ros_env, procs, target, faults, check) -> None:
    """A NaN in one input message: nothing non-finite is published, the event is logged and
    counted once, the node exits 0; ``check``: what else the case shows."""
    got, dec, log, rc = _run_case(bag, tmp_path, ros_env, procs, target, faults)
    for topic, fields in dec.items():
        assert _all_finite(fields), f"{topic}: non-finite values published\n{log}"
    check(got, dec, bag[1], log)
    assert "non-finite 1" in log and rc == 0, log


# ---------------------------------------------------------------------------------------------
# navigator_node: lost and late input
# ---------------------------------------------------------------------------------------------


def test_navigator_lost_truth_at_output_instant(bag, tmp_path, ros_env, procs) -> None:
    """Why (2): one truth message missing at an output time stopped the output for good. The
    navigator continues from its own state: every odometry equals the uninterrupted run's, only
    the errors at that stamp are missing."""
    contents = bag[1]
    m = 200  # an output instant (N = 10)
    got, _, log, rc = _run_case(bag, tmp_path, ros_env, procs, NAV, ["--drop-odom", str(m)])
    ref = [padded(p) for p in contents.topics["/navigator/odom"].payloads]
    assert got["/navigator/odom"] == ref, log  # same bytes: ran on from its own state
    ref_err = contents.topics["/navigator/error/position"]
    dropped = int(np.asarray(contents.topics["/variation/odom"].fields.stamps_ns)[m])
    expected = [padded(p) for s, p in zip(_stamps(ref_err.fields), ref_err.payloads, strict=True)
                if s != dropped]  # fmt: skip
    assert got["/navigator/error/position"] == expected, log
    assert "truth lost 1" in log, log
    assert rc == 0, log


def test_navigator_gap_between_first_messages(bag, tmp_path, ros_env, procs) -> None:
    """The IMU period is not learned from one interval: with the second IMU message missing,
    the navigator still finds T and produces the usual output rate."""
    contents = bag[1]
    got, _, log, rc = _run_case(bag, tmp_path, ros_env, procs, NAV, ["--drop-imu", "2"])
    assert "IMU period T = 5000000 ns" in log, log
    stamps = _stamps(cdr.deserialize(cdr.ODOMETRY, got["/navigator/odom"]))
    assert np.all(np.diff(stamps) == 10 * 5_000_000), log
    # The run starts at the truth before the first IMU message after the gap (cycle 2).
    assert len(stamps) >= len(contents.topics["/navigator/odom"].fields) - 1, log
    assert rc == 0, log


def test_navigator_restarted_source(bag, tmp_path, ros_env, procs) -> None:
    """The source restarts (stamps jump back): a new run, said once; the node keeps running."""
    _, dec, log, rc = _run_case(bag, tmp_path, ros_env, procs, NAV, ["--jump-back", "400:100"])
    assert all(_all_finite(f) for f in dec.values()), log
    assert log.count("the source restarted") == 1 and "restart 1" in log, log
    assert "run 2 starts" in log, log
    stamps = _stamps(dec["/navigator/odom"])
    # The new run (from the truth before the restart point) reaches the end of the input.
    assert stamps[-1] >= _stamps(bag[1].topics["/navigator/odom"].fields)[-1] - 10 * 5_000_000
    assert rc == 0, log
