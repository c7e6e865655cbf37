"""WGS-84 Earth geometry: geodetic <-> ECEF against mpmath, radii, NED frames, E <-> E0 states.

Error bounds are stated at the float64 floor: near the Earth's surface one ulp of an ECEF
coordinate is 9.3e-10 m, one ulp of a latitude above 1 rad is 1.4e-9 m on the ground and one
ulp of a longitude beyond 2 rad is up to 2.8e-9 m, so "exact" means "correctly rounded"
(≤ 0.5 ulp plus a small slack) where numpy's longdouble is extended precision (x86-64 and
aarch64 Linux) and a few ulp elsewhere.
"""

import mpmath as mp
import numpy as np
import pytest

from strapdown_ros.core import earth

EXTENDED = np.finfo(np.longdouble).eps < 1e-18
ULP_TOL = 0.501 if EXTENDED else 4.0  # float64 outputs, in units of the output's ulp
H_TOL = 1e-10 if EXTENDED else 4e-9  # altitude error vs the exact value, m

MP_DPS = 32


def mp_ellipsoid():
    """WGS-84 a, f, e² as mpmath numbers (call inside ``mp.workdps``)."""
    a = mp.mpf(6378137)
    f = 1 / mp.mpf("298.257223563")
    return a, f, f * (2 - f)


def mp_geodetic_to_ecef(lat, lon, alt):
    """High-precision forward conversion (the defining formulas, evaluated at 32 digits)."""
    with mp.workdps(MP_DPS):
        a, _, e2 = mp_ellipsoid()
        lat, lon, alt = mp.mpf(float(lat)), mp.mpf(float(lon)), mp.mpf(float(alt))
        n = a / mp.sqrt(1 - e2 * mp.sin(lat) ** 2)
        return [
            (n + alt) * mp.cos(lat) * mp.cos(lon),
            (n + alt) * mp.cos(lat) * mp.sin(lon),
            (n * (1 - e2) + alt) * mp.sin(lat),
        ]


def mp_ecef_to_geodetic(x, y, z):
    """High-precision inverse by the classical fixed point tan φ = (z + e² R_E sin φ) / p.

    (A different iteration from the implementation's Bowring + Newton; converges by a factor
    ≈ e² per step, 25 steps give far more than 30 digits.)
    """
    with mp.workdps(MP_DPS):
        a, _, e2 = mp_ellipsoid()
        x, y, z = mp.mpf(float(x)), mp.mpf(float(y)), mp.mpf(float(z))
        p = mp.sqrt(x * x + y * y)
        phi = mp.atan2(z, p * (1 - e2))
        for _ in range(25):
            n = a / mp.sqrt(1 - e2 * mp.sin(phi) ** 2)
            phi = mp.atan2(z + e2 * n * mp.sin(phi), p)
        s = mp.sin(phi)
        h = p * mp.cos(phi) + z * s - a * mp.sqrt(1 - e2 * s * s)
        return phi, mp.atan2(y, x), h


def random_geodetic(n, rng, h_lo=-1e4, h_hi=1e6):
    lat = np.arcsin(rng.uniform(-1.0, 1.0, n))
    lon = rng.uniform(-np.pi, np.pi, n)
    alt = rng.uniform(h_lo, h_hi, n)
    return lat, lon, alt


def edge_geodetic():
    """Poles, equator, date line, prime meridian and the altitude limits, all combinations."""
    lats = [np.pi / 2, -np.pi / 2, 0.0, 1e-300, -1e-12, np.nextafter(np.pi / 2, 0), 0.7, -1.4]
    lons = [0.0, np.pi, -np.pi, np.nextafter(np.pi, 0), np.pi / 2, -2.5, 1e-300]
    alts = [-1e4, 0.0, 1e6]
    g = np.array(np.meshgrid(lats, lons, alts, indexing="ij")).reshape(3, -1)
    return g[0], g[1], g[2]


def samples(n, rng):
    """``n`` random geodetic points followed by all the edge points."""
    rand, edge = random_geodetic(n, rng), edge_geodetic()
    return tuple(np.concatenate([a, b]) for a, b in zip(rand, edge, strict=True))


def ned_error_m(lat1, lon1, alt1, lat0, lon0, alt0):
    """Geodetic differences as north, east, down distances in m (longitude wrapped)."""
    rn, re = earth.radii(lat0)
    dlon = np.angle(np.exp(1j * (lon1 - lon0)))
    return np.stack(
        [(lat1 - lat0) * (rn + alt0), dlon * (re + alt0) * np.cos(lat0), alt0 - alt1], -1
    )


def test_constants():
    assert earth.B_WGS84 == pytest.approx(6356752.314245, abs=1e-6)
    assert earth.E2_WGS84 == pytest.approx(6.69437999014e-3, abs=1e-14)
    assert earth.EP2_WGS84 == pytest.approx(6.73949674228e-3, abs=1e-14)
    np.testing.assert_array_equal(earth.OMEGA_IE_VEC, [0.0, 0.0, 7.292115e-5])
    with pytest.raises(ValueError):
        earth.OMEGA_IE_VEC[2] = 0.0


def test_geodetic_to_ecef_exact_against_mpmath():
    rng = np.random.default_rng(10)
    lat, lon, alt = samples(150, rng)
    r = earth.geodetic_to_ecef(lat, lon, alt)
    ulps = []
    for i in range(len(lat)):
        exact = mp_geodetic_to_ecef(lat[i], lon[i], alt[i])
        ulps.append(
            [
                float(abs(r[i, k] - exact[k])) / np.spacing(max(abs(float(exact[k])), 1e-3))
                for k in range(3)
            ]
        )
    assert np.max(ulps) <= ULP_TOL
    # Independent geometric property: at h = 0 the point lies on the meridian ellipse.
    r0 = earth.geodetic_to_ecef(lat, lon, 0.0)
    p = np.hypot(r0[:, 0], r0[:, 1])
    np.testing.assert_allclose(
        (p / earth.A_WGS84) ** 2 + (r0[:, 2] / earth.B_WGS84) ** 2, 1.0, atol=4e-16
    )
    np.testing.assert_array_equal(earth.geodetic_to_ecef(0.0, 0.0, 0.0), [earth.A_WGS84, 0.0, 0.0])
    np.testing.assert_allclose(
        earth.geodetic_to_ecef(np.pi / 2, 0.3, 5.0), [0, 0, earth.B_WGS84 + 5.0], atol=1e-9, rtol=0
    )
    assert earth.geodetic_to_ecef(np.zeros((2, 1)), np.zeros(4), 0.0).shape == (2, 4, 3)


def test_ecef_to_geodetic_exact_against_mpmath():
    rng = np.random.default_rng(11)
    lat, lon, alt = samples(250, rng)
    r = earth.geodetic_to_ecef(lat, lon, alt)
    # Also points that are not images of float64 geodetic coordinates.
    r = np.concatenate([r, r[:100] * (1.0 + rng.uniform(-1e-3, 1e-3, (100, 1)))])
    la, lo, h = earth.ecef_to_geodetic(r)
    err_ulp, err_m = [], []
    for i in range(len(r)):
        phi, lam, hh = mp_ecef_to_geodetic(*r[i])
        err_ulp.append(
            [
                float(abs(la[i] - phi)) / np.spacing(abs(float(phi))),
                float(abs(lo[i] - lam)) / np.spacing(max(abs(float(lam)), 1e-300)),
            ]
        )
        rn, re = earth.radii(float(phi))
        err_m.append(
            [
                float(abs(la[i] - phi)) * (rn + float(hh)),
                float(abs(lo[i] - lam) * mp.cos(phi)) * (re + float(hh)),
                float(abs(h[i] - hh)),
            ]
        )
    err_ulp, err_m = np.array(err_ulp), np.array(err_m)
    assert err_ulp.max() <= ULP_TOL, err_ulp.max(axis=0)
    assert err_m[:, 2].max() <= H_TOL, err_m[:, 2].max()
    if EXTENDED:
        # In metres: < 1e-9 m north and up; east is bounded by half a longitude ulp, up to
        # 1.4e-9 m where |lon| > 2 near the equator (the float64 floor, not an algorithm error).
        assert err_m[:, 0].max() < 1e-9
        east_floor = 0.501 * np.spacing(np.abs(lo)) * (earth.transverse_radius(la) + h) * np.cos(la)
        assert np.all(err_m[:, 1] <= np.maximum(east_floor, 1e-12))
        assert err_m[np.abs(lo) < 2.0, 1].max() < 1e-9


def test_ecef_to_geodetic_edges_exact():
    b, a = earth.B_WGS84, earth.A_WGS84
    la, lo, h = earth.ecef_to_geodetic(
        [[0, 0, b], [0, 0, -b - 10.0], [a, 0, 0], [-a, 0, 0], [-a, -0.0, 0], [0, a + 1e6, 0]]
    )
    np.testing.assert_array_equal(la, [np.pi / 2, -np.pi / 2, 0, 0, 0, 0])
    np.testing.assert_array_equal(lo, [0, 0, 0, np.pi, -np.pi, np.pi / 2])
    np.testing.assert_allclose(h, [0, 10, 0, 0, 0, 1e6], atol=1e-9, rtol=0)


def test_geodetic_round_trips_1e5_points():
    rng = np.random.default_rng(12)
    lat, lon, alt = samples(100_000, rng)
    r = earth.geodetic_to_ecef(lat, lon, alt)
    la, lo, h = earth.ecef_to_geodetic(r)
    ned = np.abs(ned_error_m(la, lo, h, lat, lon, alt))
    # geodetic -> ECEF -> geodetic: every component below 1e-9 m (measured ~8e-10 m: the
    # rounding of r to float64, ≤ 4.7e-10 m per coordinate, is the floor).
    tol = 1e-9 if EXTENDED else 5e-9
    assert ned.max() < tol, ned.max(axis=0)
    # ECEF -> geodetic -> ECEF for those points.
    dr = np.linalg.norm(earth.geodetic_to_ecef(la, lo, h) - r, axis=-1)
    assert dr.max() < tol, dr.max()
    # Pole/equator/date-line points come back on the same side (no wrap or flip).
    assert np.all(np.abs(la) <= np.pi / 2) and np.all(np.abs(lo) <= np.pi)
    # Arbitrary ECEF points (not images of float64 geodetic coordinates): the round trip is
    # bounded by the float64 grid of (lat, lon) and of r, up to 1.4e-9 m (measured 1.4e-9 m).
    rr = r * (1.0 + rng.uniform(-1e-3, 1e-3, (len(r), 1)))
    la, lo, h = earth.ecef_to_geodetic(rr)
    rn, re = earth.radii(la)
    floor = np.hypot(
        0.5 * np.spacing(np.abs(la)) * (rn + h),
        0.5 * np.spacing(np.abs(lo)) * (re + h) * np.cos(la),
    ) + np.sqrt(3) * 0.5 * np.spacing(np.linalg.norm(rr, axis=-1))
    dr = np.linalg.norm(earth.geodetic_to_ecef(la, lo, h) - rr, axis=-1)
    assert np.all(dr <= floor + (1e-10 if EXTENDED else 5e-9)), (dr - floor).max()


def test_radii_against_meridian_ellipse():
    """R_N from the curvature of the ellipse x = a cos β, z = b sin β; R_E from the normal."""
    lats = np.concatenate([np.linspace(-np.pi / 2, np.pi / 2, 37), [0.123, -1.234]])
    rn, re = earth.radii(lats)
    with mp.workdps(MP_DPS):
        a, f, _ = mp_ellipsoid()
        b = a * (1 - f)
        pole = a**2 / b
    for i, phi in enumerate(lats):
        with mp.workdps(MP_DPS):
            phi_mp = mp.mpf(float(phi))
            beta = mp.atan2(b * mp.sin(phi_mp), a * mp.cos(phi_mp))  # tan β = (b/a) tan φ
            # Curvature radius of a parametric curve: (x'² + z'²)^{3/2} / |x' z'' - z' x''|.
            curv = (a**2 * mp.sin(beta) ** 2 + b**2 * mp.cos(beta) ** 2) ** 1.5 / (a * b)
            # Prime vertical: distance along the normal from the surface to the polar axis;
            # the normal direction (cos φ, sin φ) meets x = 0 after a cos β / cos φ. At the
            # pole it equals the meridian curvature radius (a²/b).
            rev = a * mp.cos(beta) / mp.cos(phi_mp) if abs(phi) < 1.5 else None
        assert rn[i] == pytest.approx(float(curv), rel=2e-15)
        if rev is not None:
            assert re[i] == pytest.approx(float(rev), rel=2e-15)
    assert re[0] == pytest.approx(float(pole), rel=1e-15)
    np.testing.assert_array_equal(earth.meridian_radius(lats), rn)
    np.testing.assert_array_equal(earth.transverse_radius(lats), re)
    # Arc-length rates of the forward map: |∂r/∂φ| = R_N + h, |∂r/∂λ| = (R_E + h) cos φ.
    lat, lon, h, d = 0.81, -2.2, 3000.0, 1e-7
    dr_dlat = (
        earth.geodetic_to_ecef(lat + d, lon, h) - earth.geodetic_to_ecef(lat - d, lon, h)
    ) / (2 * d)
    dr_dlon = (
        earth.geodetic_to_ecef(lat, lon + d, h) - earth.geodetic_to_ecef(lat, lon - d, h)
    ) / (2 * d)
    assert np.linalg.norm(dr_dlat) == pytest.approx(earth.meridian_radius(lat) + h, rel=1e-8)
    assert np.linalg.norm(dr_dlon) == pytest.approx(
        (earth.transverse_radius(lat) + h) * np.cos(lat), rel=1e-8
    )


def test_dcm_ned_to_ecef_against_finite_differences():
    rng = np.random.default_rng(13)
    lat = np.concatenate([rng.uniform(-1.55, 1.55, 50), [0.0]])
    lon = np.concatenate([rng.uniform(-np.pi, np.pi, 50), [np.pi]])
    h, d = 100.0, 1e-6
    c = earth.dcm_ned_to_ecef(lat, lon)
    np.testing.assert_allclose(
        np.swapaxes(c, -1, -2) @ c, np.broadcast_to(np.eye(3), c.shape), atol=4e-16
    )
    np.testing.assert_allclose(np.linalg.det(c), 1.0, atol=4e-16)

    def unit(v):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    north = unit(earth.geodetic_to_ecef(lat + d, lon, h) - earth.geodetic_to_ecef(lat - d, lon, h))
    east = unit(earth.geodetic_to_ecef(lat, lon + d, h) - earth.geodetic_to_ecef(lat, lon - d, h))
    down = earth.geodetic_to_ecef(lat, lon, h - 0.5) - earth.geodetic_to_ecef(lat, lon, h + 0.5)
    np.testing.assert_allclose(c[..., 0], north, atol=1e-9)
    np.testing.assert_allclose(c[..., 1], east, atol=1e-9)
    np.testing.assert_allclose(c[..., 2], down, atol=1e-9)
    np.testing.assert_array_equal(earth.dcm_ecef_to_ned(lat, lon), np.swapaxes(c, -1, -2))
    # North pole: down is -z, north points from the pole towards the meridian of lon, i.e. -x
    # at lon = 0.
    np.testing.assert_allclose(
        earth.dcm_ned_to_ecef(np.pi / 2, 0.0), [[-1, 0, 0], [0, 1, 0], [0, 0, -1]], atol=1e-16
    )
    assert earth.dcm_ned_to_ecef(np.zeros(4), 0.0).shape == (4, 3, 3)


def test_dcm_ecef_to_e0():
    np.testing.assert_array_equal(earth.dcm_ecef_to_e0(0.0), np.eye(3))
    t = 6 * 3600.0
    th = earth.OMEGA_IE * t
    np.testing.assert_allclose(
        earth.dcm_ecef_to_e0(t),
        [[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]],
        atol=1e-16,
    )
    # A point fixed on the equator at lon 0 moves eastwards (+y) in E0 after t > 0.
    assert (earth.dcm_ecef_to_e0(100.0) @ [earth.A_WGS84, 0, 0])[1] > 0
    ts = np.array([0.0, 1.0, 1e5])
    np.testing.assert_allclose(
        earth.dcm_e0_to_ecef(ts) @ earth.dcm_ecef_to_e0(ts),
        np.broadcast_to(np.eye(3), (3, 3, 3)),
        atol=1e-15,
    )
    # Earth rate: dC_E^E0/dt = C_E^E0 (ω_ie×) (central difference).
    dt = 1.0
    dc = (earth.dcm_ecef_to_e0(1000.0 + dt) - earth.dcm_ecef_to_e0(1000.0 - dt)) / (2 * dt)
    w = np.array([[0, -earth.OMEGA_IE, 0], [earth.OMEGA_IE, 0, 0], [0, 0, 0]])
    np.testing.assert_allclose(dc, earth.dcm_ecef_to_e0(1000.0) @ w, atol=1e-13)


def _rot(axis, ang):
    """Rodrigues rotation (independent of strapdown_ros.core.rotations)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    ang = np.asarray(ang)[..., None, None]
    return np.eye(3) + np.sin(ang) * k + (1 - np.cos(ang)) * (k @ k)


def _moving_body(t):
    """A body flying over the Earth: geodetic path, and C_B^E rotating at a known ω_eb^B."""
    lat = 0.6 + 2e-5 * t + 1e-3 * np.sin(0.05 * t)
    lon = -2.0 + 3e-5 * t
    alt = 1000.0 + 50.0 * np.cos(0.1 * t)
    w_eb_b = np.array([0.01, -0.02, 0.03])  # constant body rate relative to E, rad/s
    c0 = _rot([1.0, 2.0, -0.5], 0.7)
    c_b_e = c0 @ _rot(w_eb_b, np.linalg.norm(w_eb_b) * t)
    return earth.geodetic_to_ecef(lat, lon, alt), c_b_e, w_eb_b


def test_state_conversion_against_numerical_derivative():
    t = np.array([0.0, 37.0, 5000.0])
    d = 1e-2
    r, c_b_e, w_eb_b = _moving_body(t)

    def deriv(fun, tt):
        """Fourth-order central difference."""
        return (8 * (fun(tt + d) - fun(tt - d)) - (fun(tt + 2 * d) - fun(tt - 2 * d))) / (12 * d)

    def r_e0(tt):
        return (earth.dcm_ecef_to_e0(tt) @ _moving_body(tt)[0][..., None])[..., 0]

    v = deriv(lambda tt: _moving_body(tt)[0], t)  # dr^E/dt
    R, V, C = earth.ecef_state_to_e0(t, r, v, c_b_e)
    V_num = deriv(r_e0, t)  # d/dt [C_E^E0(t) r^E(t)]
    np.testing.assert_allclose(V, V_num, atol=1e-6, rtol=0)  # |ω_ie × r| ≈ 270 m/s here
    np.testing.assert_allclose(R, r_e0(t), atol=0)
    np.testing.assert_allclose(C, earth.dcm_ecef_to_e0(t) @ c_b_e, atol=0)

    # Inertial body rate from dC_B^E0/dt = C_B^E0 (ω_ib^B ×), then ω_eb^B = ω_ib^B - C_E^B ω_ie.
    def c_e0(tt):
        return earth.dcm_ecef_to_e0(tt) @ _moving_body(tt)[1]

    dc = (c_e0(t + d) - c_e0(t - d)) / (2 * d)
    wx = np.swapaxes(C, -1, -2) @ dc
    w_ib_b = np.stack([wx[:, 2, 1], wx[:, 0, 2], wx[:, 1, 0]], -1)
    np.testing.assert_allclose(
        earth.body_rates_relative_to_earth(w_ib_b, c_b_e),
        np.broadcast_to(w_eb_b, (3, 3)),
        atol=1e-8,
    )
    # ... and the Earth-rate part is exactly C_E^B ω_ie^E.
    np.testing.assert_allclose(
        earth.body_rates_relative_to_earth(np.zeros(3), c_b_e),
        -np.einsum("nji,j->ni", c_b_e, earth.OMEGA_IE_VEC),
        atol=1e-20,
    )


def test_state_conversion_round_trip():
    rng = np.random.default_rng(14)
    n = 1000
    t = rng.uniform(0, 1e6, n)
    r = earth.geodetic_to_ecef(*random_geodetic(n, rng))
    v = rng.normal(scale=300.0, size=(n, 3))
    c = _rot([0.3, -1.0, 2.0], rng.uniform(-np.pi, np.pi, n))
    R, V, C = earth.ecef_state_to_e0(t, r, v, c)
    r2, v2, c2 = earth.e0_state_to_ecef(t, R, V, C)
    np.testing.assert_allclose(r2, r, atol=4e-9, rtol=0)
    np.testing.assert_allclose(v2, v, atol=2e-12, rtol=0)
    np.testing.assert_allclose(c2, c, atol=2e-15, rtol=0)
    # Inertial speed includes the Earth's rotation: a point at rest on the equator.
    _, V0, none = earth.ecef_state_to_e0(123.0, [earth.A_WGS84, 0, 0], [0, 0, 0])
    assert none is None
    assert np.linalg.norm(V0) == pytest.approx(earth.OMEGA_IE * earth.A_WGS84, rel=1e-15)
    assert earth.e0_state_to_ecef(0.0, [earth.A_WGS84, 0, 0], [0, 0, 0])[2] is None
    # Broadcasting: one state at many times, and scalar time for many states.
    assert earth.ecef_state_to_e0(t, r[0], v[0])[0].shape == (n, 3)
    assert earth.ecef_state_to_e0(1.0, r, v, c)[2].shape == (n, 3, 3)


def test_ned_velocity_and_geodetic_rates():
    """Geodetic rates from the NED velocity of a path equal the path's own derivatives."""
    t = np.array([0.0, 10.0, 300.0])
    d = 1e-3
    lat0, lon0, alt0 = 0.9, 3.0, 200.0
    rates = np.array([3e-5, -4e-5, 12.0])  # lat, lon, alt rates (rad/s, rad/s, m/s)

    def pos(tt):
        return earth.geodetic_to_ecef(
            lat0 + rates[0] * tt, lon0 + rates[1] * tt, alt0 + rates[2] * tt
        )

    lat, lon, alt = lat0 + rates[0] * t, lon0 + rates[1] * t, alt0 + rates[2] * t
    v_e = (pos(t + d) - pos(t - d)) / (2 * d)
    v_ned = earth.ned_velocity_from_ecef(lat, lon, v_e)
    lat_dot, lon_dot, alt_dot = earth.geodetic_rates(lat, alt, v_ned)
    np.testing.assert_allclose(lat_dot, rates[0], rtol=1e-7)
    np.testing.assert_allclose(lon_dot, rates[1], rtol=1e-7)
    np.testing.assert_allclose(alt_dot, rates[2], rtol=1e-7)
    np.testing.assert_allclose(earth.ecef_velocity_from_ned(lat, lon, v_ned), v_e, atol=1e-12)
    # NED axes: moving up (v_D < 0) at lon = 0 on the equator is +x in ECEF.
    np.testing.assert_allclose(
        earth.ecef_velocity_from_ned(0.0, 0.0, [0, 0, -1.0]), [1, 0, 0], atol=1e-16
    )
