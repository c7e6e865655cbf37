"""The scorer (strapdown_ros/score/, docs/score.md) on bags read back from disk.

Expected values come from elsewhere than the scorer: the navigator's own error topics
(/navigator/error/*), the published truth samples, pyins' integrator and draws of a known
covariance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.bag.batches import batch
from strapdown_ros.bag.reader import read_bag
from strapdown_ros.bag.writer import BagWriter
from strapdown_ros.config import load_scenario
from strapdown_ros.core.earth import (
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.rotations import dcm_from_euler, dcm_from_rotvec
from strapdown_ros.generate import generate_dataset
from strapdown_ros.messages import odometry_fields_from_ecef, odometry_state, tf_message_fields
from strapdown_ros.messages.frames import dcm_from_quat_ros, quat_ros_from_dcm
from strapdown_ros.score.metrics import along_cross_track, outage_drift, time_offset_step
from strapdown_ros.score.scorer import score_bag

SCENARIO = """
name: score_car
rate_hz: 100
duration_s: 10
start_time_s: 1767225600.0
initial:
  latitude_deg: 52.52
  longitude_deg: 13.405
  altitude_m: 34.0
  velocity_ned_mps: [10.0, 0.0, 0.0]
  attitude_rph_deg: [0.0, 0.0, 0.0]
trajectory:
  kind: segments
  segments:
    - {duration_s: 3, accel_mps2: 1.0, transition_s: 1}
    - {duration_s: 4, heading_rate_dps: 15, roll_rate_dps: 1.0, transition_s: 1}
    - {duration_s: 3, heading_rate_dps: 0, roll_rate_dps: -1.0, transition_s: 1}
navigator: {mode: exact, n: 10, p: 2, imu_topic: /reference/imu, truth_topic: /reference/odom}
aiding:
  gnss: {preset: spp, rate_hz: 1, outages: [[3, 6]], seed: 1}
"""

LEVER = np.array([0.8, -0.4, -1.3])  # m, FRD of the reference IMU
MOUNT_RPH_DEG = np.array([2.0, -5.0, 30.0])


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    root = tmp_path_factory.mktemp("score")
    (root / "score_car.yaml").write_text(SCENARIO)
    scenario = load_scenario(root / "score_car.yaml")
    generate_dataset(scenario, root / "bag")
    return root, scenario


def _errors(bag: Path) -> dict[str, np.ndarray]:
    b = read_bag(bag, [f"/navigator/error/{k}" for k in ("position", "velocity", "attitude")])
    return {k: np.asarray(b[f"/navigator/error/{k}"].vector) for k in
            ("position", "velocity", "attitude")}  # fmt: skip


def _write(path: Path, topic: str, fields: object, tf: object = None) -> Path:
    with BagWriter(path) as w:
        batches = [batch(topic, fields)]
        if tf is not None:
            batches.insert(0, batch("/tf_static", tf))
        w.write_batches(batches)
    return path


@pytest.mark.slow
def test_navigator_output_reproduces_its_error_topics(case) -> None:
    """Odometry (ECEF and map) and NavSatFix of the navigator give back /navigator/error/*
    (issue limits 1e-9 m, 1e-12 rad; measured 0 m, 1.1e-14 m/s, 4e-16 rad for Odometry and
    9.5e-10 m for NavSatFix, whose degrees carry 0.5 ulp ≈ 4e-10 m per axis)."""
    root, scenario = case
    want = _errors(root / "bag")
    for topic in ("/navigator/odom", "/navigator/odom_map"):
        s = score_bag(root / "bag", topic, scenario=scenario)
        assert len(s.stamps_ns) == len(want["position"])
        assert np.abs(s.position_ned - want["position"]).max() <= 1e-9
        assert np.abs(s.velocity_ned - want["velocity"]).max() <= 1e-12
        assert np.abs(s.attitude_young - want["attitude"]).max() <= 1e-12
    fix = score_bag(root / "bag", "/navigator/fix", scenario=scenario)
    assert np.abs(fix.position_ned - want["position"]).max() <= 1e-9
    assert fix.velocity_ned is None and fix.attitude_young is None
    # the outage of the scenario: the drift between the navigator's errors at 3 s and 5.9 s
    (o,) = fix.outages
    i0, i1 = 30, 59  # outputs every 0.1 s
    assert o.first_stamp_ns == fix.stamps_ns[i0] and o.last_stamp_ns == fix.stamps_ns[i1]
    assert o.drift_m == pytest.approx(np.hypot(*(want["position"][i1, :2]
                                                 - want["position"][i0, :2])), abs=2e-9)


@pytest.mark.slow
def test_a_10_ms_stamp_offset_is_found(case) -> None:
    """The navigator's odometry re-stamped 10 ms late, in a bag of its own: 10 ms ± 0.1 ms
    (measured 10.0000012 ms; the navigator's own 1e-8 m errors leave 1e-9 s)."""
    root, scenario = case
    odom = read_bag(root / "bag", ["/navigator/odom"])["/navigator/odom"]
    late = type(odom)(**{**odom.__dict__, "stamps_ns": odom.stamps_ns + 10_000_000})
    est = _write(root / "late", "/est", late)
    s = score_bag(root / "bag", "/est", estimate_bag=est, scenario=scenario)
    assert s.summary["time_offset"]["offset_s"] == pytest.approx(0.010, abs=1e-4)
    assert s.summary["outside_truth"] == 1  # the last one is past the truth
    early = type(odom)(**{**odom.__dict__, "stamps_ns": odom.stamps_ns - 4_000_000})
    est = _write(root / "early", "/est", early)
    s = score_bag(root / "bag", "/est", estimate_bag=est, scenario=scenario)
    assert s.summary["time_offset"]["offset_s"] == pytest.approx(-0.004, abs=1e-4)


def _model_rate(scenario: object, stamps_ns: np.ndarray, h: float = 3e-5) -> np.ndarray:
    """ω_eb^B (FRD) from the trajectory model by a central difference at ±h (not the scorer's
    step; truncation and rounding ~2e-9 rad/s each here, measured against h = 1e-5 ... 3e-4)."""
    from strapdown_ros.plan import resolve_plan

    traj = resolve_plan(scenario, topics=False).trajectory
    t = (stamps_ns - scenario.start_time_ns) * 1e-9
    out = []
    for dt in (-h, h):
        lt = traj.local_truth(np.clip(t + dt, 0, traj.duration))
        out.append(dcm_ned_to_ecef(lt.lat, lt.lon) @ lt.c_b_n)
    from strapdown_ros.core.rotations import rotvec_from_dcm

    span = np.clip(t + h, 0, traj.duration) - np.clip(t - h, 0, traj.duration)
    return rotvec_from_dcm(np.swapaxes(out[0], -1, -2) @ out[1]) / span[:, None]


@pytest.mark.slow
def test_an_estimate_in_another_frame_with_its_lever_arm_scores_the_same(case) -> None:
    """The navigator's solution moved to an antenna (lever arm, mounting) and expressed in
    ``map``: declared with --lever-arm/--mounting-rph or through the estimate bag's
    /tf_static, it scores like the original (1e-9 m, 1e-8 m/s, 1e-12 rad)."""
    root, scenario = case
    b = read_bag(root / "bag", ["/navigator/odom", "/tf_static"])
    st = odometry_state(b["/navigator/odom"])
    c_p_b = dcm_from_euler(*np.radians(MOUNT_RPH_DEG))
    w = _model_rate(scenario, st.stamps_ns)
    r_p = st.r_e + np.einsum("nij,j->ni", st.c_b_e, LEVER)
    v_p = st.v_e + np.einsum("nij,nj->ni", st.c_b_e, np.cross(w, LEVER))
    c_pe = st.c_b_e @ c_p_b
    odom_e = odometry_fields_from_ecef(st.stamps_ns, r_p, v_p, c_pe, w @ c_p_b, "antenna")
    # into map: p = C_E^map (r - r0), C_FLU^map = C_E^map C_FLU^E (the earth -> map static TF)
    tf = b["/tf_static"]
    i = tf.child_frame_ids.index("map")
    r0, c_map_e = tf.translation[0, i], dcm_from_quat_ros(tf.rotation[0, i])
    pos = (r_p - r0) @ c_map_e
    q = quat_ros_from_dcm(c_map_e.T @ dcm_from_quat_ros(odom_e.orientation))
    odom_map = type(odom_e)(**{**odom_e.__dict__, "frame_id": "map", "position": pos,
                               "orientation": q})  # fmt: skip
    base = score_bag(root / "bag", "/navigator/odom", scenario=scenario)
    d = np.diag([1.0, -1.0, -1.0])
    tf_ant = tf_message_fields(st.stamps_ns[:1], ["base_link"], ["antenna"],
                               (d @ LEVER)[None, None], (d @ c_p_b @ d)[None, None])  # fmt: skip
    given = _write(root / "antenna_given", "/est", odom_map)
    via_tf = _write(root / "antenna_tf", "/est", odom_map, tf_ant)
    for s in (
        score_bag(root / "bag", "/est", estimate_bag=given, scenario=scenario,
                  lever_arm=LEVER, mounting_rph_deg=MOUNT_RPH_DEG),
        score_bag(root / "bag", "/est", estimate_bag=via_tf, scenario=scenario),
    ):  # fmt: skip
        assert np.abs(s.position_ned - base.position_ned).max() <= 1e-9
        assert np.abs(s.velocity_ned - base.velocity_ned).max() <= 1e-8
        assert np.abs(s.attitude_young - base.attitude_young).max() <= 1e-12
    assert s.summary["point"]["from"] == "/tf_static"
    # undeclared, the antenna is scored as if it were the IMU: the lever arm shows
    wrong = score_bag(root / "bag", "/est", estimate_bag=given, scenario=scenario)
    assert np.abs(wrong.position_ned - base.position_ned).max() > 1.0


def _write_pose_cov(path: Path, stamps: np.ndarray, payloads: list) -> Path:
    """A bag of PoseWithCovarianceStamped payloads on /est, one per stamp."""
    with BagWriter(path) as w:
        w.add_topic("/est", "geometry_msgs/msg/PoseWithCovarianceStamped")
        for t, p in zip(stamps, payloads, strict=True):
            w.write("/est", int(t), p)
    return path


def _pose_cov_messages(stamps, pos, quat, cov, frame):  # PoseWithCovarianceStamped payloads
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    t = ts.types
    out = []
    for k in range(len(stamps)):
        sec, ns = divmod(int(stamps[k]), 1_000_000_000)
        msg = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec,
                                            nanosec=ns), frame_id=frame),  # fmt: skip
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=pos[k, 0], y=pos[k, 1], z=pos[k, 2]),
                    orientation=t["geometry_msgs/msg/Quaternion"](
                        x=quat[k, 0], y=quat[k, 1], z=quat[k, 2], w=quat[k, 3])),
                covariance=cov.reshape(36).astype(np.float64)))
        out.append(ts.serialize_cdr(msg, "geometry_msgs/msg/PoseWithCovarianceStamped"))
    return out


@pytest.mark.slow
def test_nees_of_draws_from_the_declared_covariance(case) -> None:
    """Truth plus errors drawn from an anisotropic ENU covariance (position σ = 1, 0.1, 0.3 m
    east, north, up; rotations about the map axes σ = 1, 2, 5 mrad), published as
    PoseWithCovarianceStamped in ``map``: NEES means 3, 3, 6 within 4 σ of their sampling
    spread (1001 draws: ±0.31, ±0.31, ±0.44); with east and north swapped (a wrong ENU/NED
    conversion) the position NEES is ~35."""
    root, scenario = case
    b = read_bag(root / "bag", ["/reference/odom", "/tf_static"])
    st = odometry_state(b["/reference/odom"])
    keep = slice(0, None, 1)
    stamps, r_e, c_b_e = st.stamps_ns[keep], st.r_e[keep], st.c_b_e[keep]
    tf = b["/tf_static"]
    i = tf.child_frame_ids.index("map")
    r0, c_map_e = tf.translation[0, i], dcm_from_quat_ros(tf.rotation[0, i])
    rng = np.random.default_rng(5)
    sig_p, sig_a = np.array([1.0, 0.1, 0.3]), np.array([1e-3, 2e-3, 5e-3])
    n = len(stamps)
    dp, da = rng.standard_normal((n, 3)) * sig_p, rng.standard_normal((n, 3)) * sig_a
    pos = (r_e - r0) @ c_map_e + dp
    d = np.diag([1.0, -1.0, -1.0])
    c_flu_map = dcm_from_rotvec(da) @ (c_map_e.T @ c_b_e @ d)
    cov = np.zeros((6, 6))
    cov[np.arange(3), np.arange(3)] = sig_p**2
    cov[np.arange(3, 6), np.arange(3, 6)] = sig_a**2
    payloads = _pose_cov_messages(stamps, pos, quat_ros_from_dcm(c_flu_map), cov, "map")
    path = _write_pose_cov(root / "pose_cov", stamps, payloads)
    s = score_bag(root / "bag", "/est", estimate_bag=path, scenario=scenario)
    nees = s.summary["nees"]
    assert nees["position"]["samples"] == n
    assert nees["position"]["mean"] == pytest.approx(3.0, abs=0.31)
    assert nees["attitude"]["mean"] == pytest.approx(3.0, abs=0.31)
    assert nees["pose"]["mean"] == pytest.approx(6.0, abs=0.44)
    # the position errors themselves: the draws, from map (ENU at the datum) to the NED of the
    # true position (measured 1e-10 m: rounding of the ECEF round trip)
    lat, lon, _ = ecef_to_geodetic(r_e)
    want = np.einsum("nij,nj->ni", dcm_ecef_to_ned(lat, lon), dp @ c_map_e.T)
    assert np.abs(s.position_ned - want).max() < 1e-9
    swapped = cov.copy()
    swapped[0, 0], swapped[1, 1] = cov[1, 1], cov[0, 0]
    wrong = _pose_cov_messages(stamps, pos, quat_ros_from_dcm(c_flu_map), swapped, "map")
    path = _write_pose_cov(root / "pose_cov_swapped", stamps, wrong)
    s = score_bag(root / "bag", "/est", estimate_bag=path, scenario=scenario)
    assert s.summary["nees"]["position"]["mean"] > 20


@pytest.mark.slow
def test_pyins_integrator_output_scored_from_the_command_line(case, capsys) -> None:
    """pyins' strapdown integrator (another tool) on the bag's /reference/imu increments,
    written as Odometry: ``strapdown-sim score`` gives the errors computed here directly from
    pyins' output and the published truth (1e-9 m at the truth stamps)."""
    pd = pytest.importorskip("pandas")
    strapdown = pytest.importorskip("pyins.strapdown")
    from strapdown_ros.cli import main
    from strapdown_ros.core.rotations import euler_from_dcm
    from strapdown_ros.messages import imu_increments

    root, scenario = case
    b = read_bag(root / "bag", ["/reference/imu", "/reference/odom"])
    inc = imu_increments(b["/reference/imu"])
    st = odometry_state(b["/reference/odom"])
    lat, lon, alt = ecef_to_geodetic(st.r_e)
    c_e_n = dcm_ecef_to_ned(lat, lon)
    v_ned = np.einsum("nij,nj->ni", c_e_n, st.v_e)
    c_b_n = c_e_n @ st.c_b_e
    r2d = 180 / np.pi
    pva = pd.Series(np.concatenate([[lat[0] * r2d, lon[0] * r2d, alt[0]], v_ned[0],
                                    np.array(euler_from_dcm(c_b_n[0])) * r2d]),
                    index=["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch", "heading"])
    period = inc.period_ns * 1e-9
    m = len(inc.stamps_ns)
    data = np.hstack([inc.dalpha, inc.dv])
    imu = pd.DataFrame(np.vstack([data[:1], data]), index=pd.Index(np.arange(m + 1) * period,
                       name="time"), columns=["gyro_x", "gyro_y", "gyro_z", "accel_x",
                                              "accel_y", "accel_z"])  # fmt: skip
    res = strapdown.Integrator(pva).integrate(strapdown.compute_increments_from_imu(imu,
                                                                                    "increment"))
    t_rel = np.asarray(res.index, dtype=np.float64)
    k = np.rint(t_rel / period).astype(np.int64)
    stamps = st.stamps_ns[0] + k * inc.period_ns
    lat_p, lon_p = np.radians(res.lat.to_numpy()), np.radians(res.lon.to_numpy())
    r_p = geodetic_to_ecef(lat_p, lon_p, res.alt.to_numpy())
    c_n_e = dcm_ned_to_ecef(lat_p, lon_p)
    v_p = np.einsum("nij,nj->ni", c_n_e, res[["VN", "VE", "VD"]].to_numpy())
    c_p = c_n_e @ dcm_from_euler(*np.radians(res[["roll", "pitch", "heading"]].to_numpy().T))
    odom = odometry_fields_from_ecef(stamps, r_p, v_p, c_p, np.zeros((len(k), 3)), "pyins")
    est = _write(root / "pyins", "/pyins/odom", odom)
    out = root / "pyins_score"
    rc = main(["score", str(root / "bag"), "--topic", "/pyins/odom", "--estimate-bag", str(est),
               "--scenario", str(root / "score_car.yaml"), "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    summary = json.loads((out / "score.json").read_text())
    assert (out / "score.md").is_file() and (out / "errors.png").is_file()
    want = np.einsum("nij,nj->ni", c_e_n[k], r_p - st.r_e[k])
    got = summary["position_error_m"]
    assert got["north"]["final"] == pytest.approx(want[-1, 0], abs=1e-9)
    assert got["east"]["final"] == pytest.approx(want[-1, 1], abs=1e-9)
    assert got["down"]["max_abs"] == pytest.approx(np.abs(want[:, 2]).max(), abs=1e-9)
    assert summary["samples"] == len(k)
    assert 1e-6 < got["horizontal"]["max_abs"] < 10.0  # pyins' own integration error


def test_along_and_cross_track_signs() -> None:
    """Travelling east, an error to the south is to the right of the track; north, east is."""
    dr = np.array([[-1.0, 2.0, 0.0], [3.0, 4.0, 0.0]])
    v = np.array([[0.0, 5.0, 0.0], [7.0, 0.0, 0.0]])
    along, cross = along_cross_track(dr, v)
    assert along.tolist() == [2.0, 3.0] and cross.tolist() == [1.0, 4.0]
    along, cross = along_cross_track(dr[:1], np.zeros((1, 3)))
    assert np.isnan(along[0]) and np.isnan(cross[0])


def test_time_offset_step_of_a_pure_delay() -> None:
    """An estimate late by δt has dr = r(t − δt) − r(t) = −v δt exactly on a straight line."""
    v = np.tile([[3.0, -4.0, 0.5]], (50, 1)) * np.linspace(0.5, 2, 50)[:, None]
    d, sigma = time_offset_step(-v * 0.02, v)
    assert d == pytest.approx(0.02, rel=1e-12) and sigma < 1e-15


def test_outage_drift_window() -> None:
    """The drift is taken between the last estimates at/before the start and before the end."""
    t = np.arange(0, 10) * 1_000
    dr = np.zeros((10, 3))
    dr[:, 0] = np.arange(10.0)
    r = np.zeros((10, 3))
    r[:, 1] = np.arange(10) * 2.0
    (o,) = outage_drift(t, dr, r, [(2_500, 6_000)])
    assert (o.first_stamp_ns, o.last_stamp_ns) == (2_000, 5_000)
    assert o.drift_m == 3.0 and o.distance_m == 6.0 and o.drift_percent == 50.0
    (none,) = outage_drift(t, dr, r, [(-5, 0)])
    assert none.drift_m is None
