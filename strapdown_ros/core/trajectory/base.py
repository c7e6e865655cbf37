"""Common types of the trajectory models: truth in local-level terms and in the inertial E0 frame.

Conventions: times ``t`` are seconds since the stream start t0 (cycle m = 0); geodetic
latitude/longitude in rad, ellipsoidal altitude in m (WGS-84); velocity relative to the Earth
in NED (m/s); attitude ``C_B^N`` of the body FRD frame relative to NED. E0 is the inertial frame
equal to ECEF at t0 (docs/interface.md §1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    dcm_ned_to_ecef,
    ecef_state_to_e0,
    geodetic_to_ecef,
)


class TrajectoryError(ValueError):
    """Invalid or impossible trajectory inputs; ``where`` names the culprit argument.

    ``where`` is a path into the inputs of the model that raised it, names and list indices,
    e.g. ``("segments", 2, "accel_mps2")`` (segment 2's along-track acceleration) or
    ``("position", "knots")`` (the knots of the position spline); ``problem`` says what is
    wrong. ``str(exc)`` is ``"segments[2].accel_mps2: <problem>"``. Callers that build a model
    from a scenario map ``where`` to the scenario key.
    """

    def __init__(self, where: tuple[str | int, ...], problem: str) -> None:
        self.where = tuple(where)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}" if self.where else problem)

    @property
    def path(self) -> str:
        """``where`` written like a key: ``segments[2].accel_mps2``."""
        out = ""
        for part in self.where:
            out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
        return out

    def under(self, *prefix: str | int) -> TrajectoryError:
        """The same problem with ``prefix`` put before ``where``."""
        return TrajectoryError((*prefix, *self.where), self.problem)

    def __reduce__(self) -> tuple[type, tuple[tuple[str | int, ...], str]]:  # picklable
        return (type(self), (self.where, self.problem))


@dataclass(frozen=True)
class LocalTruth:
    """Truth samples in navigation terms.

    Attributes
    ----------
    t : array (N,)
        Time since t0 (s).
    lat, lon, alt : arrays (N,)
        Geodetic latitude, longitude (rad) and ellipsoidal altitude (m), WGS-84.
    v_ned : array (N, 3)
        Velocity relative to the Earth, NED axes (m/s).
    c_b_n : array (N, 3, 3)
        Attitude ``C_B^N``, body FRD to NED.
    """

    t: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    c_b_n: F64


@dataclass(frozen=True)
class TruthE0:
    """Truth samples in the inertial E0 frame (the form Savage 2020 eqs. (2)-(31) use).

    Attributes
    ----------
    t : array (N,)
        Time since t0 (s).
    c_b_e0 : array (N, 3, 3)
        ``C_B^E0``, body FRD to E0.
    v_e0 : array (N, 3)
        Inertial velocity ``dR^E0/dt`` (m/s, E0 axes).
    r_e0 : array (N, 3)
        Position ``R^E0`` (m).
    """

    t: F64
    c_b_e0: F64
    v_e0: F64
    r_e0: F64


class Trajectory(Protocol):
    """A continuous truth model that can be sampled at arbitrary times in ``[0, duration]``."""

    @property
    def duration(self) -> float:
        """Length of the trajectory (s)."""
        ...

    def local_truth(self, t: F64) -> LocalTruth:
        """Truth at times ``t`` (s since t0) in navigation terms."""
        ...


def local_to_e0(truth: LocalTruth) -> TruthE0:
    """Convert navigation-terms truth to E0 (docs/interface.md §1: ``C_E^E0(t) = Rz(ω_ie t)``).

    ``R^E = ecef(lat, lon, alt)``, ``v^E = C_N^E v^N``, ``C_B^E = C_N^E C_B^N``, then
    ``R^E0 = C_E^E0 R^E``, ``V^E0 = C_E^E0 (v^E + ω_ie × R^E)``, ``C_B^E0 = C_E^E0 C_B^E``
    (Savage 2020 Appendix E role: reference data conversion to E0).
    """
    c_n_e = dcm_ned_to_ecef(truth.lat, truth.lon)
    r_e = geodetic_to_ecef(truth.lat, truth.lon, truth.alt)
    v_e = np.einsum("...ij,...j->...i", c_n_e, truth.v_ned)
    r_e0, v_e0, c_b_e0 = ecef_state_to_e0(truth.t, r_e, v_e, c_n_e @ truth.c_b_n)
    return TruthE0(t=np.asarray(truth.t, dtype=np.float64), c_b_e0=c_b_e0, v_e0=v_e0, r_e0=r_e0)
