"""The covariance prediction conditioned on a campaign's drawn constants."""

from __future__ import annotations

import numpy as np

from strapdown_ros.analysis import covariance_check as cc
from strapdown_ros.config import load_scenario
from strapdown_ros.core.covariance import STATE_NAMES, initial_moments
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters


def _params(seed: int) -> ImuErrorParameters:
    spec = load_scenario("config/scenarios/default.yaml").imu_errors[0]  # the variation IMU
    p = spec.parameters()
    return ImuErrorParameters(p.gyro, p.accel, seed)


def _index(prefix: str) -> list[int]:
    return [i for i, n in enumerate(STATE_NAMES) if n.startswith(prefix)]


def test_one_run_gives_its_own_drawn_constants():
    """With one seed P0 = d dᵀ: its bias and (S + M) deviations are the model's realized
    constants minus their means (read from ImuErrorModel, not from the draw layout)."""
    params = _params(12345)
    p0 = cc.realized_initial_covariance(params, [params.seed])
    model = ImuErrorModel(params, 0.005)
    for name, triad, bias, matrix in (
        ("gyro", params.gyro, model.gyro_bias, model.gyro_error_matrix),
        ("accel", params.accel, model.accel_bias, model.accel_error_matrix),
    ):
        ib = _index(f"bias_{name}_")
        # rank one: d = P0[:, i] / √P0[i, i], with the sign of the x bias deviation
        ref = ib[0]
        d = p0[:, ref] / np.sqrt(p0[ref, ref]) * np.sign(bias[0] - triad.bias[0])
        np.testing.assert_allclose(d[ib], bias - triad.bias, rtol=1e-12, atol=0)
        mean_matrix = np.diag(triad.scale_factor) + triad.misalignment
        em = matrix - mean_matrix
        np.testing.assert_allclose(d[_index(f"sf_{name}_")], np.diag(em), rtol=1e-12)
        pairs = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
        np.testing.assert_allclose(d[_index(f"mis_{name}_")], [em[i, j] for i, j in pairs],
                                   rtol=1e-12)  # fmt: skip


def test_many_runs_tend_to_the_population_and_other_states_are_kept():
    """Over 4000 seeds the drawn constants' second moment is the population variance within
    its sampling spread (5 √(2/N) ≈ 11 %); the navigation, random-walk and g-sensitivity
    states keep the population's moments."""
    params = _params(0)
    p0 = cc.realized_initial_covariance(params, list(range(4000)))
    _, pop = initial_moments(params)
    drawn = [i for i, n in enumerate(STATE_NAMES) if n.startswith(("bias_", "sf_", "mis_", "gm_"))]
    np.testing.assert_allclose(np.diag(p0)[drawn], np.diag(pop)[drawn], rtol=0.11)
    other = np.setdiff1d(np.arange(len(STATE_NAMES)), drawn)
    np.testing.assert_array_equal(p0[np.ix_(other, other)], pop[np.ix_(other, other)])
    corr = p0[np.ix_(drawn, drawn)] / np.sqrt(np.outer(np.diag(p0)[drawn], np.diag(p0)[drawn]))
    assert np.max(np.abs(corr - np.eye(len(drawn)))) < 0.08  # 5/√4000
