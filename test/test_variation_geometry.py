"""The variation's geometry from the bag alone, against Savage 2020 eqs. (5)-(7) written out
independently: ``R_var = R_ref + C_Bref^E l^Bref + C_Bvar^E s^Bvar`` and
``C_Bvar^E = C_Bref^E C_Bvar^Bref`` with ``C_Bvar^Bref = C_mount C_scan``.

The bag is written by ``generate`` and read with rosbags (not the package's decoder); the
quaternions are turned into matrices by scipy; the lever arm, displacement and mounting are the
scenario's numbers. The scan's angle history (a ±30° sweep about z, smoothed) is not known to
the test: the variation's attitude relative to the reference, with the mounting removed, must
be a rotation about the scan axis only. Bending is off here (the lever arm is constant).
"""

from __future__ import annotations

import numpy as np
import pytest
from rosbags_read import generate_edited, messages_by_stamp
from scipy.spatial.transform import Rotation

LEVER_ARM = np.array([-6.0, 1.5, -0.3])  # m, Bref FRD
DISPLACEMENT = np.array([0.2, -0.1, 0.15])  # m, Bvar FRD
MOUNTING_RPH = np.array([10.0, -20.0, 150.0])  # deg
PERIOD_NS = 5_000_000  # 200 Hz
FLU = np.diag([1.0, -1.0, -1.0])  # FRD <-> FLU body axes


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    def fixed_offsets(doc):
        doc["variation"]["lever_arm_m"] = LEVER_ARM.tolist()
        doc["variation"]["displacement_m"] = DISPLACEMENT.tolist()
        doc["variation"]["mounting_rph_deg"] = MOUNTING_RPH.tolist()
        del doc["variation"]["bending"]
        for key in ("navigator", "imu_errors", "aiding", "aided"):
            doc.pop(key, None)
        doc["duration_s"] = 8.0

    return generate_edited(tmp_path_factory.mktemp("geometry"), "default", fixed_offsets)


def _odometry(bag, topic):
    msgs = messages_by_stamp(bag, topic)
    stamps = np.array(sorted(msgs))
    pos = np.array([[msgs[t].pose.pose.position.x, msgs[t].pose.pose.position.y,
                     msgs[t].pose.pose.position.z] for t in stamps])  # fmt: skip
    q = [msgs[t].pose.pose.orientation for t in stamps]
    rot = Rotation.from_quat([[o.x, o.y, o.z, o.w] for o in q])
    # C_B^E of the FRD body: the message's FLU body orientation in the Earth frame, times FLU
    return stamps, pos, rot.as_matrix() @ FLU


def test_position_offset_is_lever_arm_plus_displacement(bag):
    """Savage eqs. (6)-(7): the lever arm in the reference's axes, the displacement in the
    variation's. Method 2 meets position at the even cycles only (the odd-cycle state is the
    pair system's, docs/variation.md): those are compared. Measured: 2.2e-9 m at most (ECEF
    coordinates of 6.4e6 m: a few ulps); the limit is 10 times that."""
    t_ref, r_ref, c_ref = _odometry(bag, "/reference/odom")
    t_var, r_var, c_var = _odometry(bag, "/variation/odom")
    common, i, j = np.intersect1d(t_ref, t_var, return_indices=True)
    even = (common - t_ref[0]) // PERIOD_NS % 2 == 0
    i, j = i[even], j[even]
    assert i.size > 700
    expected = np.einsum("nij,j->ni", c_ref[i], LEVER_ARM) + np.einsum(
        "nij,j->ni", c_var[j], DISPLACEMENT
    )
    err = np.abs(r_var[j] - r_ref[i] - expected).max()
    assert err < 2.2e-8, err
    # the two terms matter: each alone misses by metres
    assert np.abs(r_var[j] - r_ref[i] - np.einsum("nij,j->ni", c_var[j], LEVER_ARM)).max() > 1.0


def test_attitude_offset_is_mounting_times_scan_about_its_axis(bag):
    """Savage eq. (5): ``C_Bvar^Bref = C_mount C_scan``; with the mounting removed, what is
    left is a rotation about the scan axis (z) of at most the sweep's ±30°."""
    t_ref, _, c_ref = _odometry(bag, "/reference/odom")
    t_var, _, c_var = _odometry(bag, "/variation/odom")
    common, i, j = np.intersect1d(t_ref, t_var, return_indices=True)
    offset = np.einsum("nji,njk->nik", c_ref[i], c_var[j])  # C_Bvar^Bref
    # roll, pitch, yaw of the scenario: C = Rz(yaw) Ry(pitch) Rx(roll), body to reference
    mount = Rotation.from_euler("ZYX", MOUNTING_RPH[::-1], degrees=True).as_matrix()
    scan = Rotation.from_matrix(mount.T @ offset).as_rotvec()
    assert np.abs(scan[:, :2]).max() < 1e-12, np.abs(scan[:, :2]).max()
    assert np.degrees(np.abs(scan[:, 2]).max()) <= 30.0 + 1e-9
    assert np.degrees(np.ptp(scan[:, 2])) > 20.0  # the scan did move


def _twist(bag, topic):
    """Stamps, ECEF velocity relative to the Earth (m/s) and ω_eb in body FRD (rad/s) of an
    Odometry topic: ``twist.linear = C_E^FLU v^E``, ``twist.angular = FLU(ω_eb^B)``."""
    msgs = messages_by_stamp(bag, topic)
    stamps = np.array(sorted(msgs))
    tw = [msgs[t].twist.twist for t in stamps]
    q = [msgs[t].pose.pose.orientation for t in stamps]
    c_flu_e = Rotation.from_quat([[o.x, o.y, o.z, o.w] for o in q]).as_matrix()
    v_flu = np.array([[w.linear.x, w.linear.y, w.linear.z] for w in tw])
    w_frd = np.array([[w.angular.x, w.angular.y, w.angular.z] for w in tw]) @ FLU
    return stamps, np.einsum("nij,nj->ni", c_flu_e, v_flu), w_frd, c_flu_e @ FLU


def test_velocity_offset_is_the_rate_of_the_position_offset(bag):
    """Savage eq. (10): the variation's velocity is the reference's plus the rate of the offset
    ``s = C_Bref^E l + C_Bvar^E d``, here (rigid: bending off) ``C_Bref^E (ω_ref × l) +
    C_Bvar^E (ω_var × d)`` with each body's rate relative to the Earth from its own Odometry.
    Even cycles, as the positions. eq. (10) is a central difference over 2T; a published rate is
    the mean of the cycle ending at its stamp, so the rate at a stamp is taken as the mean of
    the two cycles around it. Measured: 5.5e-6 m/s at most (at the scan's smoothed reversals),
    median 2e-8 m/s; the limit is 10 times the largest. A wrong eq. (10) (a sign, a factor 2T)
    misses by metres per second."""
    t_ref, v_ref, w_ref, c_ref = _twist(bag, "/reference/odom")
    t_var, v_var, w_var, c_var = _twist(bag, "/variation/odom")
    common, i, j = np.intersect1d(t_ref, t_var, return_indices=True)
    even = (common - t_ref[0]) // PERIOD_NS % 2 == 0
    i, j = i[even][1:-1], j[even][1:-1]  # the first sample: eq. (10) one-sided there
    assert i.size > 700
    # the rate at the stamp: the mean of the two cycles' mean rates around it (O(T²))
    wr, wv = 0.5 * (w_ref[i] + w_ref[i + 1]), 0.5 * (w_var[j] + w_var[j + 1])
    expected = np.einsum("nij,nj->ni", c_ref[i], np.cross(wr, LEVER_ARM)) + np.einsum(
        "nij,nj->ni", c_var[j], np.cross(wv, DISPLACEMENT)
    )
    err = np.abs(v_var[j] - v_ref[i] - expected).max()
    assert err < 5.5e-5, err
    assert np.abs(expected).max() > 0.05  # the offset does move
