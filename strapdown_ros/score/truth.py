"""Truth at any stamp: the scenario's trajectory model, tied to the published truth samples.

The published truth (``/reference/odom``, docs/interface.md §4) is the trajectory model
regenerated through Savage 2020 Method 2: at even cycles it equals the model to rounding, at odd
cycles it is Method 2's integrated state (measured on a 20 s car drive: up to 6e-5 m/s and
3e-9 m from the model), the one the increments obey exactly (§3). The scorer's truth is

* at a truth stamp: the published sample itself (bit for bit); the body rate (for lever arms)
  is the model's instantaneous one, the published ``twist.angular`` being a cycle's mean;
* between truth stamps: the model at the stamp, ``x(t) = x_model(t) + δ(t)``, where
  ``δ = x_published − x_model`` at the two neighbouring truth stamps is interpolated linearly
  (position and velocity in ECEF, the attitude as a rotation vector in ECEF axes). The shape
  between samples comes from the exact trajectory, not from the samples;
* without a model (``increments`` trajectories, or no scenario given): cubic Hermite on the
  published position and velocity in E0 and constant-rate attitude between samples (error
  O(T⁴ ⃛v) in position; flagged in the score).

Frames: ECEF (``earth``) positions and velocities relative to the Earth; attitude ``C_B^E`` of
the body FRD; body rates ``ω_eb^B`` (FRD). Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    e0_state_to_ecef,
    ecef_state_to_e0,
    ecef_to_geodetic,
    geodetic_to_ecef,
)
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm
from strapdown_ros.core.trajectory.base import Trajectory

__all__ = ["PointTruth", "ReferenceTruth", "TruthRangeError"]


#: Step (s) of the central difference that gives the model's body rate ``ω_eb^B``.
RATE_STEP_S = 1e-4


class TruthRangeError(ValueError):
    """Stamps outside the published truth."""


@dataclass(frozen=True)
class PointTruth:
    """Truth of a point (and frame) at K stamps.

    ``r_e`` (K, 3) ECEF m; ``v_e`` (K, 3) m/s relative to the Earth, ECEF axes; ``c_b_e``
    (K, 3, 3) the frame (FRD) to ECEF; ``omega_eb_b`` (K, 3) rad/s, the frame's axes.
    """

    stamps_ns: I64
    r_e: F64
    v_e: F64
    c_b_e: F64
    omega_eb_b: F64

    @property
    def geodetic(self) -> tuple[F64, F64, F64]:
        """Latitude, longitude (rad), ellipsoidal altitude (m) of ``r_e``."""
        return ecef_to_geodetic(self.r_e)

    def ned(self) -> tuple[F64, F64]:
        """``(v_ned, c_b_n)``: velocity and attitude in the NED frame of the true position."""
        lat, lon, _ = self.geodetic
        c_e_n = dcm_ecef_to_ned(lat, lon)
        return np.einsum("nij,nj->ni", c_e_n, self.v_e), c_e_n @ self.c_b_e

    def at_lever_arm(self, lever_frd: F64, c_p_b: F64 | None = None) -> PointTruth:
        """The truth of a point at ``lever_frd`` (m, this frame's FRD axes) with a frame
        ``C_P^B`` (default: the same axes): ``r_p = r + C_B^E l``, ``v_p = v + C_B^E (ω_eb^B ×
        l)``, ``C_P^E = C_B^E C_P^B``, ``ω_eb^P = C_B^P ω_eb^B``."""
        lever = np.asarray(lever_frd, dtype=np.float64)
        c_p_b = np.eye(3) if c_p_b is None else np.asarray(c_p_b, dtype=np.float64)
        arm = np.einsum("nij,j->ni", self.c_b_e, lever)
        spin = np.einsum("nij,nj->ni", self.c_b_e, np.cross(self.omega_eb_b, lever))
        return PointTruth(
            self.stamps_ns, self.r_e + arm, self.v_e + spin, self.c_b_e @ c_p_b,
            self.omega_eb_b @ c_p_b,
        )  # fmt: skip


def model_state(trajectory: Trajectory, t: F64) -> tuple[F64, F64, F64, F64]:
    """``(r_e, v_e, c_b_e, ω_eb^B)`` of the trajectory model at ``t`` (s since t0); the rate
    by a central difference of the attitude over ±:data:`RATE_STEP_S` (truncation error
    2e-9 rad/s in the 1 s heading-rate ramps of a car, measured against steps 1e-5 ... 3e-4 s;
    rounding about as much)."""
    t = np.asarray(t, dtype=np.float64)
    h = RATE_STEP_S
    lo = np.clip(t - h, 0.0, trajectory.duration)
    hi = np.clip(t + h, 0.0, trajectory.duration)
    lt = trajectory.local_truth(np.concatenate([t, lo, hi]))
    c_n_e = dcm_ned_to_ecef(lt.lat, lt.lon)
    c_all = c_n_e @ lt.c_b_n
    k = t.shape[0]
    r = geodetic_to_ecef(lt.lat[:k], lt.lon[:k], lt.alt[:k])
    v = np.einsum("nij,nj->ni", c_n_e[:k], lt.v_ned[:k])
    c_lo, c_hi = c_all[k : 2 * k], c_all[2 * k :]
    omega = rotvec_from_dcm(np.swapaxes(c_lo, -1, -2) @ c_hi) / (hi - lo)[:, None]
    return r, v, c_all[:k], omega


class ReferenceTruth:
    """The published truth samples of one stream and, if given, its trajectory model.

    Parameters
    ----------
    stamps_ns : (M+1,) int
        Truth stamps, uniformly spaced from the stream's t0.
    r_e, v_e, c_b_e, omega_eb_b :
        Published truth (ECEF, FRD), :class:`~strapdown_ros.messages.EarthState` fields.
    trajectory : Trajectory or None
        The scenario's model (``Plan.trajectory``), times in s since ``t0_ns``.
    t0_ns : int
        The model's t0 (the scenario's ``start_time``); default the first stamp.
    """

    def __init__(
        self,
        stamps_ns: I64,
        r_e: F64,
        v_e: F64,
        c_b_e: F64,
        omega_eb_b: F64,
        trajectory: Trajectory | None = None,
        t0_ns: int | None = None,
    ) -> None:
        self.stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
        if self.stamps_ns.shape[0] < 2:
            raise ValueError("truth: need at least 2 samples")
        d = np.diff(self.stamps_ns)
        if not np.all(d == d[0]) or d[0] <= 0:
            raise ValueError("truth: stamps are not uniformly spaced")
        self.period_ns = int(d[0])
        self.first_ns = int(self.stamps_ns[0])
        self.t0_ns = self.first_ns if t0_ns is None else int(t0_ns)
        self.r_e, self.v_e, self.c_b_e, self.omega_eb_b = r_e, v_e, c_b_e, omega_eb_b
        self.trajectory = trajectory
        self._delta: tuple[F64, F64, F64] | None = None

    @property
    def last_ns(self) -> int:
        return int(self.stamps_ns[-1])

    @property
    def exact_between_samples(self) -> bool:
        """True when the trajectory model fills the gaps between samples."""
        return self.trajectory is not None

    def _seconds(self, stamps_ns: I64) -> F64:
        return (np.asarray(stamps_ns, dtype=np.int64) - self.t0_ns) * 1e-9

    def deltas(self) -> tuple[F64, F64, F64]:
        """Published minus model at every truth stamp: ``δr``, ``δv`` (ECEF) and ``δθ``
        (rotation vector of ``C_pub C_modelᵀ``, ECEF axes)."""
        if self._delta is None:
            assert self.trajectory is not None
            r, v, c, _ = model_state(self.trajectory, self._seconds(self.stamps_ns))
            dth = rotvec_from_dcm(self.c_b_e @ np.swapaxes(c, -1, -2))
            self._delta = (self.r_e - r, self.v_e - v, dth)
        return self._delta

    def at(self, stamps_ns: I64, shift_s: float = 0.0) -> PointTruth:
        """Truth at ``stamps_ns − shift_s`` (shift in s, for the time-offset fit).

        Raises
        ------
        TruthRangeError
            A stamp outside ``[first, last]`` truth stamp.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        rel = stamps - self.first_ns
        t_ns = rel - shift_s * 1e9  # float ns since the first sample
        span = self.last_ns - self.first_ns
        if t_ns.size and (t_ns.min() < 0 or t_ns.max() > span):
            raise TruthRangeError(
                f"stamps outside the truth ({self.first_ns} .. {self.last_ns} ns)"
            )
        k = np.minimum(np.floor(t_ns / self.period_ns).astype(np.int64), self.r_e.shape[0] - 2)
        frac = t_ns / self.period_ns - k
        on_grid = (rel % self.period_ns == 0) & (shift_s == 0.0)
        k_grid = rel // self.period_ns
        if self.trajectory is not None:
            r, v, c, w = self._model_between(k, frac, (t_ns * 1e-9) + (self.first_ns - self.t0_ns)
                                             * 1e-9)  # fmt: skip
        else:
            r, v, c, w = self._hermite(k, frac)
        if np.any(on_grid):
            g, kg = on_grid, k_grid[on_grid]
            r[g], v[g], c[g] = self.r_e[kg], self.v_e[kg], self.c_b_e[kg]
            if self.trajectory is None:  # the published rate: the mean of the cycle ending here
                w[g] = self.omega_eb_b[kg]
        return PointTruth(stamps, r, v, c, w)

    def _model_between(self, k: I64, frac: F64, t: F64) -> tuple[F64, F64, F64, F64]:
        assert self.trajectory is not None
        dr, dv, dth = self.deltas()
        r, v, c, w = model_state(self.trajectory, t)
        a, b = (1.0 - frac)[:, None], frac[:, None]
        r = r + a * dr[k] + b * dr[k + 1]
        v = v + a * dv[k] + b * dv[k + 1]
        c = dcm_from_rotvec(a * dth[k] + b * dth[k + 1]) @ c
        return r, v, c, w

    def _hermite(self, k: I64, frac: F64) -> tuple[F64, F64, F64, F64]:
        """Cubic Hermite position/velocity in E0, constant-rate attitude (no model)."""
        T = self.period_ns * 1e-9
        t_s = self._seconds(self.stamps_ns)
        r0, v0, c0 = ecef_state_to_e0(t_s, self.r_e, self.v_e, self.c_b_e)
        s = frac[:, None]
        p0, p1, m0, m1 = r0[k], r0[k + 1], v0[k] * T, v0[k + 1] * T
        s2, s3 = s**2, s**3
        pos = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * p1 \
            + (s3 - s2) * m1
        vel = ((6 * s2 - 6 * s) * (p0 - p1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1) / T
        assert c0 is not None
        step = rotvec_from_dcm(np.swapaxes(c0[k], -1, -2) @ c0[k + 1])
        c_e0 = c0[k] @ dcm_from_rotvec(s * step)
        t = t_s[k] + frac * T
        r, v, c = e0_state_to_ecef(t, pos, vel, c_e0)
        assert c is not None
        # body rate relative to the Earth: the step's mean inertial rate minus the Earth's
        w_ib = step / T
        w = w_ib - np.einsum("nji,j->ni", c, OMEGA_IE_VEC)
        return r, v, c, w

