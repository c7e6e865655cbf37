"""A navigator run read back from a bag: truth, the navigator's outputs and its published errors.

Everything is read from disk (``strapdown_ros.bag.reader``) and converted with the message
layer's inverse functions (``messages.odometry_state``, ``messages.imu_increments``): ECEF
Odometry → geodetic latitude, longitude, altitude, NED velocity and ``C_B^N`` (body FRD).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag.reader import read_bag
from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic, geodetic_rates
from strapdown_ros.core.trajectory.base import LocalTruth
from strapdown_ros.core.young_nonlinear import FrameTrack
from strapdown_ros.messages import ImuIncrements, imu_increments, odometry_state

__all__ = [
    "LocalLevelStates",
    "NavigatorRecord",
    "local_level_states",
    "read_navigator_record",
]



@dataclass(frozen=True)
class LocalLevelStates(LocalTruth):
    """States in local-level terms (:class:`LocalTruth`, ``t`` in s since the record's start) at
    stamps ``stamps_ns``."""

    stamps_ns: I64

    def track(self) -> FrameTrack:
        """The local-level frame's path (rates ``geodetic_rates`` of the velocity)."""
        lat_rate, lon_rate, _ = geodetic_rates(self.lat, self.alt, self.v_ned)
        return FrameTrack(self.t, self.lat, self.lon, lat_rate, lon_rate)

    def rows(self, index: NDArray[np.intp]) -> LocalLevelStates:
        """The states at rows ``index``."""
        return LocalLevelStates(**{f.name: getattr(self, f.name)[index] for f in fields(self)})


@dataclass(frozen=True)
class NavigatorRecord:
    """A navigator run from a bag.

    Attributes
    ----------
    truth : LocalLevelStates
        Every truth Odometry message from the navigator's first output on.
    navigator : LocalLevelStates
        The navigator's outputs (its Odometry topic).
    theta_actual : array (K, 3)
        The published Young angles (rad) at the navigator's output stamps.
    truth_index : array (K,)
        Row of ``truth`` at each navigator output.
    imu : ImuIncrements or None
        An IMU topic read with the run (e.g. the ideal input of the IMU error model).
    """

    truth: LocalLevelStates
    navigator: LocalLevelStates
    theta_actual: F64
    truth_index: NDArray[np.intp]
    imu: ImuIncrements | None = None

    @property
    def t(self) -> F64:
        """Navigator output times (s since its first output)."""
        return self.navigator.t


def local_level_states(odom: object, t0_ns: int) -> LocalLevelStates:
    """Odometry messages as local-level states, times from ``t0_ns``."""
    state = odometry_state(odom)  # type: ignore[arg-type]
    lat, lon, alt = ecef_to_geodetic(state.r_e)
    c_e_n = dcm_ecef_to_ned(lat, lon)
    stamps_ns = np.asarray(state.stamps_ns, dtype=np.int64)
    return LocalLevelStates(
        t=(stamps_ns - t0_ns) * 1e-9,
        lat=lat,
        lon=lon,
        alt=alt,
        v_ned=np.einsum("nij,nj->ni", c_e_n, state.v_e),
        c_b_n=c_e_n @ state.c_b_e,
        stamps_ns=stamps_ns,
    )


def read_navigator_record(
    bag: str | Path,
    *,
    truth_topic: str = "/reference/odom",
    navigator_topic: str = "/navigator/odom",
    error_topic: str = "/navigator/error/attitude",
    imu_topic: str | None = None,
) -> NavigatorRecord:
    """Read a navigator run (truth, outputs, published attitude error) from bag ``bag``.

    The navigator's output stamps must be truth stamps (the navigator starts at a truth message
    and outputs every N IMU cycles); raises ``ValueError`` otherwise or when the error topic's
    stamps differ from the outputs'.
    """
    topics = [truth_topic, navigator_topic, error_topic] + ([imu_topic] if imu_topic else [])
    contents = read_bag(bag, topics)
    nav_odom = contents[navigator_topic]
    t0 = int(nav_odom.stamps_ns[0])  # type: ignore[attr-defined]
    nav = local_level_states(nav_odom, t0)
    truth_all = local_level_states(contents[truth_topic], t0)
    keep = np.flatnonzero(truth_all.stamps_ns >= t0)
    truth = truth_all.rows(keep)
    index = np.searchsorted(truth.stamps_ns, nav.stamps_ns)
    if np.any(index >= truth.stamps_ns.shape[0]) or not np.array_equal(
        truth.stamps_ns[np.minimum(index, truth.stamps_ns.shape[0] - 1)], nav.stamps_ns
    ):
        raise ValueError(f"{bag}: {navigator_topic} stamps are not {truth_topic} stamps")
    err = contents[error_topic]
    if not np.array_equal(np.asarray(err.stamps_ns), nav.stamps_ns):  # type: ignore[attr-defined]
        raise ValueError(f"{bag}: {error_topic} stamps differ from {navigator_topic}'s")
    imu = None
    if imu_topic:
        imu = imu_increments(contents[imu_topic])  # type: ignore[arg-type]
    theta = np.asarray(err.vector, dtype=np.float64)  # type: ignore[attr-defined]
    return NavigatorRecord(truth, nav, theta, index, imu)
