"""The navigator's typed section, its node parameters and the one streaming navigation stage.

* :class:`NavigatorSpec`: defaults (the algorithm-dependent mode, the truth topic of the input
  stream, the scenario's gravitation model), every bad key or value named by its dotted key,
  and the cross-field rules against the rest of the scenario.
* ``navigator_node``'s parameters go through the same model and name the parameter.
* :class:`NavigatorStage`: the same ``/navigator/*`` bytes for any chunking and any input form
  (decoded fields, raw payloads, ``generate``'s batches); errors from ``core/navigation/errors``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch
from strapdown_ros.config import (
    DEFAULT_TOPICS,
    ScenarioError,
    load_scenario,
    navigator_spec,
    parse_scenario,
)
from strapdown_ros.config.base import validate_section
from strapdown_ros.config.navigator import NavigatorSpec, resolve_navigator
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.messages import stream_fields
from strapdown_ros.stages.navigator import NavigatorStage, navigate_messages
from strapdown_ros.stages.trajectory import generate_reference

REPO = Path(__file__).resolve().parent.parent
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"
BASE = {
    "rate_hz": 200,
    "duration_s": 2,
    "initial": {"latitude_deg": 45.0, "longitude_deg": 7.0, "altitude_m": 300.0},
    "trajectory": {"kind": "segments", "segments": [{"duration_s": 2, "accel_mps2": 1.0}]},
}


def scenario_with(navigator, **changes):
    return parse_scenario({**BASE, "navigator": navigator, **changes})


# ---------------------------------------------------------------------------------------------
# The model


def test_defaults_and_resolution() -> None:
    s = scenario_with({}, variation={}, gravity_model="spherical")
    assert s.navigator == NavigatorSpec()
    assert s.navigator.mode is None and not s.navigator.resolved
    spec = navigator_spec(s)
    assert spec.resolved
    assert (spec.algorithm, spec.mode, spec.n, spec.p) == ("multirate", "exact", 10, 2)
    assert (spec.imu_topic, spec.truth_topic) == ("/variation/imu", "/variation/odom")
    assert spec.gravity_model == "spherical" and spec.frame_id == "navigator"
    assert spec.initialization == "truth" and spec.vertical_damping is None
    assert spec.normalize_quaternion and not spec.table1_radii
    np.testing.assert_array_equal(spec.attitude_error_rph, np.zeros(3))
    # Table 2's default mode is paper; the truth follows the input stream.
    spec = navigator_spec(
        scenario_with({"algorithm": "simultaneous", "imu_topic": "/reference/imu"})
    )
    assert (spec.mode, spec.truth_topic) == ("paper", "/reference/odom")
    # null is the default, except truth_topic: no truth; vertical_damping: true is {}.
    spec = navigator_spec(scenario_with(
        {"imu_topic": "/reference/imu", "n": None, "truth_topic": None, "mode": "paper",
         "initialization": "scenario", "vertical_damping": False,
         "initial_errors": {"attitude_rph_deg": [0, 0, 180]}}
    ))  # fmt: skip
    assert spec.n == 10 and spec.truth_topic == "" and spec.vertical_damping is None
    np.testing.assert_array_equal(spec.attitude_error_rph, [0.0, 0.0, np.pi])
    spec = navigator_spec(
        scenario_with({"imu_topic": "/reference/imu", "mode": "paper", "vertical_damping": True})
    )
    assert (spec.vertical_damping.k1, spec.vertical_damping.paper_signs) == (1.0, False)


@pytest.mark.parametrize(
    ("section", "changes", "key", "words"),
    [
        ({"mode": "rk4"}, {}, "navigator.mode", "one of"),
        ({"algorithm": "table3"}, {}, "navigator.algorithm", "one of"),
        ({"algorithm": "simultaneous", "mode": "exact"}, {}, "navigator.mode", "only 'paper'"),
        ({"n": 0}, {}, "navigator.n", ">= 1"),
        ({"p": 1.5}, {}, "navigator.p", "integer"),
        ({"n": True}, {}, "navigator.n", "integer"),
        ({"imu_topic": "reference/imu"}, {}, "navigator.imu_topic", "absolute"),
        ({"imu_topic": "/nope"}, {}, "navigator.imu_topic", "not an IMU stream"),
        ({}, {}, "navigator.imu_topic", "needs a 'variation' section"),
        ({"imu_topic": "/variation/imu_measured"}, {"variation": {}}, "navigator.imu_topic",
         "needs a 'imu_errors' section"),
        ({"imu_topic": "/reference/imu", "truth_topic": "odom"}, {}, "navigator.truth_topic",
         "absolute topic name or empty"),
        ({"imu_topic": "/reference/ imu"}, {}, "navigator.imu_topic", "absolute topic name"),
        ({"imu_topic": "/reference/imu", "frame_id": "imu link"}, {}, "navigator.frame_id",
         "frame id"),
        ({"imu_topic": "/reference/imu", "truth_topic": "/variation/odom"}, {},
         "navigator.truth_topic", "needs a 'variation' section"),
        ({"imu_topic": "/reference/imu", "truth_topic": "/reference/fix"}, {},
         "navigator.truth_topic", "not an Odometry stream"),
        ({"imu_topic": "/reference/imu", "truth_topic": ""}, {}, "navigator.initialization",
         "needs a truth_topic"),
        ({"initialization": "scenario"}, {"variation": {}}, "navigator.initialization",
         "reference IMU"),
        ({"imu_topic": "/reference/imu", "initialization": "guess"}, {},
         "navigator.initialization", "one of"),
        ({"imu_topic": "/reference/imu", "initial_errors": {"position_ned_m": [1, 2]}}, {},
         "navigator.initial_errors.position_ned_m", "3 numbers"),
        ({"imu_topic": "/reference/imu", "initial_errors": {"velocity_ned_mps": [0, 0, ".1"]}},
         {}, "navigator.initial_errors.velocity_ned_mps[2]", "number"),
        ({"imu_topic": "/reference/imu", "initial_errors": {"heading": 1}}, {},
         "navigator.initial_errors.heading", "unknown key"),
        ({"imu_topic": "/reference/imu", "vertical_damping": {"k1": 1}}, {},
         "navigator.vertical_damping", "'paper' mode"),
        ({"imu_topic": "/reference/imu", "mode": "paper", "vertical_damping": {"k2": -1}}, {},
         "navigator.vertical_damping.k2", ">= 0"),
        ({"imu_topic": "/reference/imu", "mode": "paper", "vertical_damping": 3}, {},
         "navigator.vertical_damping", "true, false or a mapping"),
        ({"imu_topic": "/reference/imu", "mode": "paper", "vertical_damping": True,
          "truth_topic": "", "initialization": "scenario"}, {}, "navigator.vertical_damping",
         "needs a truth_topic"),
        ({"imu_topic": "/reference/imu", "gravity_model": "egm"}, {}, "navigator.gravity_model",
         "one of"),
        ({"imu_topic": "/reference/imu", "table1_radii": "yes"}, {}, "navigator.table1_radii",
         "true or false"),
        ({"imu_topic": "/reference/imu", "frame_id": "nav frame"}, {}, "navigator.frame_id",
         "frame id"),
        ({"imu_topic": "/reference/imu", "frobnicate": 1}, {}, "navigator.frobnicate",
         "unknown key"),
        ([1, 2], {}, "navigator", "mapping"),
    ],
)  # fmt: skip
def test_bad_sections_name_the_key(section, changes, key, words) -> None:
    with pytest.raises(ScenarioError) as info:
        scenario_with(section, **changes)
    assert info.value.key == key, str(info.value)
    assert words in info.value.problem, str(info.value)
    assert str(info.value).startswith(f"{key}: ")


def test_scenario_initialization_needs_the_initial_state() -> None:
    """A samples trajectory has no ``initial``: ``initialization: scenario`` is rejected."""
    s = scenario_with({"imu_topic": "/reference/imu", "initialization": "scenario"})
    assert navigator_spec(s).initialization == "scenario"
    doc = {
        "rate_hz": 200,
        "trajectory": {"kind": "samples", "file": "truth.csv"},
        "navigator": {"imu_topic": "/reference/imu", "initialization": "scenario"},
    }
    with pytest.raises(ScenarioError) as info:
        parse_scenario(doc)
    assert info.value.key == "navigator.initialization" and "'initial'" in info.value.problem


def test_node_parameters_go_through_the_model() -> None:
    pytest.importorskip("rclpy")
    from strapdown_ros.nodes.navigator_node import navigator_section
    from strapdown_ros.nodes.parameters import ParameterError

    s = load_scenario(DEFAULT, [], 1.0)
    spec = navigator_section(s, {"imu_topic": "/reference/imu", "n": 4})  # the file's truth
    assert (spec.imu_topic, spec.truth_topic, spec.n, spec.mode) == (
        "/reference/imu", "/variation/odom", 4, "exact",
    )  # fmt: skip
    spec = navigator_section(None, {"algorithm": "simultaneous", "truth_topic": "/my/odom"})
    assert (spec.mode, spec.truth_topic, spec.gravity_model) == ("paper", "/my/odom", "j2")
    cases = [
        (s, {"mode": "rk4"}, "mode", "one of"),
        (s, {"algorithm": "simultaneous"}, "mode", "only 'paper'"),  # the file's mode: exact
        (s, {"imu_topic": "/nope"}, "imu_topic", "not an IMU stream"),
        (None, {"imu_topic": "my/imu"}, "imu_topic", "absolute"),
        (None, {"truth_topic": ""}, "initialization", "needs a truth_topic"),
        (None, {"initialization": "scenario", "imu_topic": "/reference/imu"}, "initialization",
         "needs a scenario"),
    ]  # fmt: skip
    for scenario, overrides, name, words in cases:
        with pytest.raises(ParameterError) as info:
            navigator_section(scenario, overrides)
        assert info.value.name == name and words in info.value.problem, str(info.value)


def test_node_without_scenario_has_the_model_defaults() -> None:
    spec = resolve_navigator(validate_section(NavigatorSpec, {}), DEFAULT_TOPICS, "j2")
    assert (spec.imu_topic, spec.truth_topic, spec.mode) == (
        "/variation/imu", "/variation/odom", "exact",
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------
# The stage


@pytest.fixture(scope="module")
def reference_input():
    """A 3 s flight's reference Imu / Odometry fields and the scenario navigating on them."""
    s = load_scenario(
        DEFAULT,
        ["variation=null", "imu_errors=null", "aided=null", "navigator.imu_topic=/reference/imu",
         "navigator.truth_topic=/reference/odom",
         "navigator.initial_errors.attitude_rph_deg=[0.01, 0, 0]"],
        3.0,
    )  # fmt: skip
    f = stream_fields(generate_reference(s), navsatfix=False)
    return s, f.imu, f.odometry


def _live_order(imu, odom) -> np.ndarray:
    """is_imu of odom 0, then (odom m, imu m) alternately, the variation/trajectory order."""
    n_odom, n_imu = len(odom.stamps_ns), len(imu.stamps_ns)
    order = [False]
    for i in range(n_imu):
        if i + 1 < n_odom:
            order.append(False)
        order.append(True)
    return np.array(order)


def _by_topic(messages):
    out: dict[str, list[bytes]] = {}
    for topic, _, payload in messages:
        out.setdefault(topic, []).append(bytes(payload))
    return out


def test_any_chunking_and_input_form_gives_the_same_bytes(reference_input) -> None:
    s, imu, odom = reference_input
    order = _live_order(imu, odom)
    whole = NavigatorStage.for_scenario(s).feed_fields(imu, odom, order)
    assert len(whole) == 5 * (len(imu.stamps_ns) // 10 + 1)
    imu_rows = np.concatenate([[0], np.cumsum(order)])
    rng = np.random.default_rng(3)
    for _ in range(3):
        stage = NavigatorStage.for_scenario(s)
        got, k = [], 0
        while k < order.size:
            m = int(rng.integers(1, 60))
            a, b = imu_rows[k], imu_rows[min(k + m, order.size)]
            t0, t1 = k - a, min(k + m, order.size) - b
            got += stage.feed_fields(imu.rows(a, b), odom.rows(t0, t1), order[k : k + m])
            k += m
        assert [(t, st, bytes(p)) for t, st, p in got] == [
            (t, st, bytes(p)) for t, st, p in whole
        ]
    # Raw payloads, one batch per cycle, as the node gets them.
    imu_p, odom_p = cdr.serialize(imu), cdr.serialize(odom)
    items, i_imu, i_odom = [], 0, 0
    for is_imu in order:
        if is_imu:
            items.append(("imu", imu_p[i_imu]))
            i_imu += 1
        else:
            items.append(("truth", odom_p[i_odom]))
            i_odom += 1
    stage = NavigatorStage.for_scenario(s)
    got = []
    for k in range(0, len(items), 2):
        got += stage.on_batch(items[k : k + 2])
    assert _by_topic(got) == _by_topic(whole) and stage.runs == 1
    # generate's pieces (period given): truth then Imu of each piece.
    stage = NavigatorStage.for_scenario(s, period_ns=s.period_ns)
    batches: list[Batch] = []
    for a in range(0, len(imu.stamps_ns), 137):
        b = min(a + 137, len(imu.stamps_ns))
        t1 = b + 1 if b == len(imu.stamps_ns) else b
        pieces = [
            Batch("/reference/odom", cdr.ODOMETRY, odom.stamps_ns[a:t1], odom_p[a:t1]),
            Batch("/reference/imu", cdr.IMU, imu.stamps_ns[a:b], imu_p[a:b]),
        ]
        batches += stage.feed_batches(pieces)
    by_batch: dict[str, list[bytes]] = {}
    for bt in batches:
        by_batch.setdefault(bt.topic, []).extend(bytes(p) for p in bt.payloads)
    assert by_batch == _by_topic(whole)
    # The replay's offline reference is the same object fed whole topics in stamp order.
    offline = navigate_messages(
        navigator_spec(s), imu, odom, output_topics=dict(stage.output_topics)
    )
    assert {stage.output_topics[k]: v for k, v in offline.items()} == _by_topic(whole)


def test_errors_come_from_core_errors(reference_input) -> None:
    """The error topics are the core formulas on the decoded output and the truth."""
    from strapdown_ros.core.earth import ecef_to_geodetic
    from strapdown_ros.messages import odometry_state

    s, imu, odom = reference_input
    stage = NavigatorStage.for_scenario(s)
    out = _by_topic(stage.feed_fields(imu, odom, _live_order(imu, odom)))
    nav = odometry_state(cdr.deserialize(cdr.ODOMETRY, out["/navigator/odom"]))
    truth = odometry_state(odom)
    rows = np.searchsorted(truth.stamps_ns, nav.stamps_ns)
    lat, lon, _ = ecef_to_geodetic(truth.r_e[rows])
    pos = cdr.deserialize(cdr.VECTOR3_STAMPED, out["/navigator/error/position"]).vector
    np.testing.assert_allclose(
        pos, position_error_ned(nav.r_e, truth.r_e[rows], lat, lon), rtol=0, atol=1e-9
    )
    att = cdr.deserialize(cdr.VECTOR3_STAMPED, out["/navigator/error/attitude"]).vector
    att = np.asarray(att)
    # A roll offset of 0.01°: a tilt of the computed level frame by 0.01° (about a level axis).
    assert abs(np.linalg.norm(att[0]) - np.radians(0.01)) < 1e-3 * np.radians(0.01)
    assert abs(att[0, 0]) < 0.1 * np.radians(0.01)
    # The formulas themselves on constructed values.
    v = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(velocity_error_ned(v, v * 0.5), v * 0.5)
    np.testing.assert_allclose(
        position_error_ned(np.array([[1.0, 0, 0]]), np.zeros((1, 3)), np.zeros(1), np.zeros(1)),
        [[0.0, 0.0, -1.0]], atol=1e-15,
    )  # at (0, 0) ECEF x is up: NED (0, 0, -1)
    assert np.all(attitude_error_young(np.eye(3)[None], np.eye(3)[None]) == 0.0)


def test_scenario_initialization_and_nav_period(reference_input) -> None:
    s, imu, odom = reference_input
    spec = navigator_spec(s).model_copy(update={"initialization": "scenario", "truth_topic": ""})
    stage = NavigatorStage.for_scenario(s, spec=spec)
    out = _by_topic(stage.feed_fields(imu, None))
    assert set(out) == {"/navigator/odom", "/navigator/fix"}
    assert len(out["/navigator/odom"]) == len(imu.stamps_ns) // 10 + 1
    # nav_period_s: N from the detected T (5 ms): 0.02 s is N = 4; 0.0123 s is refused.
    stage = NavigatorStage.for_scenario(s, nav_period_s=0.02)
    out = _by_topic(stage.feed_fields(imu, odom, _live_order(imu, odom)))
    assert stage.n == 4 and len(out["/navigator/odom"]) == len(imu.stamps_ns) // 4 + 1
    logged: list[str] = []
    stage = NavigatorStage.for_scenario(s, nav_period_s=0.0123, error=logged.append)
    assert stage.feed_fields(imu, odom, _live_order(imu, odom)) == []
    assert stage.failed and "whole multiple" in logged[0]
