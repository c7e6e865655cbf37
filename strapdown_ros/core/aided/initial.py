"""The initial estimate and covariance of the aided filter.

The navigation part of P0 is given as σ per local-level axis (position NED m, velocity NED
m/s, attitude rotation about NED axes rad) at the start, where E0 = ECEF (docs/interface.md §1).
The filter's error coordinates are E0 ones: ``δR = C_N^E δr^N``, ``δV = C_N^E δv^N + ω_ie × δR``
(``V = v^E + ω_ie × r`` at t = 0), ``φ = C_N^E ψ^N``; :func:`initial_covariance` maps
``diag(σ²)`` with that Jacobian J0. A σ of 0 gives the floor variance (the estimate starts at
the truth). The other states start at 0 with their model σ0².

:func:`initial_error` draws ``J0 (σ ⊙ ξ)`` from a seeded generator
(``SeedSequence(seed, spawn_key=(INITIAL_STREAM,))``); :func:`perturbed_state` applies an error
to a true state exactly in the filter's error coordinates, so that over Monte Carlo runs the
initial error is N(0, P0) (NEES consistent from the first epoch).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.aided.model import FilterModel
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import OMEGA_IE, dcm_ned_to_ecef
from strapdown_ros.core.rotations import dcm_from_rotvec

__all__ = [
    "FLOOR_SIGMA",
    "INITIAL_STREAM",
    "initial_covariance",
    "initial_error",
    "initial_jacobian",
    "perturbed_state",
]


#: σ floors (m, m/s, rad) of the navigation part of P0 when the configured σ is 0.
FLOOR_SIGMA = (1e-3, 1e-3, 1e-6)
#: Spawn key of the initial-error draw (the aiding sensors use 1..4).
INITIAL_STREAM = 10


def initial_jacobian(lat: float, lon: float) -> F64:
    """J0 (9, 9): NED errors ``[δr^N, δv^N, ψ^N]`` → E0 errors ``[δR, δV, φ]`` at t = 0."""
    c = dcm_ned_to_ecef(lat, lon)
    w = np.array([[0.0, -OMEGA_IE, 0.0], [OMEGA_IE, 0.0, 0.0], [0.0, 0.0, 0.0]])
    j = np.zeros((9, 9))
    j[0:3, 0:3] = c
    j[3:6, 0:3] = w @ c
    j[3:6, 3:6] = c
    j[6:9, 6:9] = c
    return j


def _sigmas(position: ArrayLike, velocity: ArrayLike, attitude: ArrayLike) -> F64:
    s = np.concatenate([np.broadcast_to(np.asarray(x, dtype=np.float64), 3)
                        for x in (position, velocity, attitude)])  # fmt: skip
    if np.any(s < 0) or not np.all(np.isfinite(s)):
        raise ValueError(f"initial sigmas must be finite and >= 0, got {s}")
    return s


def initial_covariance(model: FilterModel, lat: float, lon: float, position: ArrayLike,
                       velocity: ArrayLike, attitude: ArrayLike) -> F64:  # fmt: skip
    """P0 (n, n): the navigation block from the NED σ (floors for 0) and the model's σ0²."""
    s = _sigmas(position, velocity, attitude)
    floor = np.repeat(FLOOR_SIGMA, 3)
    s = np.where(s > 0, s, floor)
    j = initial_jacobian(lat, lon)
    p0 = np.diag(np.asarray(model.sigma0, dtype=np.float64) ** 2)
    p0[:9, :9] = j @ np.diag(s**2) @ j.T
    return 0.5 * (p0 + p0.T)


def initial_error(seed: int, lat: float, lon: float, position: ArrayLike, velocity: ArrayLike,
                  attitude: ArrayLike) -> F64:  # fmt: skip
    """A draw of the initial navigation error ``[δR, δV, φ]`` (9,) in E0 coordinates."""
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    s = _sigmas(position, velocity, attitude)
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(
        seed, spawn_key=(INITIAL_STREAM,))))  # fmt: skip
    xi = rng.standard_normal(9)
    return initial_jacobian(lat, lon) @ (s * xi)


def perturbed_state(r: F64, v: F64, c: F64, dx: F64) -> tuple[F64, F64, F64]:
    """``(R + δR, V + δV, exp([φ×]) C)``: a true E0 state with the error ``dx`` (9,)."""
    return (np.asarray(r) + dx[0:3], np.asarray(v) + dx[3:6],
            dcm_from_rotvec(dx[6:9]) @ np.asarray(c))  # fmt: skip
