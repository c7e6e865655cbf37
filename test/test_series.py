"""Coefficient functions of Savage 2020 eqs. (2)-(4) against mpmath at 60 digits."""

import mpmath as mp
import numpy as np
import pytest

from strapdown_ros.core import series

EPS = np.finfo(float).eps


def reference(x: float) -> list[mp.mpf]:
    """f1..f4 in high precision; digits scale with 1/x so cancellation cannot leak in."""
    with mp.workdps(60 + int(4 * max(0.0, -np.log10(max(x, 1e-300))))):
        xm = mp.mpf(x)
        if xm == 0:
            return [mp.mpf(1), mp.mpf(1) / 2, mp.mpf(1) / 6, mp.mpf(1) / 24]
        return [
            mp.sin(xm) / xm,
            (1 - mp.cos(xm)) / xm**2,
            (1 - mp.sin(xm) / xm) / xm**2,
            (mp.mpf(1) / 2 - (1 - mp.cos(xm)) / xm**2) / xm**2,
        ]


GRID = np.unique(
    np.concatenate(
        [
            [0.0, 1e-300, 1e-30, 1e-9, 1e-4, 0.1, 1.0, np.pi - 1e-9, np.pi, 10.0, 1e3],
            np.linspace(0.0, 7.0, 301),
            series.SERIES_SWITCH + np.array([-1e-12, -1e-15, 0.0, 1e-15, 1e-12]),
        ]
    )
)


@pytest.mark.parametrize("name", ["f1", "f2", "f3", "f4"])
def test_relative_accuracy_against_mpmath(name):
    index = int(name[1]) - 1
    fn = getattr(series, name)
    worst = 0.0
    for x in GRID:
        ref = reference(float(x))[index]
        if ref == 0:
            continue
        worst = max(worst, float(abs((mp.mpf(float(fn(x))) - ref) / ref)))
    # f3/f4 closed forms beyond the switch have cancellation of at most 12 eps / x^2 = 3 eps.
    assert worst < 5 * EPS, f"{name}: worst relative error {worst:.2e}"


def test_series_and_closed_forms_agree_at_the_switch():
    """Both sides of the switch agree to < 1e-15 relative (continuity requirement)."""
    xs = series.SERIES_SWITCH
    below = np.nextafter(xs, 0.0)
    vals_below = series.rotation_coefficients(below)
    vals_at = series.rotation_coefficients(xs)  # closed form
    for lo, hi in zip(vals_below, vals_at, strict=True):
        assert abs(float(lo) - float(hi)) / abs(float(hi)) < 1e-15


def test_rotation_coefficients_match_single_functions():
    x = np.linspace(0, 8, 1001)
    for got, fn in zip(
        series.rotation_coefficients(x), (series.f1, series.f2, series.f3, series.f4), strict=True
    ):
        np.testing.assert_array_equal(got, fn(x))


def test_negative_angles_use_magnitude():
    np.testing.assert_array_equal(series.f3(-0.7), series.f3(0.7))
