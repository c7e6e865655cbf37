"""Message conventions (FRD/NED/E0 → FLU/ENU/ECEF), checked against hand-built expectations."""

import numpy as np
import pytest

from strapdown_ros import messages as msg
from strapdown_ros.core.earth import (
    OMEGA_IE,
    dcm_ned_to_ecef,
    ecef_state_to_e0,
    geodetic_to_ecef,
)
from strapdown_ros.core.rotations import dcm_from_euler, dcm_from_rotvec, quat_from_dcm
from strapdown_ros.core.stream import Stream

T_NS = 10_000_000  # 100 Hz
T0_NS = 1_700_000_000_123_456_789
LAT, LON, ALT = np.radians(45.0), np.radians(7.0), 100.0


def earth_stream(c_b_n, v_ned=(0.0, 0.0, 0.0), cycles=5, dalpha=None, dv=None):
    """A stream whose truth is a body with constant NED attitude/velocity at a fixed point
    (the position does not move: only the conventions matter here)."""
    n = cycles + 1
    t = np.arange(n) * T_NS * 1e-9
    c_n_e = dcm_ned_to_ecef(LAT, LON)
    r_e = np.tile(geodetic_to_ecef(LAT, LON, ALT), (n, 1))
    v_e = np.tile(c_n_e @ np.asarray(v_ned), (n, 1))
    c_b_e = np.tile(c_n_e @ c_b_n, (n, 1, 1))
    r0, v0, c0 = ecef_state_to_e0(t, r_e, v_e, c_b_e)
    if dalpha is None:  # at rest relative to the Earth: Δα = C_E^B ω_ie T
        dalpha = np.tile((c_n_e @ c_b_n).T @ [0.0, 0.0, OMEGA_IE] * T_NS * 1e-9, (cycles, 1))
    if dv is None:
        dv = np.zeros((cycles, 3))
    return Stream(T0_NS, T_NS, np.asarray(dalpha, float), np.asarray(dv, float), c0, v0, r0)


def flu_to_ecef_by_hand(lat, lon):
    """Columns: FLU axes of a level, north-facing body in ECEF (x north, y west, z up)."""
    sp, cp, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    north = [-sp * cl, -sp * sl, cp]
    west = [sl, -cl, 0.0]
    up = [cp * cl, cp * sl, sp]
    return np.column_stack([north, west, up])


def test_body_at_rest_level_north():
    s = earth_stream(np.eye(3), dv=np.tile([0.0, 0.0, -9.8 * T_NS * 1e-9], (5, 1)))
    odom = msg.odometry_fields(s)
    assert len(odom) == 6 and odom.frame_id == "earth" and odom.child_frame_id == "reference_imu"
    np.testing.assert_array_equal(odom.stamps_ns, T0_NS + np.arange(6) * T_NS)
    np.testing.assert_allclose(odom.twist_linear, 0.0, atol=1e-9)
    np.testing.assert_allclose(odom.twist_angular, 0.0, atol=1e-18)
    np.testing.assert_allclose(
        odom.position, np.tile(geodetic_to_ecef(LAT, LON, ALT), (6, 1)), rtol=0, atol=1e-8
    )
    c = msg.dcm_from_quat_ros(odom.orientation)
    np.testing.assert_allclose(c, np.tile(flu_to_ecef_by_hand(LAT, LON), (6, 1, 1)), atol=1e-15)
    assert np.all(odom.orientation[:, 3] >= 0)  # canonical sign, scalar last

    imu = msg.imu_fields(s)
    assert len(imu) == 5 and imu.frame_id == "reference_imu"
    np.testing.assert_array_equal(imu.stamps_ns, T0_NS + np.arange(1, 6) * T_NS)
    # Level and facing north: FLU relative to ENU is a yaw of +90° about ENU z.
    h = np.sqrt(0.5)
    np.testing.assert_allclose(imu.orientation, np.tile([0.0, 0.0, h, h], (5, 1)), atol=1e-15)
    # Earth rate seen by the body: north (FLU x) ω cos φ, up (FLU z) ω sin φ.
    w = OMEGA_IE * np.array([np.cos(LAT), 0.0, np.sin(LAT)])
    np.testing.assert_allclose(imu.angular_velocity, np.tile(w, (5, 1)), rtol=1e-15, atol=1e-20)
    # Specific force of -9.8 m/s² along FRD z (down) is +9.8 along FLU z (up).
    np.testing.assert_allclose(imu.linear_acceleration, np.tile([0, 0, 9.8], (5, 1)), rtol=1e-15)
    for cov in (
        imu.orientation_covariance,
        imu.angular_velocity_covariance,
        imu.linear_acceleration_covariance,
    ):
        assert cov.shape == (5, 9) and not np.any(cov)
    assert not np.any(odom.pose_covariance) and odom.pose_covariance.shape == (6, 36)

    fix = msg.navsatfix_fields(s)
    np.testing.assert_allclose(fix.latitude, 45.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fix.longitude, 7.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fix.altitude, 100.0, rtol=0, atol=1e-8)
    assert np.all(fix.status == msg.STATUS_FIX) and np.all(fix.service == msg.SERVICE_GPS)
    assert np.all(fix.position_covariance_type == msg.COVARIANCE_TYPE_UNKNOWN)
    assert not np.any(fix.position_covariance)


def test_yaw_right_is_negative_flu_z_rate():
    """+1 rad/s about FRD z (yaw right) is -1 rad/s about FLU z."""
    T = T_NS * 1e-9
    s = earth_stream(np.eye(3), dalpha=np.tile([0.0, 0.0, T], (5, 1)))
    imu = msg.imu_fields(s)
    np.testing.assert_allclose(imu.angular_velocity, np.tile([0.0, 0.0, -1.0], (5, 1)), rtol=1e-15)


def test_heading_and_velocity_in_body_axes():
    # Heading 90° (east), pitch 10° up, moving east at 10 m/s and up at 1 m/s.
    c_b_n = dcm_from_euler(0.0, np.radians(10.0), np.radians(90.0))
    v_ned = np.array([0.0, 10.0, -1.0])
    s = earth_stream(c_b_n, v_ned=v_ned)
    odom = msg.odometry_fields(s)
    v_frd = c_b_n.T @ v_ned
    np.testing.assert_allclose(odom.twist_linear, np.tile(v_frd * [1, -1, -1], (6, 1)), atol=1e-9)
    imu = msg.imu_fields(s)
    # ENU orientation: heading east = yaw 0 in ENU; pitch up 10° = rotation -10° about FLU y.
    c = msg.dcm_from_quat_ros(imu.orientation[0])
    e = np.radians(10.0)
    expected = np.array([[np.cos(e), 0, -np.sin(e)], [0, 1, 0], [np.sin(e), 0, np.cos(e)]])
    np.testing.assert_allclose(c, expected, atol=1e-15)


def test_twist_angular_choice():
    """twist.angular(m) = FLU(Δα_m/T − C_E^B ω_ie), m = 0 uses cycle 1."""
    rng = np.random.default_rng(3)
    T = T_NS * 1e-9
    dalpha = rng.normal(scale=1e-3, size=(5, 3))
    c_b_n = dcm_from_rotvec([0.1, -0.2, 0.3])
    s = earth_stream(c_b_n, dalpha=dalpha)
    odom = msg.odometry_fields(s)
    c_b_e = dcm_ned_to_ecef(LAT, LON) @ c_b_n
    w_ie_b = c_b_e.T @ [0.0, 0.0, OMEGA_IE]
    w = np.vstack([dalpha[:1], dalpha]) / T - w_ie_b
    np.testing.assert_allclose(odom.twist_angular, w * [1, -1, -1], rtol=0, atol=1e-15)


def test_round_trips():
    rng = np.random.default_rng(4)
    c_b_n = dcm_from_rotvec([0.5, -1.0, 2.0])
    s = earth_stream(
        c_b_n,
        v_ned=(3.0, -4.0, 0.5),
        dalpha=rng.normal(size=(5, 3)) * 1e-2,
        dv=rng.normal(size=(5, 3)) * 0.1,
    )
    imu, odom, fix = msg.imu_fields(s), msg.odometry_fields(s), msg.navsatfix_fields(s)
    inc = msg.imu_increments(imu)
    assert inc.period_ns == T_NS
    np.testing.assert_array_equal(inc.stamps_ns, s.stamps_ns[1:])
    np.testing.assert_allclose(inc.dalpha, s.dalpha, rtol=2.3e-16, atol=0)
    np.testing.assert_allclose(inc.dv, s.dv, rtol=2.3e-16, atol=0)
    back = msg.stream_from_messages(imu, odom)
    assert back.t0_ns == s.t0_ns and back.period_ns == s.period_ns
    np.testing.assert_allclose(back.r_e0, s.r_e0, rtol=0, atol=2e-9)
    np.testing.assert_allclose(back.v_e0, s.v_e0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.c_b_e0, s.c_b_e0, rtol=0, atol=1e-15)
    st = msg.odometry_state(odom)
    np.testing.assert_allclose(st.omega_eb_b * [1, -1, -1], odom.twist_angular, rtol=0, atol=0)
    t, lat, lon, alt = msg.navsatfix_geodetic(fix)
    np.testing.assert_allclose([lat[0], lon[0], alt[0]], [LAT, LON, ALT], rtol=1e-15, atol=1e-8)
    with pytest.raises(ValueError, match="Imu stamps"):
        msg.stream_from_messages(imu, msg.odometry_fields(earth_stream(c_b_n, cycles=4)))


def test_covariance_specs():
    s = earth_stream(np.eye(3))
    imu = msg.imu_fields(
        s,
        "imu_measured",
        orientation=False,
        angular_velocity_covariance=np.diag([1e-6, 2e-6, 3e-6]),
        linear_acceleration_covariance=msg.COVARIANCE_NOT_PROVIDED,
    )
    assert imu.frame_id == "imu_measured"
    np.testing.assert_array_equal(imu.orientation, np.tile([0, 0, 0, 1.0], (5, 1)))
    np.testing.assert_array_equal(imu.orientation_covariance[:, 0], -1.0)
    assert not np.any(imu.orientation_covariance[:, 1:])
    np.testing.assert_array_equal(
        imu.angular_velocity_covariance[:, [0, 4, 8]], np.tile([1e-6, 2e-6, 3e-6], (5, 1))
    )
    np.testing.assert_array_equal(imu.linear_acceleration_covariance[:, 0], -1.0)
    odom = msg.odometry_fields(s, pose_covariance=np.eye(6), twist_covariance=np.ones((6, 36)))
    assert odom.pose_covariance[0, 7] == 1.0 and odom.twist_covariance.shape == (6, 36)
    fix = msg.navsatfix_fields(s, position_covariance=np.eye(3))
    assert np.all(fix.position_covariance_type == msg.COVARIANCE_TYPE_KNOWN)
    with pytest.raises(ValueError, match="pose_covariance"):
        msg.odometry_fields(s, pose_covariance=np.eye(3))
    with pytest.raises(ValueError, match="unknown covariance spec"):
        msg.imu_fields(s, orientation_covariance="bogus")


def test_stamps_to_sec_nanosec():
    sec, nsec = msg.stamps_to_sec_nanosec(np.array([-1, 0, 1_999_999_999, -1_000_000_001]))
    np.testing.assert_array_equal(sec, [-1, 0, 1, -2])
    np.testing.assert_array_equal(nsec, [999_999_999, 0, 999_999_999, 999_999_999])
    assert sec.dtype == np.int32 and nsec.dtype == np.uint32
    with pytest.raises(ValueError, match="int32"):
        msg.stamps_to_sec_nanosec(np.array([2**31 * 1_000_000_000]))


def _special_dcms():
    """Signed permutations (exact zeros), 180° rotations, -0.0 entries and random DCMs."""
    from itertools import permutations, product

    mats = []
    for perm in permutations(range(3)):
        for sign in product([1.0, -1.0], repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = sign
            if np.linalg.det(m) > 0:
                mats.append(m)
    mats = np.array(mats)
    rng = np.random.default_rng(7)
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return np.concatenate(
        [mats, np.where(mats == 0, -0.0, mats), dcm_from_rotvec(axes * np.pi)]
        + [dcm_from_rotvec(rng.normal(size=(200, 3)))]
    )


def test_quat_ros_from_dcm_is_quat_from_dcm_bit_for_bit():
    c = _special_dcms()
    for cc in (c, c[5], c[::3], c.reshape(-1, 2, 3, 3)[:, 1]):
        q = quat_from_dcm(cc)
        want = np.concatenate([q[..., 1:], q[..., :1]], axis=-1)
        got = msg.quat_ros_from_dcm(cc)
        assert got.shape == want.shape and got.tobytes() == want.tobytes()
    with pytest.raises(ValueError):
        msg.quat_ros_from_dcm(np.eye(4))


def test_stream_fields_equal_separate_calls():
    rng = np.random.default_rng(3)
    m = 40
    c = dcm_from_rotvec(rng.normal(size=(m + 1, 3)))
    r = np.array([4.2e6, 0.9e6, 4.7e6]) + rng.normal(size=(m + 1, 3)) * 1e3
    s = Stream(T0_NS, T_NS, rng.normal(size=(m, 3)), rng.normal(size=(m, 3)), c, r * 1e-4, r)
    f = msg.stream_fields(s, "body", "earth")
    assert f.odometry.equals(msg.odometry_fields(s, "body", "earth"))
    assert f.navsatfix.equals(msg.navsatfix_fields(s, "body"))
    assert f.imu.equals(msg.imu_fields(s, "body"))
    kw = {"orientation": False, "angular_velocity_covariance": np.eye(3)}
    g = msg.stream_fields(s, odometry=False, navsatfix=False, imu_kwargs=kw)
    assert g.odometry is None and g.navsatfix is None
    assert g.imu.equals(msg.imu_fields(s, **kw))
