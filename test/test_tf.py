"""TF and map-frame odometry of a generated bag (docs/interface.md, "Frames and TF").

The default scenario is generated once per length: its first 30 s (straight, pitch-up, the
start of the climb, the variation IMU bending and scanning) in the fast tier, the whole 10 min
flight (every maneuver) as a ``slow`` test; the bag is read back (TF with rosbags' own
deserializer, independent of our codec) and:

* ``earth → map → base_link → reference_imu`` composed from ``/tf_static`` and ``/tf`` equals
  the ECEF reference truth (``/reference/odom``) at every truth sample, to 1e-6 m and 1e-9 rad;
* ``earth → map → base_link → variation_imu`` equals the variation truth (``/variation/odom``);
* ``map → navigator`` composed with ``earth → map`` equals ``/navigator/odom``;
* ``/reference/odom_map`` equals the ECEF truth converted with the datum (independent ENU
  formulas), the datum being the scenario's initial position;
* ``/tf_static`` is offered transient local (latched), ``/navigator/fix`` claims no GNSS fix.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag import cdr
from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset

REPO = Path(__file__).resolve().parent.parent
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"
TS = get_typestore(Stores.ROS2_JAZZY)
POS_TOL, ANG_TOL = 1e-6, 1e-9

WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    e2 = WGS84_F * (2 - WGS84_F)
    n = WGS84_A / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    return np.array(
        [
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1 - e2) + h) * np.sin(lat),
        ]
    )


def _enu_axes(lat: float, lon: float) -> np.ndarray:
    """Rows: east, north, up in ECEF (C_E^ENU)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def _dcm(q: np.ndarray) -> np.ndarray:
    """DCM of ROS quaternions (..., 4) x, y, z, w (rotates child components into the parent)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle of aᵀ b (rad), robust at small angles."""
    d = np.swapaxes(a, -1, -2) @ b
    skew = 0.5 * np.stack([d[..., 2, 1] - d[..., 1, 2], d[..., 0, 2] - d[..., 2, 0],
                           d[..., 1, 0] - d[..., 0, 1]], -1)  # fmt: skip
    return np.arcsin(np.clip(np.linalg.norm(skew, axis=-1), 0, 1))


class Poses:
    """Stamped poses (N,) of one topic or frame pair: stamps, positions (N, 3), DCMs (N, 3, 3)."""

    def __init__(self, stamps: list[int], pos: list, rot: list) -> None:
        order = np.argsort(np.asarray(stamps), kind="stable")
        self.t = np.asarray(stamps, dtype=np.int64)[order]
        self.p = np.asarray(pos, dtype=np.float64).reshape(-1, 3)[order]
        self.c = _dcm(np.asarray(rot, dtype=np.float64).reshape(-1, 4))[order]

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i = np.searchsorted(self.t, t)
        assert np.all(i < self.t.size) and np.array_equal(self.t[i], t), "missing stamps"
        return self.p[i], self.c[i]


@pytest.fixture(
    scope="module",
    params=[pytest.param(30.0, id="30s"), pytest.param(None, id="full", marks=pytest.mark.slow)],
)
def bag(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> dict:
    out = tmp_path_factory.mktemp("tf") / "default"
    scenario = load_scenario(DEFAULT, duration_s=request.param)
    generate_dataset(scenario, out)
    tf: dict[tuple[str, str], list] = defaultdict(lambda: [[], [], []])
    static: dict[tuple[str, str], tuple] = {}
    payloads: dict[str, list[bytes]] = defaultdict(list)
    with Reader(out) as reader:
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
        types = {c.topic: c.msgtype for c in reader.connections}
        for conn, _, raw in reader.messages():
            if conn.topic in ("/tf", "/tf_static"):  # rosbags' own decoder
                msg = TS.deserialize_cdr(raw, conn.msgtype)
                for tr in msg.transforms:
                    key = (tr.header.frame_id, tr.child_frame_id)
                    stamp = tr.header.stamp.sec * 10**9 + tr.header.stamp.nanosec
                    v, q = tr.transform.translation, tr.transform.rotation
                    if conn.topic == "/tf_static":
                        static[key] = (stamp, [v.x, v.y, v.z], [q.x, q.y, q.z, q.w])
                    else:
                        tf[key][0].append(stamp)
                        tf[key][1].append([v.x, v.y, v.z])
                        tf[key][2].append([q.x, q.y, q.z, q.w])
            elif conn.msgtype == "nav_msgs/msg/Odometry" or conn.topic == "/navigator/fix":
                payloads[conn.topic].append(raw)
    # Odometry in bulk (the codec is byte-identical to rosbags': test_bag_io, test_frames)
    odom = {}
    for topic, raws in payloads.items():
        if types[topic] != "nav_msgs/msg/Odometry":
            continue
        f = cdr.deserialize(cdr.ODOMETRY, raws)
        odom[topic] = (
            Poses(list(f.stamps_ns), f.position, f.orientation),
            {(f.frame_id, f.child_frame_id)},
        )
    fix = cdr.deserialize(cdr.NAVSATFIX, payloads["/navigator/fix"])
    fix_status = list(zip(fix.status.tolist(), fix.service.tolist(), strict=True))
    return {
        "scenario": scenario,
        "tf": {k: Poses(*v) for k, v in tf.items()},
        "static": static,
        "odom": odom,
        "qos": qos,
        "fix_status": fix_status,
    }


def _static(bag: dict, parent: str, child: str) -> tuple[np.ndarray, np.ndarray]:
    _, p, q = bag["static"][(parent, child)]
    return np.asarray(p), _dcm(np.asarray(q))


def test_tf_static_tree_and_datum(bag: dict) -> None:
    sc = bag["scenario"]
    assert {("earth", "map"), ("base_link", "reference_imu")} <= set(bag["static"])
    stamps = {v[0] for v in bag["static"].values()}
    assert stamps == {sc.start_time_ns}
    p, c = _static(bag, "earth", "map")
    lat, lon = np.radians(sc.initial.latitude_deg), np.radians(sc.initial.longitude_deg)
    np.testing.assert_allclose(p, _ecef(lat, lon, sc.initial.altitude_m), rtol=0, atol=1e-6)
    assert _angle(c, _enu_axes(lat, lon).T) < ANG_TOL
    p, c = _static(bag, "base_link", "reference_imu")
    assert not p.any() and _angle(c, np.eye(3)) == 0
    assert "transient_local" in str(bag["qos"]["/tf_static"]).lower()


def test_earth_map_base_link_is_the_reference_truth(bag: dict) -> None:
    truth, frames = bag["odom"]["/reference/odom"]
    assert frames == {("earth", "reference_imu")}
    p_map, c_map = _static(bag, "earth", "map")
    tf = bag["tf"][("map", "base_link")]
    sc = bag["scenario"]
    assert tf.t.size == truth.t.size == round(sc.duration_s * sc.rate_hz) + 1  # every sample
    p_bl, c_bl = tf.at(truth.t)
    p_imu, c_imu = _static(bag, "base_link", "reference_imu")
    pos = p_map + (c_map @ (p_bl + (c_bl @ p_imu))[..., None])[..., 0]
    rot = c_map @ c_bl @ c_imu
    assert np.max(np.abs(pos - truth.p)) < POS_TOL
    assert np.max(_angle(rot, truth.c)) < ANG_TOL


def test_base_link_variation_imu_is_the_variation_truth(bag: dict) -> None:
    truth, frames = bag["odom"]["/variation/odom"]
    assert frames == {("earth", "variation_imu")}
    p_map, c_map = _static(bag, "earth", "map")
    p_bl, c_bl = bag["tf"][("map", "base_link")].at(truth.t)
    if ("base_link", "variation_imu") in bag["static"]:
        p_v, c_v = _static(bag, "base_link", "variation_imu")
        p_v, c_v = np.broadcast_to(p_v, p_bl.shape), np.broadcast_to(c_v, c_bl.shape)
    else:
        tf = bag["tf"][("base_link", "variation_imu")]
        assert tf.t.size == truth.t.size
        p_v, c_v = tf.at(truth.t)
    pos = p_map + (c_map @ (p_bl + (c_bl @ p_v[..., None])[..., 0])[..., None])[..., 0]
    rot = c_map @ c_bl @ c_v
    assert np.max(np.abs(pos - truth.p)) < POS_TOL
    assert np.max(_angle(rot, truth.c)) < ANG_TOL
    # the default flight's variation moves (bending / scan): base_link → variation_imu varies
    assert np.ptp(_angle(c_v, np.broadcast_to(np.eye(3), c_v.shape))) > 1e-3


def test_map_navigator_is_the_navigation_solution(bag: dict) -> None:
    nav, frames = bag["odom"]["/navigator/odom"]
    (child,) = {c for _, c in frames}
    p_map, c_map = _static(bag, "earth", "map")
    tf = bag["tf"][("map", child)]
    assert tf.t.size == nav.t.size
    p, c = tf.at(nav.t)
    pos = p_map + (c_map @ p[..., None])[..., 0]
    assert np.max(np.abs(pos - nav.p)) < POS_TOL
    assert np.max(_angle(c_map @ c, nav.c)) < ANG_TOL


@pytest.mark.parametrize(
    "topic", ["/reference/odom", "/variation/odom", "/variation/reference/odom", "/navigator/odom"]
)
def test_map_odometry_is_the_ecef_odometry_in_map(bag: dict, topic: str) -> None:
    sc = bag["scenario"]
    ecef, frames = bag["odom"][topic]
    local, local_frames = bag["odom"][f"{topic}_map"]
    assert {f for f, _ in local_frames} == {"map"}
    assert {c for _, c in local_frames} == {c for _, c in frames}
    np.testing.assert_array_equal(local.t, ecef.t)
    lat, lon = np.radians(sc.initial.latitude_deg), np.radians(sc.initial.longitude_deg)
    r0, c = _ecef(lat, lon, sc.initial.altitude_m), _enu_axes(lat, lon)
    assert np.max(np.abs(local.p - (ecef.p - r0) @ c.T)) < POS_TOL
    assert np.max(_angle(local.c, c @ ecef.c)) < ANG_TOL


def test_navigator_fix_claims_no_gnss_fix(bag: dict) -> None:
    assert bag["fix_status"]
    assert set(bag["fix_status"]) == {(-1, 0)}  # STATUS_NO_FIX, SERVICE_UNKNOWN


def test_tf_off_and_datum_key(tmp_path: Path) -> None:
    """``tf.enabled: false`` writes neither TF nor map odometry unless asked; ``tf.datum`` moves
    the map origin."""
    doc = yaml.safe_load(DEFAULT.read_text())
    doc["duration_s"] = 2.0
    doc["tf"] = {"enabled": False, "map_odometry": False}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    generate_dataset(load_scenario(path), tmp_path / "off")
    with Reader(tmp_path / "off") as reader:
        topics = {c.topic for c in reader.connections}
    assert not {"/tf", "/tf_static"} & topics and not any(t.endswith("_map") for t in topics)
    doc["tf"] = {"datum": {"latitude_deg": 10.0, "longitude_deg": 20.0, "altitude_m": 5.0}}
    path.write_text(yaml.safe_dump(doc))
    generate_dataset(load_scenario(path), tmp_path / "datum")
    with Reader(tmp_path / "datum") as reader:
        conn = next(c for c in reader.connections if c.topic == "/tf_static")
        raw = next(r for _, _, r in reader.messages(connections=[conn]))
    t = TS.deserialize_cdr(raw, conn.msgtype).transforms[0].transform.translation
    np.testing.assert_allclose(
        [t.x, t.y, t.z], _ecef(np.radians(10.0), np.radians(20.0), 5.0), rtol=0, atol=1e-6
    )


def test_increment_topics_beside_each_imu(tmp_path: Path) -> None:
    """``recording.increments: true``: <imu>_dv / <imu>_dq per Imu message, Δv = a·T and Δq the
    rotation of Δα = ω·T (FLU), same stamps and frame; off by default."""
    doc = yaml.safe_load(DEFAULT.read_text())
    doc["duration_s"] = 1.0
    doc["recording"] = {**doc.get("recording", {}), "increments": True}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    scenario = load_scenario(path)
    generate_dataset(scenario, tmp_path / "inc")
    payloads: dict[str, list[bytes]] = defaultdict(list)
    with Reader(tmp_path / "inc") as reader:
        for conn, _, raw in reader.messages():
            payloads[conn.topic].append(raw)
    period = scenario.period_ns * 1e-9
    for imu_topic in ("/reference/imu", "/variation/imu", "/variation/imu_measured"):
        imu = cdr.deserialize(cdr.IMU, payloads[imu_topic])
        dv = cdr.deserialize(cdr.VECTOR3_STAMPED, payloads[f"{imu_topic}_dv"])
        dq = TS.deserialize_cdr(payloads[f"{imu_topic}_dq"][7], cdr.QUATERNION_STAMPED)
        np.testing.assert_array_equal(dv.stamps_ns, imu.stamps_ns)
        assert dv.frame_id == imu.frame_id == dq.header.frame_id
        np.testing.assert_array_equal(dv.vector, imu.linear_acceleration * period)
        phi = imu.angular_velocity[7] * period
        theta = np.linalg.norm(phi)
        q = [dq.quaternion.x, dq.quaternion.y, dq.quaternion.z, dq.quaternion.w]
        want = [*(np.sin(theta / 2) * phi / theta), np.cos(theta / 2)]
        np.testing.assert_allclose(q, want, rtol=0, atol=1e-16)
    generate_dataset(load_scenario(DEFAULT, duration_s=0.5), tmp_path / "default")
    with Reader(tmp_path / "default") as reader:
        assert not any(c.topic.endswith(("_dv", "_dq")) for c in reader.connections)
