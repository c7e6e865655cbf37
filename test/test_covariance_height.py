"""down_as_height_error: the error topic's NED down against −δh, from the WGS-84 closed form."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.analysis.covariance_check import Ensemble, down_as_height_error

A, F = 6378137.0, 1.0 / 298.257223563  # WGS-84
E2 = F * (2.0 - F)


def ecef(lat: float, lon: float, h: float) -> np.ndarray:
    n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.array([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - E2) + h) * np.sin(lat)])  # fmt: skip


def ned_rows(lat: float, lon: float) -> np.ndarray:
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-sl * co, -sl * so, cl], [-so, co, 0.0], [-cl * co, -cl * so, -sl]])


LAT, LON, H = np.radians(47.5), np.radians(8.5), 420.0
R_N = A * (1.0 - E2) / (1.0 - E2 * np.sin(LAT) ** 2) ** 1.5 + H
R_E = A / np.sqrt(1.0 - E2 * np.sin(LAT) ** 2) + H
# computed points: north, east offsets of ~0.5–3 km and height errors (m)
OFFSETS = [(2000.0, 0.0, 0.0), (0.0, -3000.0, 0.0), (1500.0, 1000.0, 0.7), (-500.0, 2500.0, -1.3)]


def _ensemble() -> tuple[Ensemble, np.ndarray]:
    r_true, c_en = ecef(LAT, LON, H), ned_rows(LAT, LON)
    errors, dh = np.zeros((len(OFFSETS), 2, 9)), np.empty(len(OFFSETS))
    for i, (north, east, h_err) in enumerate(OFFSETS):
        lat, lon = LAT + north / R_N, LON + east / (R_E * np.cos(LAT))
        errors[i, :, :3] = c_en @ (ecef(lat, lon, H + h_err) - r_true)
        errors[i, :, 3:] = np.arange(6) + i  # untouched by the correction
        dh[i] = h_err
    return Ensemble(np.array([0, 10**9], dtype=np.int64), errors), dh


def test_raw_down_is_the_curvature_below_the_tangent_plane() -> None:
    ens, dh = _ensemble()
    x = ens.errors[:, 0]
    c = x[:, 0] ** 2 / (2 * R_N) + x[:, 1] ** 2 / (2 * R_E)
    # a point at the true height, displaced horizontally, is c below the tangent plane
    assert np.all(c[dh == 0] > 0.3)
    np.testing.assert_allclose(x[:, 2], c - dh, atol=3e-6)


def test_corrected_down_is_minus_the_height_error() -> None:
    ens, dh = _ensemble()
    before = ens.errors.copy()
    out = down_as_height_error(ens, LAT, H)
    np.testing.assert_array_equal(ens.errors, before)  # the input is not changed
    np.testing.assert_array_equal(out.stamps_ns, ens.stamps_ns)
    np.testing.assert_array_equal(np.delete(out.errors, 2, axis=2), np.delete(before, 2, axis=2))
    residual = out.errors[:, :, 2] + dh[:, None]
    # third order in the horizontal error: measured 3.2e-7 m for these offsets; limit 10×
    assert np.max(np.abs(residual)) < 3e-6, residual


@pytest.mark.parametrize("swap", [False, True])
def test_each_radius_goes_with_its_axis(swap: bool) -> None:
    """R_N with δr_N and R_E with δr_E: swapping them (at 47.5°, R_E − R_N ≈ 19 km) is seen."""
    ens, dh = _ensemble()
    errors = ens.errors.copy()
    if swap:
        errors[..., [0, 1]] = errors[..., [1, 0]]
    out = down_as_height_error(Ensemble(ens.stamps_ns, errors), LAT, H)
    bad = np.max(np.abs(out.errors[:, :, 2] + dh[:, None]))
    assert (bad > 1e-3) if swap else (bad < 3e-6)
