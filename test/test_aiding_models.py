"""Aiding-sensor models (strapdown_ros.core.aiding): statistics, seeds, chunks, references.

Statistical tolerances are 4 standard errors of the estimator for the run length used (stated
next to each check), so a correct model fails with probability < 1e-4 per check, and the seeds
are fixed anyway (bit-reproducible).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from strapdown_ros.core.aiding import (
    BaroErrorModel,
    BaroErrors,
    GaussMarkov,
    GnssErrorModel,
    GnssErrors,
    MagnetometerErrorModel,
    MagnetometerErrors,
    OdometerErrorModel,
    OdometerErrors,
    icao_pressure,
    igrf_field_ned,
)
from strapdown_ros.core.aiding.common import sensor_rng
from strapdown_ros.core.earth import geodetic_to_ecef

# ---------------------------------------------------------------------------------------------
# estimators and their standard errors


def _ar1_phi(x: np.ndarray) -> float:
    """Lag-1 autocorrelation (mean removed)."""
    x = x - x.mean()
    return float(np.dot(x[:-1], x[1:]) / np.dot(x, x))


def _std_tolerance(n: int, phi: float) -> float:
    """4 standard errors of the relative sample std of an AR(1) sequence of n samples.

    Var(s²)/σ⁴ ≈ 2 (1 + φ²) / ((1 − φ²) n), so the relative error of s is half its square root.
    """
    return 4.0 * 0.5 * math.sqrt(2.0 * (1.0 + phi**2) / ((1.0 - phi**2) * n))


def _tau_tolerance(n: int, phi: float, period: float) -> float:
    """4 standard errors of τ̂ = −P / ln φ̂ (Var φ̂ ≈ (1 − φ²)/n; dτ/dφ = P / (φ ln² φ))."""
    return 4.0 * math.sqrt((1.0 - phi**2) / n) * period / (phi * math.log(phi) ** 2)


# ---------------------------------------------------------------------------------------------
# GNSS


N_EPOCHS = 200_000  # 55 h at 1 Hz


def _gnss_errors() -> GnssErrors:
    return GnssErrors(
        position_white=np.array([0.3, 0.4, 0.6]),
        position_gm_sigma=np.array([1.5, 2.0, 3.0]),
        position_gm_tau_s=np.array([50.0, 100.0, 200.0]),
        position_offset=np.array([0.5, -0.25, 1.0]),
        velocity_white=np.array([0.05, 0.05, 0.1]),
        velocity_gm_sigma=np.array([0.02, 0.03, 0.04]),
        velocity_gm_tau_s=np.array([20.0, 30.0, 40.0]),
        velocity_offset=np.array([0.0, 0.01, 0.0]),
    )


def test_gnss_gauss_markov_sigma_and_correlation_time():
    """White σ, GM σ and τ of every axis recovered from 200 000 epochs (tolerances: 4 SE)."""
    e = GnssErrors(
        position_gm_sigma=np.array([1.5, 2.0, 3.0]),
        position_gm_tau_s=np.array([50.0, 100.0, 200.0]),
        velocity_gm_sigma=np.array([0.02, 0.03, 0.04]),
        velocity_gm_tau_s=np.array([20.0, 30.0, 40.0]),
    )
    pos, vel = GnssErrorModel(e, 1.0, seed=3).take(N_EPOCHS)
    for data, sigma, tau in (
        (pos, e.position_gm_sigma, e.position_gm_tau_s),
        (vel, e.velocity_gm_sigma, e.velocity_gm_tau_s),
    ):
        for axis in range(3):
            phi = math.exp(-1.0 / tau[axis])
            std = data[:, axis].std()
            assert abs(std / sigma[axis] - 1) < _std_tolerance(N_EPOCHS, phi), (axis, std)
            tau_hat = -1.0 / math.log(_ar1_phi(data[:, axis]))
            assert abs(tau_hat - tau[axis]) < _tau_tolerance(N_EPOCHS, phi, 1.0), (axis, tau_hat)


def test_gnss_white_noise_and_offset():
    """White σ (4 SE: 4/√(2n) relative), offset as the mean (4 SE: 4σ/√n), no correlation."""
    e = GnssErrors(
        position_white=np.array([0.3, 0.4, 0.6]),
        position_offset=np.array([0.5, -0.25, 1.0]),
        velocity_white=np.array([0.05, 0.05, 0.1]),
    )
    pos, vel = GnssErrorModel(e, 0.2, seed=4).take(N_EPOCHS)
    tol = 4.0 / math.sqrt(2 * N_EPOCHS)
    for data, white, offset in ((pos, e.position_white, e.position_offset),
                                (vel, e.velocity_white, np.zeros(3))):  # fmt: skip
        assert np.all(np.abs(data.std(axis=0) / white - 1) < tol)
        assert np.all(np.abs(data.mean(axis=0) - offset) < 4 * white / math.sqrt(N_EPOCHS))
        for axis in range(3):
            assert abs(_ar1_phi(data[:, axis])) < 4 / math.sqrt(N_EPOCHS)


def test_gnss_chunks_seeds_and_skip():
    """Chunked takes equal one take bit for bit; same seed same bits; skip = take discarded."""
    e = _gnss_errors()
    whole = GnssErrorModel(e, 1.0, seed=7).take(1000)
    m = GnssErrorModel(e, 1.0, seed=7)
    parts = [m.take(n) for n in (1, 2, 3, 5, 8, 13, 21, 34, 55, 89, 144, 233, 392)]
    assert np.array_equal(np.concatenate([p[0] for p in parts]), whole[0])
    assert np.array_equal(np.concatenate([p[1] for p in parts]), whole[1])
    again = GnssErrorModel(e, 1.0, seed=7).take(1000)
    assert np.array_equal(again[0], whole[0]) and np.array_equal(again[1], whole[1])
    other = GnssErrorModel(e, 1.0, seed=8).take(1000)
    assert np.all(other[0] != whole[0])
    skipped = GnssErrorModel(e, 1.0, seed=7)
    skipped.skip(400)
    assert np.array_equal(skipped.take(600)[0], whole[0][400:])


def test_sensor_streams_independent():
    """The same seed on two sensors gives independent normals (correlation within 4/√n)."""
    n = 100_000
    a = sensor_rng(5, "gnss").standard_normal(n)
    b = sensor_rng(5, "baro").standard_normal(n)
    assert abs(np.corrcoef(a, b)[0, 1]) < 4 / math.sqrt(n)


def test_gauss_markov_zero_sigma_is_zero_and_needs_tau():
    gm = GaussMarkov([0.0, 1.0], [1.0, 10.0], 1.0, [0.3, 0.3])
    out = gm.take(np.ones((5, 2)))
    assert np.all(out[:, 0] == 0) and np.all(out[:, 1] != 0)
    with pytest.raises(ValueError, match="tau"):
        GaussMarkov([1.0], [0.0], 1.0, [0.0])


# ---------------------------------------------------------------------------------------------
# Barometer


def test_icao_pressure_matches_ambiance():
    """Our ICAO 1993 atmosphere vs ambiance from −5 km to 80 km: ≤ 3e-6 relative (ambiance
    uses the table's rounded layer-base pressures, e.g. 22632.1 Pa at 11 km vs 22632.06)."""
    ambiance = pytest.importorskip("ambiance")
    h = np.linspace(-5000.0, 80000.0, 1701)
    ref = ambiance.Atmosphere(h).pressure
    assert np.max(np.abs(icao_pressure(h) / ref - 1)) < 3e-6
    assert icao_pressure(np.array([0.0]))[0] == 101325.0


def test_baro_statistics_quantization_chunks():
    """Drift σ and τ (4 SE), white σ, turn-on bias drawn once, quantized output, chunks."""
    e = BaroErrors(drift_sigma=30.0, drift_tau_s=100.0, white=0.0, quantum=0.0)
    n = 200_000
    out = BaroErrorModel(e, 1.0, seed=1).apply(np.zeros(n))
    phi = math.exp(-1.0 / 100.0)
    assert abs(out.std() / 30.0 - 1) < _std_tolerance(n, phi)
    assert abs(-1.0 / math.log(_ar1_phi(out)) - 100.0) < _tau_tolerance(n, phi, 1.0)
    w = BaroErrorModel(BaroErrors(white=2.0), 0.04, seed=2).apply(np.full(n, 9e4))
    assert abs((w - 9e4).std() / 2.0 - 1) < 4 / math.sqrt(2 * n)
    full = BaroErrors(bias=10.0, turn_on_bias_sigma=50.0, drift_sigma=20.0, drift_tau_s=60.0,
                      white=3.0, quantum=0.5)  # fmt: skip
    p = np.linspace(9e4, 1e5, 5000)
    model = BaroErrorModel(full, 0.04, seed=9)
    whole = model.apply(p)
    assert np.all(np.abs(whole / 0.5 - np.round(whole / 0.5)) < 1e-9)
    m2 = BaroErrorModel(full, 0.04, seed=9)
    cuts = ((0, 1), (1, 7), (7, 2500), (2500, 5000))
    chunks = np.concatenate([m2.apply(p[a:b]) for a, b in cuts])
    assert np.array_equal(chunks, whole)
    assert model.bias != 10.0  # the turn-on bias was drawn
    assert full.variance == 3.0**2 + 20.0**2 + 0.5**2 / 12


# ---------------------------------------------------------------------------------------------
# Magnetometer


def _igrf_arrays(year: float) -> tuple[np.ndarray, np.ndarray]:
    from strapdown_ros.stages.aiding import igrf_coefficients

    return igrf_coefficients(year)


@pytest.mark.parametrize("year", [1900.0, 1965.5, 1994.9, 2000.0, 2017.3, 2026.0, 2029.9])
def test_igrf_synthesis_matches_pyigrf14(year):
    """Our vectorized synthesis vs pyIGRF14's scalar port of the IAGA routine: ≤ 0.05 nT
    (requirement ≤ 1 nT; the residual is pyIGRF14's rounded WGS-84 a², b²) at 300 points from
    pole to pole, −1 km to 400 km."""
    pyigrf = pytest.importorskip("pyIGRF14")
    g, h = _igrf_arrays(year)
    rng = np.random.default_rng(int(year * 10))
    lat = np.concatenate([rng.uniform(-89.9, 89.9, 296), [90.0, -90.0, 0.0, 45.0]])
    lon = np.concatenate([rng.uniform(-180.0, 180.0, 296), [0.0, 10.0, 0.0, -75.0]])
    alt = np.concatenate([rng.uniform(-1000.0, 400_000.0, 296), [0.0, 1000.0, 0.0, 0.0]])
    r = geodetic_to_ecef(np.radians(lat), np.radians(lon), alt)
    ours = igrf_field_ned(r, np.radians(lat), g, h)
    ref = np.array(
        [pyigrf.igrf_value(a, o % 360.0, z / 1000.0, year)[3:6] for a, o, z in zip(lat, lon, alt,
                                                                                  strict=True)]
    )  # fmt: skip
    assert np.max(np.abs(ours - ref)) < 0.05
    one_by_one = np.concatenate([igrf_field_ned(r[i : i + 1], np.radians(lat[i : i + 1]), g, h)
                                 for i in range(len(lat))])  # fmt: skip
    assert np.array_equal(one_by_one, ours)  # chunk-invariant (sums over m sequential)


def test_magnetometer_errors_and_chunks():
    """Hard iron, soft iron and noise σ (4 SE); chunk invariance; identity when errors off."""
    n = 100_000
    field = np.tile([20e-6, -3e-6, 45e-6], (n, 1))
    assert np.array_equal(MagnetometerErrorModel(MagnetometerErrors(), 0.02, 0).apply(field), field)
    soft = np.array([[1.02, 0.01, 0.0], [0.01, 0.98, 0.005], [0.0, 0.005, 1.01]])
    e = MagnetometerErrors(hard_iron=np.array([1e-6, -2e-6, 0.5e-6]), soft_iron=soft,
                           white=np.array([0.3e-6, 0.3e-6, 0.5e-6]))  # fmt: skip
    out = MagnetometerErrorModel(e, 0.02, seed=1).apply(field)
    expected = soft @ field[0] + e.hard_iron
    assert np.all(np.abs(out.mean(axis=0) - expected) < 4 * e.white / math.sqrt(n))
    assert np.all(np.abs(out.std(axis=0) / e.white - 1) < 4 / math.sqrt(2 * n))
    m = MagnetometerErrorModel(e, 0.02, seed=1)
    parts = np.concatenate([m.apply(field[a:b]) for a, b in ((0, 3), (3, 1000), (1000, n))])
    assert np.array_equal(parts, out)


# ---------------------------------------------------------------------------------------------
# Wheel odometer


def test_odometer_quantization_bound_and_statistics():
    """Distance counted over any window within one pulse of the distance travelled; scale
    factor and noise σ (4 SE); chunks."""
    period = 0.02
    t = np.arange(50_000) * period
    speed = 10.0 + 5.0 * np.sin(0.05 * t)
    q_model = OdometerErrorModel(OdometerErrors(pulses_per_m=48.0), period, seed=0)
    out = q_model.apply(speed)
    q = 1 / 48.0
    assert np.all(np.abs(out * period / q - np.round(out * period / q)) < 1e-6)
    counted = np.cumsum(out * period)
    travelled = np.cumsum(speed * period)
    diff = counted - travelled
    assert np.max(diff) - np.min(diff) < q  # any window: within one pulse
    e = OdometerErrors(scale_factor=2e-3, white=0.02)
    n = 200_000
    meas = OdometerErrorModel(e, period, seed=1).apply(np.full(n, 10.0))
    assert abs(meas.mean() - 10.02) < 4 * 0.02 / math.sqrt(n)
    assert abs(meas.std() / 0.02 - 1) < 4 / math.sqrt(2 * n)
    full = OdometerErrors(scale_factor_sigma=1e-3, white=0.01, pulses_per_m=100.0)
    whole = OdometerErrorModel(full, period, seed=5).apply(speed)
    m = OdometerErrorModel(full, period, seed=5)
    parts = np.concatenate([m.apply(speed[a:b]) for a, b in ((0, 1), (1, 9), (9, 50_000))])
    assert np.array_equal(parts, whole)
    assert full.variance(period) == 0.01**2 + (0.01 / period) ** 2 / 6


def test_odometer_quantization_error_is_a_difference_of_residuals():
    """Without noise the speed's error is ``(ρ_{k−1} − ρ_k) / P`` with ρ uniform over a pulse:
    variance (q/P)²/6 (what the published covariance adds) and successive errors correlated
    −½ (the aided filter's two residual states), 4 standard errors. The residuals are
    independent when the distance rolled per epoch varies by pulses from epoch to epoch (here
    a speed drawn per epoch over 1 m/s: 4.8 pulses); at a steady speed they follow each other
    (ρ_k = ρ_{k−1} + uP mod q) and the variance is α(1 − α)(q/P)², α = frac(uP/q)."""
    period, q = 0.1, 1 / 48.0
    n = 100_000
    speed = 13.0 + np.random.default_rng(9).uniform(0.0, 1.0, n)
    e = OdometerErrors(pulses_per_m=48.0)
    err = OdometerErrorModel(e, period, seed=0).apply(speed) - speed
    var = (q / period) ** 2 / 6
    assert e.quantization_variance(period) == var
    assert abs(err.var() / var - 1) < 4 * math.sqrt(2 / n)
    lag1 = np.mean(err[1:] * err[:-1]) / err.var()
    assert abs(lag1 + 0.5) < 4 / math.sqrt(n), lag1
    assert abs(np.mean(err[2:] * err[:-2]) / err.var()) < 4 / math.sqrt(n)  # none beyond


def test_odometer_counts_nothing_at_rest():
    """An encoder counts the wheel's rotation: at rest (after driving, residual carried)
    exactly zero speed whatever the scale factor and noise; rolling slower than σ_w the noise
    σ is the speed itself (slip cannot exceed the rolling), from σ_w up the full σ_w."""
    period = 0.02
    e = OdometerErrors(scale_factor=3e-3, scale_factor_sigma=5e-3, white=0.02, pulses_per_m=48)
    speed = np.concatenate([np.linspace(0.0, 8.0, 500), np.full(500, 8.0),
                            np.linspace(8.0, 0.0, 500), np.zeros(2000)])  # fmt: skip
    out = OdometerErrorModel(e, period, seed=4).apply(speed)
    assert np.all(out[1500:] == 0.0)
    assert np.any(out[:1500] != 0.0)  # not vacuous: it counts while rolling
    n = 200_000
    for u, sigma in ((0.005, 0.005), (0.05, 0.02)):
        meas = OdometerErrorModel(OdometerErrors(white=0.02), period, seed=2).apply(
            np.full(n, u)
        )
        assert abs(meas.std() / sigma - 1) < 4 / math.sqrt(2 * n), (u, meas.std())
