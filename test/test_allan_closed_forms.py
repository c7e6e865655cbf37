"""The Allan-deviation model of ``core/allan.py`` term by term against the closed forms.

Expected values are written here from IEEE Std 952-1997 Annex C (white rate noise
σ² = N²/τ, rate random walk σ² = K²τ/3, quantization σ² = 3Q²/τ²) and from the Allan variance
of a first-order Gauss–Markov rate with steady-state σ and correlation time T_c (El-Sheimy,
Hou, Niu 2008, IEEE Trans. Instrum. Meas. 57(1), Table 1, with the driving PSD q_c² = 2σ²/T_c):

    σ_A²(τ) = (2σ²T_c/τ) [1 − (T_c/2τ)(3 − 4e^{−τ/T_c} + e^{−2τ/T_c})],

whose limits are the white noise 2σ²T_c/τ (τ ≫ T_c) and the rate random walk 2σ²τ/(3T_c)
(τ ≪ T_c). Each term is called alone, with the other keywords left at their defaults, so a
default that is not "no such term" (or a correlation time other than 1 s) shows.
"""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.core import allan

TAUS = np.array([0.01, 0.1, 0.5, 1.0, 3.0, 10.0, 100.0, 1000.0])


def _gauss_markov_avar(tau, sigma, tc):
    x = tau / tc
    bracket = 1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x)
    return (2.0 * sigma**2 * tc / tau) * bracket


def test_white_noise_alone():
    # measured: equal to the closed form within 1 ulp
    np.testing.assert_allclose(allan.model_allan_deviation(TAUS, white=2e-3), 2e-3 / np.sqrt(TAUS),
                               rtol=1e-15)  # fmt: skip


def test_rate_random_walk_alone():
    np.testing.assert_allclose(
        allan.model_allan_deviation(TAUS, random_walk=5e-5), 5e-5 * np.sqrt(TAUS / 3.0), rtol=1e-15
    )


def test_quantization_alone():
    np.testing.assert_allclose(
        allan.model_allan_deviation(TAUS, quantization=1e-6), np.sqrt(3.0) * 1e-6 / TAUS, rtol=1e-15
    )


def test_no_term_is_zero():
    assert np.array_equal(allan.model_allan_deviation(TAUS), np.zeros_like(TAUS))


@pytest.mark.parametrize("tc", [None, 0.3, 50.0])
def test_gauss_markov_alone_against_the_closed_form(tc):
    """With the default correlation time (1 s) and two others. Small τ/T_c loses digits in the
    closed form's bracket (1 − (1 − x²/3 …)), hence the floor at τ ≥ T_c/100."""
    sigma = 3e-4
    kw = {} if tc is None else {"correlation_time_s": tc}
    t_c = 1.0 if tc is None else tc
    taus = TAUS[TAUS >= t_c / 100.0]
    got = allan.model_allan_deviation(taus, gauss_markov_sigma=sigma, **kw)
    np.testing.assert_allclose(got, np.sqrt(_gauss_markov_avar(taus, sigma, t_c)), rtol=1e-9)


def test_gauss_markov_limits():
    """τ ≫ T_c: white noise N² = 2σ²T_c; τ ≪ T_c: rate random walk K² = 2σ²/T_c."""
    sigma, tc = 1e-3, 2.0
    long = allan.model_allan_deviation(np.array([2e4]), gauss_markov_sigma=sigma,
                                       correlation_time_s=tc)  # fmt: skip
    np.testing.assert_allclose(long, np.sqrt(2 * sigma**2 * tc / 2e4), rtol=1e-3)
    short = allan.model_allan_deviation(np.array([1e-3]), gauss_markov_sigma=sigma,
                                        correlation_time_s=tc)  # fmt: skip
    np.testing.assert_allclose(short, np.sqrt(2 * sigma**2 * 1e-3 / (3 * tc)), rtol=1e-3)


def test_terms_add_in_variance():
    taus = np.array([0.1, 1.0, 10.0])
    got = allan.model_allan_deviation(taus, white=1e-3, random_walk=1e-4, quantization=1e-5,
                                      gauss_markov_sigma=2e-4, correlation_time_s=5.0)  # fmt: skip
    want = np.sqrt(1e-6 / taus + 1e-8 * taus / 3 + 3e-10 / taus**2
                   + _gauss_markov_avar(taus, 2e-4, 5.0))  # fmt: skip
    np.testing.assert_allclose(got, want, rtol=1e-12)


def _flicker_like(taus):
    """A bathtub: white N²/τ plus rate random walk K²τ/3, flat (slope 0) at τ* = √3 N/K."""
    return np.sqrt(1e-6 / taus + 1e-8 * taus / 3.0)


def test_bias_instability_reads_the_minimum_of_a_bathtub():
    """The slope-0 point of N²/τ + K²τ/3 is τ* = √3 N/K = 17.3 s, σ(τ*)² = 2N²/τ*; the reading
    is the grid point nearest in slope, its σ divided by √(2 ln 2/π) (IEEE Std 952)."""
    taus = np.geomspace(0.1, 1000.0, 81)
    b, tau_flat = allan.bias_instability(taus, _flicker_like(taus))
    assert np.shape(b) == () and np.shape(tau_flat) == ()
    assert abs(np.log(tau_flat / (np.sqrt(3.0) * 1e-3 / 1e-4))) < np.log(taus[1] / taus[0])
    sigma_min = np.sqrt(2e-6 / (np.sqrt(3.0) * 10.0))
    np.testing.assert_allclose(b * np.sqrt(2 * np.log(2) / np.pi), sigma_min, rtol=2e-3)


def test_bias_instability_per_column_and_range():
    taus = np.geomspace(0.1, 1000.0, 81)
    one = _flicker_like(taus)
    b, tau_flat = allan.bias_instability(taus, np.stack([one, 2 * one], axis=1))
    assert b.shape == (2,) and tau_flat.shape == (2,)
    np.testing.assert_allclose(b[1], 2 * b[0], rtol=1e-14)
    b_lo, t_lo = allan.bias_instability(taus, one, tau_max=1.0)  # only the white branch
    assert t_lo <= 1.0 and b_lo > b[0]
    _, t_hi = allan.bias_instability(taus, one, tau_min=100.0, tau_max=300.0)
    assert 100.0 <= t_hi <= 300.0


def test_bias_instability_input_errors():
    taus = np.array([1.0, 2.0, 4.0])
    allan.bias_instability(taus, np.array([3.0, 2.0, 3.0]), tau_max=4.0)  # 3 τ: enough
    msg = "^need >= 3 increasing τ and an adev with one row per τ$"
    with pytest.raises(ValueError, match=msg):
        allan.bias_instability(taus[:2], np.array([1.0, 1.0]))
    with pytest.raises(ValueError, match=msg):
        allan.bias_instability(taus, np.ones(4))
    with pytest.raises(ValueError, match=msg):
        allan.bias_instability(taus.reshape(1, 3), np.ones(3))
    with pytest.raises(ValueError, match="^no τ in the requested range$"):
        allan.bias_instability(taus, np.ones(3), tau_min=10.0)


# log σ on an uneven τ grid, written so that the slope (central difference in log-log) is
# -0.455 at τ = 2, +0.144 at τ = 3 = τ_max/3 and exactly 0 at τ = 5 (beyond the default range).
UNEVEN_TAUS = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 9.0])
UNEVEN_LOG_ADEV = np.array([0.0, -1.0, -0.5, -0.9, -2.0, -0.9, -3.0])


@pytest.mark.parametrize(
    ("kw", "tau_want"),
    [({}, 3.0), ({"tau_min": 2.0}, 3.0), ({"tau_min": 3.0}, 3.0), ({"tau_max": 100.0}, 5.0),
     ({"tau_max": 2.9}, 2.0)],
)  # fmt: skip
def test_bias_instability_range_edges_on_an_uneven_grid(kw, tau_want):
    """Default τ_max = largest τ / 3 and both bounds inclusive; the slope is a difference
    quotient (on an even log grid any constant scaling would pick the same point)."""
    adev = np.exp(UNEVEN_LOG_ADEV)
    b, tau_flat = allan.bias_instability(UNEVEN_TAUS, adev, **kw)
    assert tau_flat == tau_want
    i = int(np.flatnonzero(UNEVEN_TAUS == tau_want)[0])
    assert b == pytest.approx(adev[i] / np.sqrt(2.0 * np.log(2.0) / np.pi), rel=1e-15, abs=0.0)


def test_bias_instability_slope_is_the_log_log_difference_quotient():
    """Candidates whose log-σ differences and log-τ spacings rank differently: by the quotient
    Δlnσ/Δlnτ the flattest is τ = 8000 s (0.4/3.91 = 0.10, against 0.05/0.18 = 0.27 at
    1100 s); a product or a sum of the log τ would pick 1100 s."""
    taus = 1000.0 * np.array([1.0, 1.1, 1.2, 8.0, 60.0, 3000.0])
    log_adev = np.array([0.0, -1.0, 0.05, 1.0, 0.45, 4.0])
    b, tau_flat = allan.bias_instability(taus, np.exp(log_adev))
    assert tau_flat == 8000.0
    assert b == pytest.approx(np.e / np.sqrt(2.0 * np.log(2.0) / np.pi), rel=1e-15, abs=0.0)


@pytest.mark.parametrize("x", [1e-8, 1e-6, 3e-5, 9.9e-5, 2e-4, 1e-2, 1.0, 30.0])
def test_gauss_markov_shape_against_mpmath(x):
    """g(x) = σ²(τ)/σ² at x = τ/τ_c, from the closed form in 50-digit arithmetic (mpmath), on
    both sides of the series switch at x = 1e-4. Measured relative errors: ≤ 1.2e-13 below the
    switch (the series' x⁵ term), 1.1e-8 at x = 2e-4 and 3.4e-12 at 1e-2 (the cancelling
    bracket, ~1e-16 / (x²/3)), ≤ 2e-16 from x = 1. Tolerances about 10× those; 1e-12 below the
    switch also sees a 2 % change of the series' 7x⁴/60 term (6e-11 of g at x = 9.9e-5)."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 50
    xm = mpmath.mpf(x)
    want = float(2 / xm * (1 - (3 - 4 * mpmath.exp(-xm) + mpmath.exp(-2 * xm)) / (2 * xm)))
    rtol = 1e-12 if x < 1e-4 else 1e-7 if x < 1e-3 else 1e-10 if x < 0.1 else 1e-14
    got = allan.gauss_markov_allan_variance(np.array([x]), 1.0, 1.0)[0]
    assert got == pytest.approx(want, rel=rtol, abs=0.0)


def test_gauss_markov_needs_a_positive_correlation_time():
    for tc in (0.0, -1.0):
        with pytest.raises(ValueError, match=rf"^correlation_time_s must be > 0, got {tc}$"):
            allan.gauss_markov_allan_variance(np.array([1.0]), 1.0, tc)
