"""Truth for the navigator: Odometry truth rows in navigation terms, the rows kept to (re)start
runs, and the initial state from truth or from the scenario (with the spec's initial errors).
Conventions: docs/navigator.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.config import Initial
from strapdown_ros.config.navigator import NavigatorSpec
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.navigation import NavState
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    euler_from_dcm,
    quat_from_dcm,
)
from strapdown_ros.messages import EarthState

#: Truth messages kept for (re)starting runs.
TRUTH_KEEP = 4096


@dataclass(frozen=True)
class TruthRows:
    """Truth rows in navigation terms (from Odometry messages): ECEF position (m), geodetic
    latitude, longitude (rad), altitude (m), NED velocity (m/s), ``C_B^N``, body rate relative
    to the Earth (rad/s, FRD)."""

    r_e: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    c_b_n: F64
    omega_eb_b: F64


def truth_rows(state: EarthState) -> TruthRows:
    lat, lon, alt = ecef_to_geodetic(state.r_e)
    c_e_n = dcm_ecef_to_ned(lat, lon)
    return TruthRows(
        state.r_e,
        lat,
        lon,
        alt,
        np.einsum("nij,nj->ni", c_e_n, state.v_e),
        c_e_n @ state.c_b_e,
        state.omega_eb_b,
    )


def state_rows(state: EarthState, rows: slice | NDArray[np.intp]) -> EarthState:
    return EarthState(*(np.asarray(a)[rows] for a in state))


def initial_state_from_truth(
    truth: EarthState, row: int, spec: NavigatorSpec, t: float = 0.0
) -> NavState:
    """The initial state from truth row ``row`` plus the spec's initial errors.

    Position error: NED metres in the true local level, applied in ECEF; velocity error: NED;
    attitude error: offsets of roll, pitch and heading (Euler angles of ``C_B^N``).
    """
    tr = truth_rows(state_rows(truth, slice(row, row + 1)))
    r = tr.r_e[0] + dcm_ned_to_ecef(tr.lat[0], tr.lon[0]) @ spec.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    c = tr.c_b_n[0]
    att = spec.attitude_error_rph
    if np.any(att):
        c = dcm_from_euler(*(np.asarray(euler_from_dcm(c)) + att))
    return NavState(
        float(t), float(lat), float(lon), float(alt),
        tr.v_ned[0] + spec.velocity_error_ned, quat_from_dcm(c),
    )  # fmt: skip


def initial_state_from_scenario(initial: Initial, spec: NavigatorSpec) -> NavState:
    """The initial state from a scenario's ``initial`` (the reference IMU at t0) plus the
    spec's initial errors (see :func:`initial_state_from_truth`)."""
    lat, lon = np.radians(initial.latitude_deg), np.radians(initial.longitude_deg)
    alt = float(initial.altitude_m)
    r = geodetic_to_ecef(lat, lon, alt) + dcm_ned_to_ecef(lat, lon) @ spec.position_error_ned
    lat, lon, alt = ecef_to_geodetic(r)
    rph = np.radians(np.asarray(initial.attitude_rph_deg, dtype=np.float64))
    v = np.asarray(initial.velocity_ned_mps, dtype=np.float64) + spec.velocity_error_ned
    c = dcm_from_euler(*(rph + spec.attitude_error_rph))
    return NavState(0.0, float(lat), float(lon), float(alt), v, quat_from_dcm(c))


class TruthStore:
    """The latest ``keep`` truth rows by stamp (a repeated stamp: the last one received),
    kept as a few arrays and sorted when a run is to start."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self._parts: list[EarthState] = []
        self._rows = 0
        self._sorted = True

    def add(self, state: EarthState) -> None:
        self._parts.append(state)
        self._rows += len(state.stamps_ns)
        self._sorted = False
        if self._rows > 2 * self.keep:
            self.sorted()

    def sorted(self) -> EarthState | None:
        """The rows kept, in stamp order (None if none)."""
        if not self._parts:
            return None
        if not self._sorted:
            parts = self._parts
            cat = EarthState(*(np.concatenate([p[i] for p in parts]) for i in range(5)))
            rev = np.asarray(cat.stamps_ns, dtype=np.int64)[::-1]
            _, first = np.unique(rev, return_index=True)  # last occurrence of each stamp
            rows = (rev.size - 1 - first)[-self.keep :]
            self._parts = [state_rows(cat, rows)]
            self._rows = rows.size
            self._sorted = True
        return self._parts[0]
