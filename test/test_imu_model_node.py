"""imu_model_node publishes exactly what the offline model gives (interface.md §4, §6; issue 7).

A bag is generated offline for 2 s of the default scenario (its variation, no navigator). Its
ideal ``/variation/imu`` is the input; the reference output is computed in this process by
:func:`~strapdown_ros.stages.imu_errors.measured_imu_fields` on the whole stream at once
(one model, one call) and serialized with the project's codec. Then, as separate processes over
real DDS in this session's ROS domain:

1. a replay process publishes the bag's ``/variation/imu`` (and ``/variation/odom``), the node
   turns it into ``/variation/imu_measured`` message by message, a raw recorder records it:
   every payload equals the offline one byte for byte (and the bag's, when ``generate`` writes
   the measured stream);
2. the replay drops a cycle, swaps two and repeats one: the node logs the gap, the out-of-order
   and the duplicate stamps, advances the model over the missing cycles (later messages keep the
   offline noise: they differ from the uninterrupted offline run by quantization only);
3. invalid parameters or scenario: exit 2 naming the key.

:class:`~strapdown_ros.stages.imu_errors.ImuErrorsStage` (no DDS) is also checked in-process.
Every wait has a timeout; children are killed at teardown.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import node_testing as nt
import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.core.imu_errors import ImuErrorModel
from strapdown_ros.messages import imu_increments
from strapdown_ros.plan import resolve_plan
from strapdown_ros.plan.chain import offline_stages
from strapdown_ros.stages.imu_errors import (
    ImuErrorsStage,
    measured_imu_fields,
)

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
DURATION_S = 2.0
M_VAR = 398  # variation cycles 0..398 of the 400 reference cycles at 200 Hz
#: Tactical preset with fine quanta, so that noise (not quantization) dominates each sample and
#: the gap test can tell "the noise continues" from "the noise restarted".
IMU_ERRORS = (
    "imu_errors={preset: tactical, seed: 3, gyro_quantum_rad: 1.0e-9, accel_quantum_mps: 1.0e-8}"
)
OVERRIDES = [IMU_ERRORS, "navigator=null", "aided=null"]  # one model, on the variation IMU
IN, OUT, ODOM = "/variation/imu", "/variation/imu_measured", "/variation/odom"
TIMEOUT_S = 60.0
#: Faults of the replay test: cycle DROP is missing, SWAP and SWAP+1 swapped, DUP repeated.
DROP, SWAP, DUP = 101, 250, 300


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO, OVERRIDES, DURATION_S)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """``strapdown-sim generate`` of the scenario: (path, contents)."""
    out = tmp_path_factory.mktemp("generate") / "bag"
    contents = nt.generated(SCENARIO, out, DURATION_S, OVERRIDES, timeout=120)
    assert len(contents.topics[IN].payloads) == M_VAR
    return out, contents


@pytest.fixture(scope="module")
def offline(bag, scenario) -> list[bytes]:
    """The measured payloads of the whole ideal stream, by one call on all of it."""
    _, contents = bag
    ideal = contents[IN]
    model = ImuErrorModel(scenario.imu_errors[0].parameters(), scenario.period_ns * 1e-9)
    return [bytes(p) for p in cdr.serialize(measured_imu_fields(ideal, model, scenario.period_ns))]


def _stamp_of(payload: bytes) -> int:
    sec, nanosec = np.frombuffer(bytes(payload)[4:12], dtype="<i4,<u4")[0]
    return int(sec) * 1_000_000_000 + int(nanosec)


def _cycle(scenario, payload: bytes) -> int:
    return (_stamp_of(payload) - scenario.start_time_ns) // scenario.period_ns


# ---------------------------------------------------------------------------------------------
# In-process: the measured messages


def test_measured_messages_follow_the_model_and_rep145(bag, scenario, offline):
    _, contents = bag
    ideal = contents[IN]
    measured = cdr.deserialize(cdr.IMU, offline)
    assert np.array_equal(measured.stamps_ns, ideal.stamps_ns)
    assert measured.frame_id == ideal.frame_id == "variation_imu"
    # Orientation not provided (docs/interface.md §4), REP-145 element 0 = -1.
    assert np.all(measured.orientation_covariance[:, 0] == -1)
    assert np.all(measured.orientation_covariance[:, 1:] == 0)
    # Covariances: white noise N²/T + quantization q²/(6T²) on the diagonal, from the preset.
    T = scenario.period_ns * 1e-9
    var_w = (0.1 * np.pi / 180 / 60) ** 2 / T + 1e-9**2 / (6 * T**2)
    var_a = (0.03 / 60) ** 2 / T + 1e-8**2 / (6 * T**2)
    cov_w = np.asarray(measured.angular_velocity_covariance).reshape(-1, 3, 3)
    cov_a = np.asarray(measured.linear_acceleration_covariance).reshape(-1, 3, 3)
    np.testing.assert_allclose(cov_w, np.broadcast_to(np.eye(3) * var_w, cov_w.shape), rtol=1e-12)
    np.testing.assert_allclose(cov_a, np.broadcast_to(np.eye(3) * var_a, cov_a.shape), rtol=1e-12)
    # Minus the run's deterministic errors (bias, S + M, g-sensitivity), computed here in FRD
    # from the realized constants, the rest is white noise of the published variance.
    model = ImuErrorModel(scenario.imu_errors[0].parameters(), T)
    params = model.params
    ideal_inc = imu_increments(ideal, scenario.period_ns)
    meas_inc = imu_increments(measured, scenario.period_ns)
    da, dv = ideal_inc.dalpha, ideal_inc.dv
    det_w = model.gyro_bias * T + da @ model.gyro_error_matrix.T + dv @ params.gyro.g_sensitivity.T
    det_a = model.accel_bias * T + dv @ model.accel_error_matrix.T
    r_w = (meas_inc.dalpha - da - det_w) / T
    r_a = (meas_inc.dv - dv - det_a) / T
    assert np.all(np.abs(np.std(r_w, axis=0) / np.sqrt(var_w) - 1) < 0.15)
    assert np.all(np.abs(np.std(r_a, axis=0) / np.sqrt(var_a) - 1) < 0.15)
    assert np.all(np.abs(np.mean(r_w, axis=0)) < 4 * np.sqrt(var_w / len(r_w)) + 1e-5)
    # Quantized: whole quanta of the increments.
    inc = imu_increments(measured, scenario.period_ns)
    for x, q in ((inc.dalpha, 1e-9), (inc.dv, 1e-8)):
        np.testing.assert_allclose(x / q, np.round(x / q), atol=1e-3)


def test_stream_message_by_message_equals_offline(bag, scenario, offline):
    """The node's code path (one payload at a time) equals one call on the whole stream."""
    _, contents = bag
    stream = ImuErrorsStage(scenario)
    got = [stream.on_payload(p) for p in contents.topics[IN].payloads]
    assert got == offline
    assert stream.published == M_VAR and stream.last_cycle == M_VAR and stream.runs == 1
    # generate's path: batches of other sizes.
    stream = ImuErrorsStage(scenario)
    d = contents.topics[IN]
    out = []
    for a, b in ((0, 7), (7, 8), (8, 300), (300, M_VAR)):
        batch_in = Batch(IN, cdr.IMU, d.log_time_ns[a:b], d.payloads[a:b])
        out += [bytes(p) for bo in stream.feed_batches([batch_in]) for p in bo.payloads]
    assert out == offline
    if OUT in contents.topics:  # generate writes the measured stream
        assert [bytes(p) for p in contents.topics[OUT].payloads] == offline


def test_stream_payload_batches_equal_offline(bag, scenario, offline):
    """``on_payloads`` (what the node calls) equals ``on_payload`` one by one; a batch with a
    malformed payload falls back to one by one: only that message is dropped and reported."""
    _, contents = bag
    payloads = [bytes(p) for p in contents.topics[IN].payloads]
    stream = ImuErrorsStage(scenario)
    got = []
    for a in range(0, len(payloads), 9):
        got += stream.on_payloads(payloads[a : a + 9])
    assert got == offline and stream.runs == 1
    errors: list[str] = []
    stream = ImuErrorsStage(scenario, error=errors.append)
    got = stream.on_payloads(payloads[:5] + [b"\x00\x01\x00\x00garbage"] + payloads[5:12])
    assert got == offline[:12] and len(errors) == 1 and "decode" in errors[0]


def test_stream_restart_offgrid_and_late_start(bag, scenario, offline):
    _, contents = bag
    payloads = contents.topics[IN].payloads
    warn, error = [], []
    stream = ImuErrorsStage(scenario, warn=warn.append, error=error.append)
    # Late start at cycle 11: advanced over 1..10; without quantization differences the noise
    # is the offline one, so the result is within a quantum (here: a few 1e-9 rad) of it.
    first = stream.on_payload(payloads[10])
    assert "the input starts at" in warn[-1] and "cycles 1..10" in warn[-1]
    a = cdr.deserialize(cdr.IMU, [first])
    b = cdr.deserialize(cdr.IMU, [offline[10]])
    T = scenario.period_ns * 1e-9
    assert np.all(np.abs(a.angular_velocity - b.angular_velocity) <= 2.0000001e-9 / T)
    assert np.all(np.abs(a.linear_acceleration - b.linear_acceleration) <= 2.0000001e-8 / T)
    # Input restarted at cycle 1: a new run from the seed, equal to the offline stream.
    again = [stream.on_payload(p) for p in payloads[:50]]
    assert "the input restarted" in warn[-1] and stream.runs == 2
    assert again == offline[:50]
    # A stamp off the cycle grid is rejected.
    ideal = cdr.deserialize(cdr.IMU, [payloads[50]])
    shifted = type(ideal)(**{**ideal.__dict__, "stamps_ns": ideal.stamps_ns + 1})
    assert stream.feed(shifted) is None and "not a cycle" in error[-1]
    assert stream.on_payload(b"\x00\x01\x00\x00garbage") is None and "decode" in error[-1]


def test_the_scenario_checks_the_topics():
    """The input must be an ideal IMU topic the scenario produces (named in the error), checked
    when the scenario loads (``validate``, ``generate`` and the node alike)."""
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCENARIO, ["variation=null", "navigator=null"], DURATION_S)
    # default.yaml's first model reads /variation/imu
    assert info.value.key == "imu_errors[0].input_topic" and "/reference/imu" in info.value.problem
    with pytest.raises(ScenarioError, match="imu_errors.input_topic"):
        load_scenario(  # default input /variation/imu: not generated
            SCENARIO,
            ["variation=null", "navigator=null", "imu_errors={preset: navigation}"],
            DURATION_S,
        )
    ok = load_scenario(
        SCENARIO,
        ["variation=null", "navigator=null", "imu_errors={input_topic: /reference/imu}"],
        DURATION_S,
    )
    stages = dict(offline_stages(resolve_plan(ok)))
    (stage,) = stages["imu_errors"].stages  # one model
    assert stage.input_topic == "/reference/imu"
    assert stage.output_topic == "/variation/imu_measured"
    with pytest.raises(ScenarioError, match="imu_errors.output_topic"):
        load_scenario(SCENARIO, ["imu_errors={output_topic: /variation/odom}"], DURATION_S)
    plan = resolve_plan(load_scenario(SCENARIO, ["imu_errors=null", "aided=null"]))
    assert "imu_errors" not in dict(offline_stages(plan))


# ---------------------------------------------------------------------------------------------
# Processes over DDS


def _node(procs, env, tmp_path, *params: str) -> nt.Proc:
    args = nt.node_args(
        "imu_model_node", f"scenario:={SCENARIO}", nt.list_param("overrides", OVERRIDES),
        f"duration_s:={DURATION_S}", "wait_for_subscribers:=1", *params,
    )  # fmt: skip
    return nt.launch(procs, args, env, tmp_path, "imu_model_node")


def _recorder(procs, env, tmp_path, n_out: int, n_odom: int) -> tuple[nt.Proc, Path]:
    topics = [(OUT, cdr.IMU, n_out), (ODOM, cdr.ODOMETRY, n_odom)]
    return nt.raw_recorder(procs, env, tmp_path, topics, TIMEOUT_S - 5)


def _replay(procs, env, tmp_path, path, *faults: str) -> nt.Proc:
    return nt.reference_replay(
        procs, env, tmp_path, path, "--imu-topic", IN, "--odom-topic", ODOM,
        "--interval", "0.001", "--timeout", str(TIMEOUT_S - 10), *faults,
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("executor", ["events", "single_threaded"])
def test_node_equals_offline(bag, offline, procs, ros_env, tmp_path, executor):
    """replay → imu_model_node → recorder: the offline payloads, byte for byte, on either
    executor (``single_threaded`` is the fallback where rclpy has no EventsExecutor)."""
    pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")
    path, contents = bag
    deadline = time.monotonic() + TIMEOUT_S
    rec, out = _recorder(procs, ros_env, tmp_path, M_VAR, M_VAR + 1)
    node = _node(procs, ros_env, tmp_path, f"executor:={executor}")
    node.wait_for(r"subscribed to /variation/imu", deadline)
    replay = _replay(procs, ros_env, tmp_path, path)
    nt.wait_ok(deadline, replay, node, rec)
    nt.assert_clean(node, warnings=False)
    assert f"published {M_VAR} measured messages" in node.output, node.describe()
    got = nt.load_recording(out)["topics"][OUT]
    assert len(got) == M_VAR
    bad = [i for i, (g, w) in enumerate(zip(got, offline, strict=True)) if g != nt.padded(w)]
    assert not bad, f"payloads {bad[:5]}... differ from the offline model"
    assert nt.bitwise_equal(cdr.deserialize(cdr.IMU, got), cdr.deserialize(cdr.IMU, offline))


@pytest.mark.slow
def test_node_gap_out_of_order_duplicate(bag, scenario, offline, procs, ros_env, tmp_path):
    pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")
    path, contents = bag
    deadline = time.monotonic() + TIMEOUT_S
    # Published: cycles 1..398 without DROP; SWAP+1 before SWAP (SWAP dropped as out of
    # order); DUP twice (the repeat dropped).
    expect = [m for m in range(1, M_VAR + 1) if m not in (DROP, SWAP)]
    rec, out = _recorder(procs, ros_env, tmp_path, len(expect), M_VAR + 1)  # -1 drop, +1 dup
    node = _node(procs, ros_env, tmp_path, "idle_timeout_s:=3.0")
    node.wait_for(r"subscribed to /variation/imu", deadline)
    faults = ("--drop", str(DROP), "--swap", str(SWAP), "--duplicate", str(DUP))
    replay = _replay(procs, ros_env, tmp_path, path, *faults)
    nt.wait_ok(deadline, replay, node, rec)
    nt.assert_clean(node)
    log = node.output

    def st(m: int) -> str:
        return nt.stamp_regex(scenario.start_time_ns, scenario.period_ns, m)

    assert re.search(rf"WARN.*{IN}: gap: stamp {st(DROP + 1)} .*follows {st(DROP - 1)}", log)
    assert re.search(rf"WARN.*{IN}: gap: stamp {st(SWAP + 1)} .*follows {st(SWAP - 1)}", log)
    assert re.search(rf"WARN.*{IN}: out-of-order stamp {st(SWAP)} .*after {st(SWAP + 1)}", log)
    assert re.search(rf"WARN.*{IN}: duplicate stamp {st(DUP)} .*after {st(DUP)}", log)
    got = nt.load_recording(out)["topics"][OUT]
    assert [_cycle(scenario, p) for p in got] == expect
    # Before the first gap: the offline bytes.
    for p in got[: DROP - 1]:
        assert p == nt.padded(offline[_cycle(scenario, p) - 1])
    # After it: the offline noise continues; only the quantizer's running sum lacks the
    # missing increments (≤ 2 quanta on the first message after a gap, ≤ 1 after).
    T = scenario.period_ns * 1e-9
    a = cdr.deserialize(cdr.IMU, got[DROP - 1 :])
    b = cdr.deserialize(cdr.IMU, [offline[m - 1] for m in expect[DROP - 1 :]])
    dw = np.abs(np.asarray(a.angular_velocity) - b.angular_velocity) * T / 1e-9
    da = np.abs(np.asarray(a.linear_acceleration) - b.linear_acceleration) * T / 1e-8
    assert dw.max() <= 2.001 and da.max() <= 2.001, (dw.max(), da.max())
    noise = np.std(np.asarray(b.angular_velocity) - contents[IN].angular_velocity[:1], axis=0)
    assert np.all(noise * T / 1e-9 > 100)  # the tolerance above is far below the noise
    # The exact expectation: the same message sequence through the same code, in-process.
    stream = ImuErrorsStage(scenario)
    order = [m for m in range(1, M_VAR + 1) if m != DROP]
    i = order.index(SWAP)
    order[i], order[i + 1] = order[i + 1], order[i]
    order.insert(order.index(DUP) + 1, DUP)
    want = [stream.on_payload(contents.topics[IN].payloads[m - 1]) for m in order]
    assert got == [nt.padded(w) for w in want if w is not None]


@pytest.mark.parametrize(
    ("params", "expected"),
    [
        ([], r"parameter 'scenario': is required"),
        (
            [f"scenario:={SCENARIO}", "overrides:=['imu_errors=null', 'aided=null']"],
            r"invalid scenario: imu_errors: missing",
        ),
        (
            [f"scenario:={SCENARIO}", "overrides:=['imu_errors={preset: tactical, seed: -2}']"],
            r"invalid scenario: imu_errors\.seed: must be an integer >= 0",
        ),
        (
            [f"scenario:={SCENARIO}", "overrides:=['imu_errors={gyro_arw_dpsh: [1, 2]}']"],
            r"invalid scenario: imu_errors\.gyro_arw_dpsh: must be a number or a list of 3",
        ),
        (
            [f"scenario:={SCENARIO}", "overrides:=['variation=null', 'navigator=null']"],
            r"invalid scenario: imu_errors\[0\]\.input_topic: /variation/imu is not an ideal IMU "
            r"topic",
        ),
        (
            [f"scenario:={SCENARIO}", f"overrides:=['{IMU_ERRORS}', 'aided=null']",
             f"output_topic:={IN}"],
            r"parameter 'output_topic': equals the input topic",
        ),
        (
            [f"scenario:={SCENARIO}", f"overrides:=['{IMU_ERRORS}', 'aided=null']", "qos_depth:=0"],
            r"parameter 'qos_depth'",
        ),
        (
            [f"scenario:={SCENARIO}", f"overrides:=['{IMU_ERRORS}', 'aided=null']",
             "executor:=multi"],
            r"parameter 'executor': must be one of: events, single_threaded",
        ),
        (  # default.yaml has models 0 and 1
            [f"scenario:={SCENARIO}", "model:=2"],
            r"invalid scenario: imu_errors: no model 2: the scenario has 2 \(0\.\.1\)",
        ),
    ],
    ids=["missing", "no-imu-errors", "seed", "shape", "no-input", "same-topic", "qos", "executor",
         "no-model"],  # fmt: skip
)
def test_invalid_input_exits_2(params, expected, ros_env):
    pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")
    rc, output = nt.node_exit("imu_model_node", ros_env, *params)
    assert rc == 2, output
    assert re.search(expected, output), output
