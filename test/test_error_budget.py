"""Error budget per IMU error source (analysis/error_budget.py): the single-source variances
add up to the all-sources run's, and an accelerometer bias alone matches the Schuler–Foucault
closed form of analysis/closed_forms.py (a navigator at rest, level, north-facing)."""

from dataclasses import replace

import numpy as np
from test_covariance import ALT, DAMP, LAT, one_source, static_steps

from strapdown_ros.analysis.closed_forms import StaticSite, static_errors
from strapdown_ros.analysis.covariance_check import ScenarioModel
from strapdown_ros.analysis.error_budget import budget_table, error_budget, source_alone
from strapdown_ros.config.imu_errors import ImuErrorsSpec


def test_single_source_variances_add_to_the_all_sources_run():
    """The industrial preset with rate random walks added, 600 s at rest in 1-s steps: every
    random source is run, Σ variances = the all-sources variance within 1e-12 (measured
    2.4e-14); the one fixed term (the gyros' g-sensitivity) gives the all-sources mean."""
    params = ImuErrorsSpec(preset="industrial").parameters()
    gyro = replace(params.gyro, random_walk=np.full(3, 1e-8))
    accel = replace(params.accel, random_walk=np.full(3, 1e-6))
    params = replace(params, gyro=gyro, accel=accel)
    budget = error_budget(ScenarioModel(0, static_steps(600.0, 1.0), params, "j2", DAMP))
    assert len(budget.random) == 12  # every random source of both triads
    np.testing.assert_allclose(budget.total_sum, budget.total, rtol=1e-12)
    assert list(budget.fixed) == ["gyro g-sensitivity"]
    np.testing.assert_allclose(budget.fixed["gyro g-sensitivity"], budget.mean_total, rtol=1e-12)
    assert "√(Σ variances)" in budget_table(budget)


def test_source_alone_keeps_one_field():
    params = ImuErrorsSpec(preset="industrial").parameters()
    alone = source_alone(params, "accel", "white")
    np.testing.assert_array_equal(alone.accel.white, params.accel.white)
    np.testing.assert_array_equal(alone.gyro.correlation_time_s, params.gyro.correlation_time_s)
    for triad, field in (("gyro", "white"), ("gyro", "turn_on_bias_sigma"),
                         ("accel", "bias_instability"), ("gyro", "g_sensitivity")):  # fmt: skip
        assert not np.any(getattr(getattr(alone, triad), field))


def test_accelerometer_bias_alone_against_the_closed_form():
    """A turn-on bias σ = 1 mg on the north and east accelerometers (with other sources beside
    it, zeroed by the budget), half a Schuler period (2532 s) in 5-s steps: its final σ of
    horizontal position, velocity and tilt equal the root sum of squares of the closed-form
    responses to a bias of σ on each axis, within 1 % of their peak (measured 3.9e-5)."""
    sigma = 9.80665e-3 * np.array([1.0, 1.0, 0.0])
    params = one_source(gyro={"white": np.full(3, 1e-5)},
                        accel={"turn_on_bias_sigma": sigma, "white": np.full(3, 1e-3)})
    steps = static_steps(2532.0, 5.0)
    budget = error_budget(ScenarioModel(0, steps, params, "j2", DAMP))
    var = budget.random["accel turn-on bias"]
    site = StaticSite(LAT, ALT)
    resp = [static_errors(steps.t, site, accel_ned=sigma[i] * np.eye(3)[i]) for i in (0, 1)]
    for q, attr in ((0, "position_ned"), (2, "velocity_ned"), (4, "phi_ned")):
        series = np.sqrt(sum(np.sum(getattr(r, attr)[:, :2] ** 2, axis=1) for r in resp))
        scale = 1e3 if q == 4 else 1.0
        assert abs(np.sqrt(var[q]) - scale * series[-1]) < 0.01 * scale * series.max(), (q, var)
