"""The navigator on messages: ``generate``'s ``/navigator/*`` streams, the streaming solver and
``navigator_node`` as a process between ``trajectory_node``/``variation_node`` and a recorder.

1. ``generate`` with the default ``navigator`` section writes the five navigator topics; their
   values agree with an independent offline computation from the bag's own variation messages
   (``stream_from_messages`` → core navigator → ``navigation_errors`` on the E0 truth).
2. :class:`NavigatorStage` fed the bag's payloads one at a time (live order) publishes exactly
   the bag's payloads; with a dropped and a swapped IMU message it logs them, never integrates
   across the gap, and restarts from the truth.
3. trajectory_node → variation_node → navigator_node → recorder over real DDS: message for
   message the same payloads as ``generate`` (the acceptance test of issue 5).
"""

from __future__ import annotations

import time
from pathlib import Path

import node_testing as nt
import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.config import load_scenario, navigator_spec
from strapdown_ros.core.navigation import navigate_multirate, state_from_stream
from strapdown_ros.core.navigation.errors import navigation_errors
from strapdown_ros.messages import stream_from_messages
from strapdown_ros.plan import resolve_plan
from strapdown_ros.stages.navigator import NavigatorStage

REPO = Path(__file__).resolve().parent.parent
SCENARIO = nt.scenario_without_tf(REPO / "config" / "scenarios" / "default.yaml")
DURATION_S = 3.0
NAV_TOPICS = {
    "/navigator/odom": cdr.ODOMETRY,
    "/navigator/fix": cdr.NAVSATFIX,
    "/navigator/error/position": cdr.VECTOR3_STAMPED,
    "/navigator/error/velocity": cdr.VECTOR3_STAMPED,
    "/navigator/error/attitude": cdr.VECTOR3_STAMPED,
}
TIMEOUT_S = 90.0


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO, [], DURATION_S)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("generate") / "bag"
    return out, nt.generated(SCENARIO, out, DURATION_S, timeout=120)


def _variation_stream(contents, scenario):
    imu, odom = contents.topics["/variation/imu"], contents.topics["/variation/odom"]
    return stream_from_messages(
        imu.fields, odom.fields, scenario.gravity_model, e0_epoch_ns=scenario.start_time_ns
    )


def test_generate_writes_navigator_streams(bag, scenario) -> None:
    """Counts, stamps and values against an independent offline computation."""
    _, contents = bag
    settings = navigator_spec(scenario)
    assert (settings.algorithm, settings.mode, settings.imu_topic) == (
        "multirate",
        "exact",
        "/variation/imu",
    )
    stream = _variation_stream(contents, scenario)
    n = settings.n
    cycles = stream.cycles // n
    for topic in NAV_TOPICS:
        data = contents.topics[topic]
        assert data.msgtype == NAV_TOPICS[topic]
        assert len(data.payloads) == cycles + 1, topic
        expected = scenario.start_time_ns + np.arange(cycles + 1) * n * scenario.period_ns
        np.testing.assert_array_equal(np.asarray(data.fields.stamps_ns), expected)
    sol = navigate_multirate(
        state_from_stream(stream), stream.dalpha, stream.dv, stream.period, n, settings.p,
        mode="exact",
    )  # fmt: skip
    err = navigation_errors(sol, stream)
    pos = np.asarray(contents.topics["/navigator/error/position"].fields.vector)
    vel = np.asarray(contents.topics["/navigator/error/velocity"].fields.vector)
    att = np.asarray(contents.topics["/navigator/error/attitude"].fields.vector)
    # Both are at rounding level (the initial state goes through the Odometry quaternion).
    np.testing.assert_allclose(pos, err.position_ned, atol=2e-8)
    np.testing.assert_allclose(vel, err.velocity_ned, atol=1e-10)
    np.testing.assert_allclose(att, err.attitude_young, atol=1e-13)
    assert np.abs(pos).max() < 1e-6
    fix = contents.topics["/navigator/fix"].fields
    np.testing.assert_allclose(np.radians(np.asarray(fix.latitude)), sol.lat, rtol=0, atol=1e-15)


def _solver(scenario, warnings):
    """The stage as navigator_node builds it (period from the stamps, end from the scenario)."""
    spec = navigator_spec(scenario)
    return NavigatorStage.for_scenario(
        scenario, end_ns=resolve_plan(scenario).last_stamp(spec.imu_topic), warn=warnings.append,
        error=warnings.append,
    )  # fmt: skip


def _live_order(contents, drop: int | None = None, swap: int | None = None):
    """(kind, payload) in publication order: odom m, then imu m (variation_node's merge order)."""
    imu = contents.topics["/variation/imu"].payloads
    odom = contents.topics["/variation/odom"].payloads
    imu_items = [("imu", p) for p in imu]
    if drop is not None:
        del imu_items[drop]
    if swap is not None:
        imu_items[swap], imu_items[swap + 1] = imu_items[swap + 1], imu_items[swap]
    items = [("odom", odom[0])]
    for i, it in enumerate(imu_items):
        if i + 1 < len(odom):
            items.append(("odom", odom[i + 1]))
        items.append(it)
    return items


def test_solver_publishes_the_bag_payloads(bag, scenario) -> None:
    _, contents = bag
    warnings: list[str] = []
    solver = _solver(scenario, warnings)
    got: dict[str, list[bytes]] = {t: [] for t in NAV_TOPICS}
    for kind, payload in _live_order(contents):
        handler = solver.on_imu if kind == "imu" else solver.on_truth
        for topic, _, data in handler(payload):
            got[topic].append(bytes(data))
    assert not warnings
    assert solver.finished and solver.runs == 1
    for topic in NAV_TOPICS:
        assert got[topic] == [bytes(p) for p in contents.topics[topic].payloads], topic


def test_solver_gap_and_out_of_order(bag, scenario) -> None:
    """A missing IMU message ends the run at its last complete cycle and a new run starts from
    the truth; a swapped pair: the late one is dropped (logged), the early one is a gap."""
    _, contents = bag
    warnings: list[str] = []
    solver = _solver(scenario, warnings)
    got: dict[str, list[tuple[int, bytes]]] = {t: [] for t in NAV_TOPICS}
    drop = 123  # IMU message index 123 (cycle 124) missing
    for kind, payload in _live_order(contents, drop=drop):
        handler = solver.on_imu if kind == "imu" else solver.on_truth
        for topic, stamp, data in handler(payload):
            got[topic].append((stamp, bytes(data)))
    assert any("gap" in w and "missing" in w for w in warnings), warnings
    assert solver.runs == 2
    period, t0 = scenario.period_ns, scenario.start_time_ns
    stamps = [s for s, _ in got["/navigator/odom"]]
    assert stamps == sorted(set(stamps))
    # Run 1: outputs up to the last complete cycle before the gap equal the bag's.
    bag_odom = dict(
        zip(contents.topics["/navigator/odom"].fields.stamps_ns.tolist(),
            map(bytes, contents.topics["/navigator/odom"].payloads), strict=True)
    )  # fmt: skip
    first_run = [(s, p) for s, p in got["/navigator/odom"] if s < t0 + 124 * period]
    assert first_run and all(bag_odom[s] == p for s, p in first_run)
    assert max(s for s, _ in first_run) == t0 + 120 * period  # cycle 124 missing: last T_nav 120
    # Run 2 starts at cycle 124 (the truth before the next message, cycle 125), exact again.
    second = [s for s, _ in got["/navigator/odom"] if s >= t0 + 124 * period]
    assert second[0] == t0 + 124 * period and second[1] == t0 + 134 * period
    errs = cdr.deserialize(cdr.VECTOR3_STAMPED, [p for _, p in got["/navigator/error/position"]])
    assert np.abs(np.asarray(errs.vector)).max() < 1e-6  # restarted from truth: still exact

    warnings.clear()
    solver = _solver(scenario, warnings)
    for kind, payload in _live_order(contents, swap=200):
        handler = solver.on_imu if kind == "imu" else solver.on_truth
        handler(payload)
    assert any("gap" in w for w in warnings) and any("dropped" in w for w in warnings), warnings
    assert solver.runs == 2


@pytest.mark.parametrize("size", [1, 7, 40])
def test_solver_batches_equal_one_by_one(bag, scenario, size) -> None:
    """``on_batch`` (what the node calls) publishes what ``on_imu``/``on_truth`` one by one
    publish, in the same order, also across a gap, a repeat, a malformed payload and a truth
    message in the wrong frame (each reported as one by one)."""
    _, contents = bag
    items = [("truth" if k == "odom" else k, p) for k, p in _live_order(contents, drop=123)]
    items.insert(500, items[497])  # a repeated IMU message
    items.insert(700, ("imu", bytes(items[699][1])[:-8]))  # a malformed one
    k = next(i for i in range(900, len(items)) if items[i][0] == "truth")
    odom = cdr.deserialize(cdr.ODOMETRY, [items[k][1]])
    wrong = type(odom)(**{**odom.__dict__, "frame_id": "map"})
    items[k] = ("truth", bytes(cdr.serialize(wrong)[0]))
    want_log: list[str] = []
    one = _solver(scenario, want_log)
    want = []
    for kind, payload in items:
        want += (one.on_imu if kind == "imu" else one.on_truth)(payload)
    got_log: list[str] = []
    batched = _solver(scenario, got_log)
    got = []
    for i in range(0, len(items), size):
        got += batched.on_batch(items[i : i + size])
    assert [(t, s, bytes(d)) for t, s, d in got] == [(t, s, bytes(d)) for t, s, d in want]
    assert got_log == want_log and any("'map'" in w for w in got_log)
    assert batched.runs == one.runs >= 2 and batched.finished


def test_scenario_rejects_bad_navigator_sections() -> None:
    from strapdown_ros.config import ScenarioError

    cases = {
        "navigator.mode=rk4": "navigator.mode",
        "navigator.algorithm=simultaneous": "navigator.mode",  # default mode exact: not Table 2
        "navigator.n=0": "navigator.n",
        "navigator.imu_topic=/nope": "navigator.imu_topic",
        "navigator.imu_topic=/variation/imu_measured": "navigator.imu_topic",
        "navigator.initial_errors.position_ned_m=[1, 2]": "navigator.initial_errors.position_ned_m",
        "navigator.vertical_damping={k1: 1}": "navigator.vertical_damping",
        "navigator.frobnicate=1": "navigator.frobnicate",
    }
    for override, key in cases.items():
        extra = ["imu_errors=null", "aided=null"] if "imu_measured" in override else []
        with pytest.raises(ScenarioError) as info:
            load_scenario(SCENARIO, [*extra, override], 1.0)
        assert info.value.key == key, (override, str(info.value))


def test_initial_errors_show_in_the_first_output(scenario) -> None:
    from strapdown_ros.stages.navigator import initial_state_from_truth
    from strapdown_ros.stages.trajectory import generate_reference

    s = load_scenario(
        SCENARIO,
        ["navigator.initial_errors={position_ned_m: [3, -4, 1], velocity_ned_mps: [0.1, 0, 0],"
         " attitude_rph_deg: [0, 0, 0.01]}"],
        1.0,
    )  # fmt: skip
    settings = navigator_spec(s)
    ref = generate_reference(s)
    from strapdown_ros.messages import odometry_fields, odometry_state

    truth = odometry_state(odometry_fields(ref))
    st = initial_state_from_truth(truth, 0, settings)
    from strapdown_ros.core.navigation import NavSolution
    from strapdown_ros.core.navigation.errors import navigation_errors

    sol = NavSolution(
        np.array([0.0]), np.array([st.lat]), np.array([st.lon]), np.array([st.alt]),
        st.v_ned[None], st.q_b_n[None], 1,
    )  # fmt: skip
    err = navigation_errors(sol, ref)
    np.testing.assert_allclose(err.position_ned[0], [3, -4, 1], atol=1e-8)
    np.testing.assert_allclose(err.velocity_ned[0], [0.1, 0, 0], atol=1e-12)
    # A heading error of 0.01°: the Young angle about the vertical (θ1, up) is -0.01° (the
    # computed level frame is rotated by +0.01° about down relative to the true one).
    assert abs(abs(err.attitude_young[0, 0]) - np.radians(0.01)) < 1e-9
    assert np.abs(err.attitude_young[0, 1:]).max() < 1e-9


# ---------------------------------------------------------------------------------------------
# 3. Three nodes as processes over DDS
# ---------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_three_node_pipeline_equals_generate(bag, procs, ros_env, tmp_path) -> None:
    _, contents = bag
    deadline = time.monotonic() + TIMEOUT_S
    # The recorder also takes variation_node's other outputs (it waits for a subscription on
    # each before subscribing to the reference).
    others = {
        "/variation/fix": cdr.NAVSATFIX,
        "/variation/reference/imu": cdr.IMU,
        "/variation/reference/odom": cdr.ODOMETRY,
    }
    counts = {t: len(contents.topics[t].payloads) for t in [*NAV_TOPICS, *others]}
    topics = [(t, msgtype, counts[t]) for t, msgtype in [*NAV_TOPICS.items(), *others.items()]]
    rec, out = nt.raw_recorder(procs, ros_env, tmp_path, topics, TIMEOUT_S - 10)
    common = [f"scenario:={SCENARIO}", f"duration_s:={DURATION_S}"]

    def node(name: str, *params: str) -> nt.Proc:
        return nt.launch(procs, nt.node_args(name, *common, *params), ros_env, tmp_path, name)

    nav = node("navigator_node", "wait_for_subscribers:=1", "qos_depth:=5000")
    nav.wait_for(r"subscribed to /variation/imu", deadline)
    var = node("variation_node", "wait_for_subscribers:=1", "qos_depth:=5000")
    var.wait_for(r"subscribed to /reference/imu", deadline)
    traj = node(
        "trajectory_node", "rate_factor:=1.0", "time_source:=wall", "wait_for_subscribers:=1",
        "wait_for_all_topics:=false", "qos_depth:=5000",
    )  # fmt: skip
    nt.wait_ok(deadline, traj, var, nav, rec)
    nt.assert_clean(var, nav, warnings=False)
    recorded = nt.load_recording(out)["topics"]
    for topic in NAV_TOPICS:
        want = [bytes(p) for p in contents.topics[topic].payloads]
        got = [bytes(p)[: len(w)] for p, w in zip(recorded[topic], want, strict=True)]
        assert got == want, topic
