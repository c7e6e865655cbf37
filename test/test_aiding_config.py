"""The ``aiding`` section model (strapdown_ros.config.aiding): defaults, presets, errors by key,
cross-checks against the scenario's time grid."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.config import Recording, ScenarioError
from strapdown_ros.config.aiding import (
    AIDING_TOPICS,
    GNSS_PRESETS,
    AidingSpec,
    check_aiding,
    decimal_year,
)
from strapdown_ros.config.base import validate_section


def _spec(doc) -> AidingSpec:
    return validate_section(AidingSpec, doc, "aiding")  # type: ignore[return-value]


def test_defaults_are_error_free():
    spec = _spec({"gnss": {}, "barometer": {}, "magnetometer": {}, "wheel_odometer": {}})
    assert (spec.gnss.rate_hz, spec.barometer.rate_hz) == (1.0, 25.0)
    assert (spec.magnetometer.rate_hz, spec.wheel_odometer.rate_hz) == (50.0, 50.0)
    e = spec.gnss.errors()
    assert not np.any(e.position_variance) and not np.any(e.velocity_variance)
    assert spec.barometer.errors().variance == 0.0
    assert np.array_equal(spec.magnetometer.errors().soft_iron, np.eye(3))
    assert spec.wheel_odometer.errors().variance(0.02) == 0.0
    assert spec.topics() == list(AIDING_TOPICS.values())
    assert spec.gnss.status_code == 0 and spec.gnss.service_code == 1
    assert _spec({"gnss": {"enabled": False}, "barometer": {}}).topics() == ["/baro/pressure"]


def test_presets_and_overrides():
    spec = _spec({"gnss": {"preset": "rtk", "position_white_m": 0.002, "constellations":
                           ["gps", "galileo", "glonass"]}})  # fmt: skip
    e = spec.gnss.errors()
    assert np.array_equal(e.position_white, [0.002] * 3)
    assert np.array_equal(e.position_gm_sigma, GNSS_PRESETS["rtk"]["position_gm_sigma_m"])
    assert spec.gnss.status_code == 2 and spec.gnss.service_code == 1 + 8 + 2
    assert _spec({"gnss": {"preset": "sbas", "status": "fix"}}).gnss.status_code == 0
    baro = _spec({"barometer": {"preset": "mems", "quantum_pa": 0.0}}).barometer.errors()
    assert baro.quantum == 0.0 and baro.white == 3.0
    mag = _spec({"magnetometer": {"preset": "fluxgate", "hard_iron_ut": [1, 2, 3]}}).magnetometer
    assert np.allclose(mag.errors().hard_iron, [1e-6, 2e-6, 3e-6])
    wheel = _spec({"wheel_odometer": {"preset": "encoder", "scale_factor_ppm": 500}})
    assert wheel.wheel_odometer.errors().scale_factor == 5e-4


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"gnss": {"rate_hz": 0}}, "aiding.gnss.rate_hz: must be > 0"),
        ({"gnss": {"rate_hz": 3}}, "aiding.gnss.rate_hz: the period"),
        ({"gnss": {"lever": [0, 0, 0]}}, "aiding.gnss.lever: unknown key"),
        ({"gnss": {"preset": "ppp"}}, "aiding.gnss.preset: must be one of"),
        ({"gnss": {"position_white_m": [1, 2]}}, "aiding.gnss.position_white_m: must be a number"),
        ({"gnss": {"position_white_m": -1}}, "aiding.gnss.position_white_m: must be >= 0"),
        ({"gnss": {"position_gm_sigma_m": 1}}, "aiding.gnss.position_gm_tau_s: is required"),
        ({"gnss": {"outages": [[5, 3]]}}, "aiding.gnss.outages[0]: [start_s, end_s] needs"),
        ({"gnss": {"outages": [5]}}, "aiding.gnss.outages[0]: must be a window"),
        ({"gnss": {"latency_s": -0.1}}, "aiding.gnss.latency_s: must be >= 0"),
        ({"gnss": {"seed": 1.5}}, "aiding.gnss.seed: must be an integer"),
        ({"gnss": {"enabled": "yes"}}, "aiding.gnss.enabled: must be true or false"),
        ({"barometer": {"drift_sigma_pa": 5}}, "aiding.barometer.drift_correlation_time_s: is"),
        ({"barometer": {"noise_sigma_pa": float("nan")}}, "aiding.barometer.noise_sigma_pa"),
        ({"magnetometer": {"soft_iron": [1, 2, 3]}}, "aiding.magnetometer.soft_iron: must be a"),
        ({"magnetometer": {"decimal_year": 2040}}, "aiding.magnetometer.decimal_year: must be <="),
        ({"wheel_odometer": {"nhc_sigma_mps": 0}}, "aiding.wheel_odometer.nhc_sigma_mps: must"),
        ({"radar": {}}, "aiding.radar: unknown key"),
    ],
)
def test_bad_values_name_the_key(doc, message):
    with pytest.raises(ScenarioError) as err:
        _spec(doc)
    assert str(err.value).startswith(message), str(err.value)


def _check(doc, rate_hz=200.0, start_time_s=1767225600.0, topics=None):
    rec = Recording() if topics is None else Recording(topics=topics)
    check_aiding(
        _spec(doc),
        period_ns=int(round(1e9 / rate_hz)),
        start_time_s=start_time_s,
        start_time_ns=int(round(start_time_s * 1e9)),
        topics=rec.topics,
    )


def test_cross_checks():
    _check({"gnss": {"rate_hz": 10}, "magnetometer": {}})
    with pytest.raises(ScenarioError, match=r"^aiding.barometer.rate_hz: the epoch period"):
        _check({"barometer": {"rate_hz": 16}}, rate_hz=40)  # 62.5 ms vs T = 25 ms
    with pytest.raises(ScenarioError, match=r"^aiding.gnss.rate_hz: start_time_s"):
        _check({"gnss": {}}, start_time_s=1767225600.0025)
    with pytest.raises(ScenarioError, match=r"^aiding.gnss.rate_hz: GNSS epochs are whole"):
        _check({"gnss": {"rate_hz": 0.4}})  # 2.5 s
    with pytest.raises(ScenarioError, match=r"^aiding.magnetometer.decimal_year: start_time_s"):
        _check({"magnetometer": {}}, start_time_s=4.0e9)
    _check({"magnetometer": {"decimal_year": 2020.0}}, start_time_s=4.0e9)
    _check({"gnss": {"enabled": False, "rate_hz": 0.4}})  # disabled: unchecked


def test_decimal_year():
    assert decimal_year(1767225600 * 10**9) == 2026.0
    assert decimal_year(0) == 1970.0
    assert abs(decimal_year((1767225600 + 365 * 86400 // 2) * 10**9) - 2026.5) < 1e-12
