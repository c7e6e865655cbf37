"""Work split over threads gives the same bits as one thread, and the same errors.

``core/threads.rowwise`` (the long-double geodetic conversion of long sample arrays), the
samples trajectory's two independent fits, and ``generate_reference``'s chunks on two threads
(docs/benchmarks.md): each is compared bit for bit with the one-thread computation here.
"""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.config import parse_scenario
from strapdown_ros.core import earth, threads
from strapdown_ros.core.trajectory import TrajectoryError
from strapdown_ros.core.trajectory.samples import (
    FitOptions,
    SamplesTrajectory,
    samples_from_arrays,
)
from strapdown_ros.stages.trajectory import generate_reference

N = threads.MIN_ROWS + 1001  # long enough to be split


def _geodetic(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    return rng.uniform(-1.57, 1.57, n), rng.uniform(-3.14, 3.14, n), rng.uniform(-400, 9e4, n)


def test_rowwise_geodetic_equals_one_thread() -> None:
    lat, lon, alt = _geodetic(N)
    split = earth.geodetic_to_ecef(lat, lon, alt)
    one = earth._geodetic_to_ecef(lat, lon, alt)
    assert threads.WORKERS < 2 or threads.MIN_ROWS <= N
    assert split.dtype == one.dtype and np.array_equal(split, one)
    # and a short array, computed in one call, is a prefix of the long one's rows
    assert np.array_equal(earth.geodetic_to_ecef(lat[:10], lon[:10], alt[:10]), one[:10])


def _samples(n: int, gap: bool = False):
    t = np.arange(n) * 0.01
    if gap:  # a hole far wider than the knot spacing: both fits are under-determined there
        t[n // 2 :] += 50.0
    lat = 0.6 + 1e-7 * t
    lon = 0.2 + 2e-7 * t
    return samples_from_arrays(
        t,
        lat=lat,
        lon=lon,
        alt=100.0 + 0.1 * np.sin(0.1 * t),
        v_ned=np.column_stack([0.6 + 0 * t, 0.9 + 0 * t, -0.01 * np.cos(0.1 * t)]),
        roll=0.01 * np.sin(0.3 * t),
        pitch=0.02 * np.cos(0.2 * t),
        heading=0.5 + 0.001 * t,
    )


def test_samples_fits_on_two_threads_equal_one(monkeypatch: pytest.MonkeyPatch) -> None:
    samples = _samples(N)
    two = SamplesTrajectory(samples, FitOptions())
    monkeypatch.setattr("strapdown_ros.core.trajectory.samples.WORKERS", 1)
    one = SamplesTrajectory(samples, FitOptions())
    t = np.linspace(0.0, two.duration, 5001)
    a, b = two.truth_e0(t), one.truth_e0(t)
    for name in ("c_b_e0", "v_e0", "r_e0"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_position_error_first_on_two_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    samples = _samples(N, gap=True)
    with pytest.raises(TrajectoryError) as two:
        SamplesTrajectory(samples, FitOptions())
    monkeypatch.setattr("strapdown_ros.core.trajectory.samples.WORKERS", 1)
    with pytest.raises(TrajectoryError) as one:
        SamplesTrajectory(samples, FitOptions())
    assert str(two.value) == str(one.value)
    assert "position" in str(two.value)


def test_reference_chunks_on_two_threads_equal_one() -> None:
    scenario = parse_scenario(
        {
            "name": "threads",
            "rate_hz": 200,
            "duration_s": 230.0,
            "initial": {"latitude_deg": 48.1, "longitude_deg": 11.6, "altitude_m": 520.0},
            "trajectory": {
                "kind": "segments",
                "segments": [
                    {"duration_s": 100, "accel_mps2": 0.5, "heading_rate_dps": 3},
                    {"duration_s": 130, "heading_rate_dps": -2, "roll_rate_dps": 0.5},
                ],
            },
        }
    )
    a = generate_reference(scenario, workers=2)
    b = generate_reference(scenario, workers=1)
    assert a.cycles == b.cycles == 46_000
    for name in ("dalpha", "dv", "c_b_e0", "v_e0", "r_e0"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
