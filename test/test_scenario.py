"""Scenario loading, overrides and validation: every bad input names its key (interface.md §5)."""

import textwrap

import pytest

from strapdown_ros.config import ScenarioError, apply_overrides, load_scenario, parse_scenario

BASE = {
    "rate_hz": 200,
    "duration_s": 10,
    "initial": {"latitude_deg": 45.0, "longitude_deg": 7.0, "altitude_m": 300.0},
    "trajectory": {"kind": "segments", "segments": [{"duration_s": 10}]},
}


def with_(**changes):
    doc = {k: (dict(v) if isinstance(v, dict) else v) for k, v in BASE.items()}
    doc.update(changes)
    return doc


def error_of(doc) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(doc)
    return info.value


def test_valid_minimal_scenario_has_defaults():
    s = parse_scenario(BASE)
    assert s.period_ns == 5_000_000 and s.oversample == 1 and s.gravity_model == "j2"
    assert s.start_time_ns == 0 and s.recording.storage == "mcap"
    assert s.recording.topics["reference_imu"] == "/reference/imu"
    assert s.initial.velocity_ned_mps == (0.0, 0.0, 0.0)


def test_unknown_top_level_key():
    err = error_of(with_(rate=100))
    assert err.key == "rate" and "unknown key" in str(err)


def test_unknown_nested_key():
    doc = with_(initial={**BASE["initial"], "heading_deg": 3})
    err = error_of(doc)
    assert err.key == "initial.heading_deg"


def test_wrong_type():
    err = error_of(with_(rate_hz="fast"))
    assert err.key == "rate_hz" and "must be a number" in str(err)
    err = error_of(with_(initial={**BASE["initial"], "velocity_ned_mps": [1, 2]}))
    assert err.key == "initial.velocity_ned_mps"


def test_nan_anywhere_is_rejected_with_its_key():
    err = error_of(with_(duration_s=float("nan")))
    assert err.key == "duration_s" and "finite" in str(err)
    doc = with_(trajectory={"kind": "segments", "segments": [{"duration_s": float("nan")}]})
    err = error_of(doc)
    assert err.key == "trajectory.segments[0].duration_s"


def test_non_integer_nanosecond_period():
    err = error_of(with_(rate_hz=300))
    assert err.key == "rate_hz" and "integer number of nanoseconds" in str(err)
    parse_scenario(with_(rate_hz=1.0 / 9.996e-2 * 12))  # Waldmann's T_gyr = 8.33 ms is fine


def test_oversample_below_one_and_non_integer_generation_period():
    assert error_of(with_(oversample=0)).key == "oversample"
    assert error_of(with_(oversample=1.5)).key == "oversample"
    # 1 kHz: 1e6 ns / 3 is not integral
    err = error_of(with_(rate_hz=1000, oversample=3))
    assert err.key == "oversample" and "integer number of nanoseconds" in str(err)


def test_bad_choices():
    assert error_of(with_(gravity_model="egm96")).key == "gravity_model"
    assert error_of(with_(trajectory={"kind": "teleport"})).key == "trajectory.kind"
    err = error_of(with_(recording={"storage": "bag"}))
    assert err.key == "recording.storage"
    err = error_of(with_(recording={"topics": {"reference_imu": "imu"}}))
    assert err.key == "recording.topics.reference_imu"


def test_missing_required():
    doc = with_()
    del doc["rate_hz"]
    assert error_of(doc).key == "rate_hz"
    doc = with_()
    del doc["trajectory"]
    assert error_of(doc).key == "trajectory"
    assert error_of(with_(initial={"longitude_deg": 3})).key == "initial.latitude_deg"


def test_out_of_range_values():
    assert error_of(with_(initial={"latitude_deg": 91, "longitude_deg": 0})).key == (
        "initial.latitude_deg"
    )
    assert error_of(with_(duration_s=-1)).key == "duration_s"


def test_overrides_parse_yaml_values_and_index_lists():
    doc = apply_overrides(
        BASE,
        [
            "variation.lever_arm_m=[1,0,0]",
            "rate_hz=400",
            "trajectory.segments.0.duration_s=5",
            "recording.storage=sqlite3",
        ],
    )
    assert doc["variation"] == {"lever_arm_m": [1, 0, 0]}
    assert doc["rate_hz"] == 400
    assert doc["trajectory"]["segments"][0]["duration_s"] == 5
    assert BASE["rate_hz"] == 200  # the input is not modified
    with pytest.raises(ScenarioError, match="dotted.key=value"):
        apply_overrides(BASE, ["rate_hz"])
    with pytest.raises(ScenarioError) as info:
        apply_overrides(BASE, ["trajectory.segments.3.duration_s=1"])
    assert info.value.key == "trajectory.segments.3.duration_s"


def test_load_from_file_with_overrides_and_duration(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(
        textwrap.dedent(
            """
            rate_hz: 100
            initial: {latitude_deg: 10, longitude_deg: 20}
            trajectory: {kind: segments, segments: [{duration_s: 60}]}
            """
        )
    )
    s = load_scenario(path, ["gravity_model=spherical"], duration_s=2.0)
    assert s.gravity_model == "spherical" and s.duration_s == 2.0 and s.base_dir == tmp_path
    path.write_text("rate_hz: [\n")
    with pytest.raises(ScenarioError, match="not valid YAML"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "missing.yaml")
    path.write_text("rate_hz: .nan\ninitial: {latitude_deg: 1, longitude_deg: 2}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "rate_hz"


def test_variation_method_and_gravity_are_checked_at_load():
    for section, key in (({"method": 3}, "variation.method"),
                         ({"gravity": "egm"}, "variation.gravity"),
                         ({"lever_arm_m": [1, 2]}, "variation.lever_arm_m")):  # fmt: skip
        assert error_of(with_(variation=section)).key == key
    assert parse_scenario(with_(variation={"method": 1, "lever_arm_m": [1, 0, 0]})).variation


# -- trajectory section (config/trajectory.py) ---------------------------------------------------


def test_trajectory_kinds_load_typed_with_their_defaults():
    from strapdown_ros.config.trajectory import (
        ConingTrajectorySpec,
        IncrementsTrajectorySpec,
        SamplesTrajectorySpec,
        SegmentsTrajectorySpec,
    )

    seg = parse_scenario(BASE).trajectory
    assert isinstance(seg, SegmentsTrajectorySpec) and seg.natural_duration == 10.0
    s0 = seg.segments[0]
    assert (s0.roll_rate_dps, s0.accel_mps2, s0.climb_rate_mps, s0.transition_s) == (
        0.0, None, None, None)  # fmt: skip
    assert s0.core_segment().blend == 1.0  # min(1, duration / 2)
    inc = parse_scenario(with_(trajectory={"kind": "increments", "segments": [
        {"duration_s": 2}, {"duration_s": 0.5, "omega_dps": [0, 0, 180]}]})).trajectory  # fmt: skip
    assert isinstance(inc, IncrementsTrajectorySpec) and inc.natural_duration == 2.5
    assert inc.core_segments()[1].omega[2] == pytest.approx(3.141592653589793)
    con = parse_scenario(with_(trajectory={"kind": "coning"})).trajectory
    assert isinstance(con, ConingTrajectorySpec) and con.coning.duration_s == 300.0
    sam = parse_scenario({"rate_hz": 100, "trajectory": {"kind": "samples", "bag": "b"}})
    assert isinstance(sam.trajectory, SamplesTrajectorySpec) and sam.initial is None
    assert sam.trajectory.odometry_topic == "/reference/odom"
    assert sam.trajectory.source_key == "trajectory.bag"


@pytest.mark.parametrize(
    ("trajectory", "key"),
    [
        ({"kind": "segments", "segments": []}, "trajectory.segments"),
        ({"kind": "segments", "segments": [{"duration_s": 0}]},
         "trajectory.segments[0].duration_s"),
        ({"kind": "segments", "segments": [{"duration_s": 1, "accel_mps2": None}]},
         "trajectory.segments[0].accel_mps2"),
        ({"kind": "segments", "segments": [{"duration_s": 1}], "coning": {}}, "trajectory.coning"),
        ({"kind": "increments", "segments": [{"duration_s": 1, "omega_dps": [0, 0]}]},
         "trajectory.segments[0].omega_dps"),
        ({"kind": "increments", "segments": [{"duration_s": 0.0125}]},
         "trajectory.segments[0].duration_s"),
        ({"kind": "coning", "coning": {"duration_s": -3}}, "trajectory.coning.duration_s"),
        ({"kind": "coning", "coning": {"theta_deg": 200}}, "trajectory.coning.theta_deg"),
        ({"kind": "samples"}, "trajectory.file"),
        ({"kind": "samples", "file": "x.csv", "degree": {"position": True}},
         "trajectory.degree.position"),
        ({"segments": [{"duration_s": 1}]}, "trajectory.kind"),
    ],
)  # fmt: skip
def test_trajectory_errors_name_the_key(trajectory, key):
    assert error_of(with_(trajectory=trajectory)).key == key


def test_initial_is_required_except_for_samples():
    doc = with_()
    del doc["initial"]
    for kind in ({"kind": "segments", "segments": [{"duration_s": 1}]}, {"kind": "coning"},
                 {"kind": "increments", "segments": [{"duration_s": 1}]}):  # fmt: skip
        assert error_of({**doc, "trajectory": kind}).key == "initial"
    parse_scenario({**doc, "trajectory": {"kind": "samples", "file": "x.csv"}})


def test_latitude_rule_differs_by_kind():
    """±90° for increments (integrated in E0); ±89.9° for segments and coning (1/cos φ)."""
    pole = {"latitude_deg": 90.0, "longitude_deg": 0.0}
    parse_scenario(with_(initial=pole, trajectory={"kind": "increments",
                                                   "segments": [{"duration_s": 1}]}))  # fmt: skip
    for trajectory in ({"kind": "segments", "segments": [{"duration_s": 1}]}, {"kind": "coning"}):
        err = error_of(with_(initial=pole, trajectory=trajectory))
        assert err.key == "initial.latitude_deg" and "89.9" in err.problem
