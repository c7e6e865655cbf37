"""The transfer-alignment filter: a closed-loop error-state Kalman filter on the slave IMU.

States (error = estimate minus truth, E0 frame; docs/transfer_alignment.md §3): the aided
filter's ``δR, δV, φ`` and gyro/accelerometer biases (the layout of
:func:`strapdown_ros.core.aided.model.build_model`, its IMU white-noise PSDs and bias random
walks, and its Gauss–Markov bias and scale-factor states when the slave's error model has those
terms), then the mounting misalignment ``μ`` (3, Br axes, random constant or random walk) and
optionally the lever-arm error ``δl`` (3, Br FRD, random constant). On a scanning platform the
matching measurements carry the resolver's ``Ĉ_scan`` and the displacement (:class:`Platform`,
docs/transfer_alignment.md §5); μ stays the zero-scan mounting's error.

The inertial part, the error dynamics, the Van Loan discretization and the Joseph update are
the aided filter's own compiled functions (docs/theory/aided_ins.md §4, §6):
:func:`~strapdown_ros.core.navigation._kernels.exact_kernel` (Savage 2020 eqs. (2)–(4), N = 1)
on the bias-corrected increments, :func:`~strapdown_ros.core.aided.dynamics.sparse_dynamics`,
:func:`~strapdown_ros.core.aided.dynamics.van_loan_series`,
:func:`~strapdown_ros.core.aided.dynamics.propagate_covariance` (the mounting and lever-arm
states are decoupled in F: they enter through the measurements only) and
:func:`~strapdown_ros.core.aided.update.joseph_update`. The closed-loop reset injects ``dμ`` as
``M̂ ← exp([dμ×]) M̂`` and transforms P's φ and μ blocks by ``I + ½[d×]`` (Solà 2017,
eq. (287)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.core.aided._fields import gravitation_gradient
from strapdown_ros.core.aided.dynamics import (
    continuous_noise,
    propagate_covariance,
    propagate_estimates,
    sparse_dynamics,
    van_loan_series,
)
from strapdown_ros.core.aided.layout import B_BA, B_BG, B_GMA, B_GMG, B_SFA, B_SFG
from strapdown_ros.core.aided.model import FilterModel
from strapdown_ros.core.aided.update import joseph_update, reset_attitude
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.navigation._kernels import GRAVITY_CODES, exact_kernel
from strapdown_ros.core.rotations import dcm_from_rotvec, skew
from strapdown_ros.core.transfer.measurements import (
    attitude_matching,
    displacement_transport,
    platform_offset,
    velocity_matching,
)

__all__ = ["Platform", "TransferFilter", "TransferLayout", "UpdateResult"]


@dataclass(frozen=True)
class Platform:
    """A scanning platform around a velocity-matching epoch m (docs/transfer_alignment.md §5).

    ``c_prev``, ``c_next``: the master's ``C_Br^E0`` at m−1, m+1 (as for ``D``); ``scan_prev``,
    ``scan_next``: ``Ĉ_scan`` from the resolver at the slave's cycles m−1, m+1; ``displacement``
    ``d`` (m, Bvar FRD, on the platform).
    """

    c_prev: F64
    c_next: F64
    scan_prev: F64
    scan_next: F64
    displacement: F64


@dataclass(frozen=True)
class TransferLayout:
    """The aided model's states, then μ (``i_mu``) and δl (``i_l``, −1: absent)."""

    model: FilterModel
    lever_arm: bool

    @property
    def n_aided(self) -> int:
        """States of the aided layout (navigation and biases)."""
        return self.model.layout.n

    @property
    def i_mu(self) -> int:
        """Index of μ."""
        return self.n_aided

    @property
    def i_l(self) -> int:
        """Index of δl (−1: no lever-arm states)."""
        return self.n_aided + 3 if self.lever_arm else -1

    @property
    def n(self) -> int:
        """All states."""
        return self.n_aided + (6 if self.lever_arm else 3)


@dataclass(frozen=True)
class UpdateResult:
    """One matching update: innovation (3,), NIS, accepted."""

    innovation: F64
    nis: float
    accepted: bool


def _reset_block(p: F64, i: int, d: F64) -> None:
    """``P ← G P Gᵀ`` with ``G = I + ½[d×]`` on the block ``i:i+3`` (after injecting ``d``)."""
    g = np.eye(p.shape[0])
    g[i : i + 3, i : i + 3] += 0.5 * skew(d)
    p[:] = g @ p @ g.T
    p[:] = 0.5 * (p + p.T)


class TransferFilter:
    """The slave INS and its error-state filter.

    Parameters
    ----------
    layout : TransferLayout
    period_ns : int
        IMU period T.
    gravity_model : str
        ``j2`` or ``spherical`` (the scenario's).
    r0, v0 : (3,) arrays
        Initial slave position and inertial velocity (E0, m, m/s).
    c0 : (3, 3) array
        Initial ``Ĉ_s`` (slave body FRD to E0).
    mount0 : (3, 3) array
        Initial mounting estimate ``M̂ = C_Bs^Br``.
    lever0 : (3,) array
        Initial lever-arm estimate (Br FRD, m).
    p0 : (n, n) array
    mounting_q : float
        PSD of the mounting random walk (rad²/s).
    attitude_jacobian : str
        ``measurement``: attitude matching's ``H_μ = −C̃_r`` (the measured master attitude);
        ``estimate``: ``H_μ = −Ĉ_s M̂ᵀ``
        (:func:`~strapdown_ros.core.transfer.measurements.attitude_jacobian_at_estimate`).
    """

    def __init__(self, layout: TransferLayout, period_ns: int, gravity_model: str, r0: F64,
                 v0: F64, c0: F64, mount0: F64, lever0: F64, p0: F64,
                 mounting_q: float = 0.0,
                 attitude_jacobian: str = "measurement") -> None:  # fmt: skip
        self.layout = layout
        n = layout.n
        if p0.shape != (n, n):
            raise ValueError(f"P0 must be ({n}, {n}), got {p0.shape}")
        self.T = period_ns * 1e-9
        self.gmodel = GRAVITY_CODES[gravity_model]
        self.nav = np.zeros(27)
        self.nav[0:3], self.nav[3:6] = r0, v0
        self.nav[6:15] = np.asarray(c0, dtype=np.float64).reshape(9)
        self.est = np.zeros(n)
        self.p = np.array(p0, dtype=np.float64)
        self.mount = np.array(mount0, dtype=np.float64)
        self.lever = np.array(lever0, dtype=np.float64)
        m = layout.model
        self.beta = np.zeros(n)
        self.beta[: layout.n_aided] = m.beta
        self.q = np.zeros(n)
        self.q[: layout.n_aided] = m.q
        self.q[layout.i_mu : layout.i_mu + 3] = mounting_q
        self.ni = m.layout.n_coupled
        self.off = m.layout.offsets
        self.bg = int(self.off[B_BG])
        self.ba = int(self.off[B_BA])
        self.m = 0
        if attitude_jacobian not in ("measurement", "estimate"):
            raise ValueError(f"unknown attitude_jacobian {attitude_jacobian!r}")
        self.jacobian_at_estimate = attitude_jacobian == "estimate"

    def _corrected(self, raw: F64, bias: int, gm: int, sf: int) -> F64:
        """``(Δ̃ − (b̂ + m̂) T) / (1 + ŝ)`` (the aided filter's correction; absent blocks 0)."""
        b = self.est[bias : bias + 3].copy()
        if gm >= 0:
            b = b + self.est[gm : gm + 3]
        x = raw - b * self.T
        if sf >= 0:
            x = x / (1.0 + self.est[sf : sf + 3])
        return np.ascontiguousarray(x)

    # -- propagation ----------------------------------------------------------------------------

    def propagate(self, dalpha: F64, dv: F64) -> None:
        """Integrate the raw increments of the next k cycles (k, 3) and propagate P over them."""
        da = np.asarray(dalpha, dtype=np.float64).reshape(-1, 3)
        dvv = np.asarray(dv, dtype=np.float64).reshape(-1, 3)
        k = len(da)
        if not k:
            return
        T = self.T
        da_c = self._corrected(da, self.bg, self.off[B_GMG], self.off[B_SFG])
        dv_c = self._corrected(dvv, self.ba, self.off[B_GMA], self.off[B_SFA])
        est = self.est
        sr = np.zeros((k + 1, 3))
        sv = np.zeros((k + 1, 3))
        sc = np.zeros((k + 1, 3, 3))
        sr[0], sv[0], sc[0] = self.nav[0:3], self.nav[3:6], self.nav[6:15].reshape(3, 3)
        lo = self.nav[15:21].copy()
        exact_kernel(sr, sv, sc, lo, da_c, dv_c, T, 1, 1, self.gmodel)
        # interval means for F (as the aided loop: Σ C_j, Σ C_j Δv̂_j, Σ Δα̂, Σ Δv̂ over cycles)
        cm = sc[:k].sum(axis=0) / k
        dt = k * T
        fe = np.einsum("kij,kj->i", sc[:k], dv_c) / dt
        wb = da_c.sum(axis=0) / dt
        fb = dv_c.sum(axis=0) / dt
        self.nav[0:3], self.nav[3:6] = sr[k], sv[k]
        self.nav[6:15] = sc[k].reshape(9)
        self.nav[15:21] = lo
        self.nav[21:24], self.nav[24:27] = da[-1], dvv[-1]
        self.m += k
        grad = gravitation_gradient(self.nav[0:3].copy(), self.gmodel)
        rows, cols, vals, nnz = sparse_dynamics(np.ascontiguousarray(cm), fe, wb, fb, grad,
                                                est, self.off, self.beta, self.ni)  # fmt: skip
        qc = continuous_noise(np.ascontiguousarray(cm), self.layout.model.q_ins, self.q, self.ni)
        phi, qd = van_loan_series(rows, cols, vals, nnz, qc, dt)
        propagate_covariance(self.p, phi, qd, self.beta, self.q, dt, self.ni)
        propagate_estimates(self.est, self.beta, dt)

    # -- updates --------------------------------------------------------------------------------

    def _apply(self, nu: F64, h: F64, r: F64, gate: float) -> UpdateResult:
        dx, nis, ok = joseph_update(self.p, np.ascontiguousarray(nu), np.ascontiguousarray(h),
                                    np.ascontiguousarray(r), gate)  # fmt: skip
        if ok:
            self._inject(dx)
        return UpdateResult(np.array(nu, dtype=np.float64), float(nis), bool(ok))

    def _inject(self, dx: F64) -> None:
        nav = self.nav
        for a in range(6):  # compensated sums, as the aided filter's inject
            y = dx[a] + nav[15 + a]
            t = nav[a] + y
            nav[15 + a] = y - (t - nav[a])
            nav[a] = t
        c = nav[6:15].reshape(3, 3)
        nav[6:15] = (dcm_from_rotvec(dx[6:9]) @ c).reshape(9)
        lay = self.layout
        self.est[9 : lay.n_aided] += dx[9 : lay.n_aided]
        dmu = dx[lay.i_mu : lay.i_mu + 3]
        self.mount = dcm_from_rotvec(dmu) @ self.mount
        if lay.i_l >= 0:
            self.lever = self.lever + dx[lay.i_l : lay.i_l + 3]
        reset_attitude(self.p, np.ascontiguousarray(dx[6:9]))
        _reset_block(self.p, lay.i_mu, dmu)

    def update_velocity(self, v_master: F64, d: F64, r: F64, gate: float = np.inf,
                        platform: Platform | None = None) -> UpdateResult:  # fmt: skip
        """Velocity matching: master inertial velocity (E0), ``D`` (3, 3), R (3, 3).

        ``platform``: a scanning platform's displacement carried with the current ``M̂``
        (docs/transfer_alignment.md §5); None: a fixed mount without displacement.
        """
        lay = self.layout
        extra = None
        if platform is not None:
            w_prev = platform_offset(self.mount, platform.scan_prev, platform.displacement)
            w_next = platform_offset(self.mount, platform.scan_next, platform.displacement)
            e, h_mu = displacement_transport(platform.c_prev, platform.c_next, w_prev, w_next,
                                             self.T)  # fmt: skip
            extra = (e, h_mu, lay.i_mu)
        nu, h = velocity_matching(self.nav[3:6], v_master, d, self.lever, lay.n, 3, lay.i_l,
                                  extra)  # fmt: skip
        return self._apply(nu, h, r, gate)

    def update_attitude(self, c_master: F64, r: F64, gate: float = np.inf,
                        scan: F64 | None = None) -> UpdateResult:  # fmt: skip
        """Attitude matching: master ``C_Br^E0``, R (3, 3) of the rotation-vector noise (E0).

        ``scan``: the platform's ``Ĉ_scan`` from the resolver (the nominal ``C_Bs^Br`` is then
        ``M̂ Ĉ_scan``; ``H_μ = −C_r`` holds).
        """
        lay = self.layout
        nominal = self.mount if scan is None else self.mount @ np.asarray(scan)
        nu, h = attitude_matching(self.nav[6:15].reshape(3, 3), c_master, nominal, lay.n, 6,
                                  lay.i_mu, self.jacobian_at_estimate)  # fmt: skip
        return self._apply(nu, h, r, gate)
