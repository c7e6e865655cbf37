"""core/aiding/gnss.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: the WGS-84 geodetic-to-ECEF closed form and the NED/ENU unit vectors written
out here, and the receiver's normals drawn by hand from the documented stream
(docs/aiding.md: ``SeedSequence(seed, spawn_key=(1,))``, 6 normals at construction, then 12 per
epoch: position white, position GM, velocity white, velocity GM).
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aiding.gnss import GnssErrorModel, GnssErrors, gnss_measurement

A = 6378137.0  # WGS-84 semi-major axis, m
E2 = 6.69437999014e-3  # WGS-84 first eccentricity squared


def _ecef(lat: float, lon: float, alt: float) -> np.ndarray:
    rn = A / math.sqrt(1.0 - E2 * math.sin(lat) ** 2)
    return np.array([
        (rn + alt) * math.cos(lat) * math.cos(lon),
        (rn + alt) * math.cos(lat) * math.sin(lon),
        (rn * (1.0 - E2) + alt) * math.sin(lat),
    ])  # fmt: skip


def _ned_axes(lat: float, lon: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sp, cp, sl, cl = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    north = np.array([-sp * cl, -sp * sl, cp])
    east = np.array([-sl, cl, 0.0])
    return north, east, -np.array([cp * cl, cp * sl, sp])


LAT, LON, ALT = 0.81, -2.3, 412.0


def _fix(dr: np.ndarray, dv: np.ndarray, v: np.ndarray):
    return gnss_measurement(_ecef(LAT, LON, ALT)[None], v[None], dr[None], dv[None])


def test_fix_with_a_position_error_is_the_antenna_moved_along_ned():
    """``r̃ = r_a + C_N^E δr``: the fix's geodetic position maps back to the moved point."""
    north, east, down = _ned_axes(LAT, LON)
    for dr in ([3.0, -4.0, 2.5], [1.0, 1.0, 1.0]):  # all ones: the "any error" test on 1.0
        m = _fix(np.array(dr), np.zeros(3), np.zeros(3))
        moved = _ecef(LAT, LON, ALT) + dr[0] * north + dr[1] * east + dr[2] * down
        back = _ecef(float(m.lat[0]), float(m.lon[0]), float(m.alt[0]))
        np.testing.assert_allclose(back, moved, rtol=0, atol=1e-6)  # 1 µm of 6.4e6 m
    # a pure down error lowers the altitude by its size, latitude and longitude unchanged
    m = _fix(np.array([0.0, 0.0, 7.0]), np.zeros(3), np.zeros(3))
    assert abs(float(m.alt[0]) - (ALT - 7.0)) < 1e-6
    assert abs(float(m.lat[0]) - LAT) < 1e-12 and abs(float(m.lon[0]) - LON) < 1e-12


def test_fix_without_error_is_the_antenna_position():
    m = _fix(np.zeros(3), np.zeros(3), np.zeros(3))
    assert abs(float(m.lat[0]) - LAT) < 1e-12 and abs(float(m.lon[0]) - LON) < 1e-12
    assert abs(float(m.alt[0]) - ALT) < 1e-6


def test_velocity_error_is_added_in_ned_then_reported_in_enu():
    """``ṽ^ENU = ENU(C_E^N v_a + δv^N)`` with the axes at the antenna."""
    north, east, down = _ned_axes(LAT, LON)
    v = np.array([120.0, -35.0, 60.0])
    dv = np.array([0.5, -0.25, 0.125])
    enu = _fix(np.zeros(3), dv, v).v_enu[0]
    expected = [east @ v + dv[1], north @ v + dv[0], -(down @ v) - dv[2]]
    np.testing.assert_allclose(enu, expected, rtol=0, atol=1e-12)


def _stream(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(1,))))
    return rng.standard_normal(6), rng.standard_normal((n, 12))


def test_errors_are_offset_plus_white_plus_gauss_markov_from_the_documented_stream():
    """Each epoch's error from the normals drawn by hand: ``b + σ_w ξ + x_GM``."""
    s_gm_p, tau_p, s_gm_v, tau_v, period = 2.0, 50.0, 0.03, 20.0, 0.5
    e = GnssErrors(
        position_white=np.array([0.3, 0.4, 0.6]),
        position_gm_sigma=np.full(3, s_gm_p),
        position_gm_tau_s=np.full(3, tau_p),
        position_offset=np.array([0.5, -0.25, 1.0]),
        velocity_white=np.array([0.05, 0.06, 0.1]),
        velocity_gm_sigma=np.full(3, s_gm_v),
        velocity_gm_tau_s=np.full(3, tau_v),
        velocity_offset=np.array([0.02, 0.01, -0.03]),
    )
    n = 4
    init, z = _stream(11, n)
    pos, vel = GnssErrorModel(e, period, seed=11).take(n)
    for got, white, offset, s_gm, tau, x0, zw, zg in (
        (pos, e.position_white, e.position_offset, s_gm_p, tau_p, init[0:3], z[:, 0:3], z[:, 3:6]),
        (vel, e.velocity_white, e.velocity_offset, s_gm_v, tau_v, init[3:6], z[:, 6:9], z[:, 9:12]),
    ):  # fmt: skip
        phi = math.exp(-period / tau)
        x = s_gm * x0
        for k in range(n):
            np.testing.assert_allclose(got[k], offset + white * zw[k] + x, rtol=0, atol=1e-12)
            x = phi * x + s_gm * math.sqrt(1.0 - phi**2) * zg[k]


def test_epoch_count_and_skip_of_one_epoch():
    e = GnssErrors(position_white=np.ones(3))
    m = GnssErrorModel(e, 1.0, seed=2)
    assert m.epochs == 0
    m.take(3)
    m.take(4)
    assert m.epochs == 7
    init, z = _stream(2, 9)
    m.skip(1)  # epoch 7 drawn and discarded
    assert m.epochs == 8
    np.testing.assert_array_equal(m.take(1)[0][0], z[8, 0:3])
