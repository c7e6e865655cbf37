"""The hot loop of the aided filter (compiled): IMU cycles, covariance steps, measurement updates.

:func:`advance` integrates the nominal state cycle by cycle with the navigator's exact-mode
kernel (:func:`strapdown_ros.core.navigation._kernels.exact_kernel` with N = 1: Savage 2020
eqs. (2)-(4) per increment, gravitation by the trapezoid rule of docs/interface.md §3) on the
increments corrected by the current estimates ``Δα̂ = (Δα̃ - (b̂ + m̂) T) / (1 + ŝ)`` (the same
for Δv), accumulates the interval means that F needs, and at every grid point (a multiple of the
covariance period, of a sensor period or of the output period, on the absolute time axis)
propagates P (:mod:`.dynamics`), stores a checkpoint of the prior state (rollback for delayed
measurements) and applies the measurements of that epoch (:mod:`.update`, canonical order).

It stops at the *prior* of ``m_target``: the updates of the last epoch are applied by the next
call or by :func:`make_posterior`, so a run split into calls at any cycles gives the same bits
as one call.

Arrays (owned by :class:`strapdown_ros.core.aided.engine.AidedFilter`):

``ist`` int64 (4,): current cycle m (since the filter's start), posterior flag, last output
cycle stored, output rows stored. Checkpoint of grid point m in slot
``((k0 + m) // gstep) % len(ck_m)`` (``gstep``: the gcd of the grid periods, so grid points in
the window never share a slot). ``nav`` (27,): R (3), V (3), C_B^E0 row-major (9), Kahan
residuals of R and V (6), raw Δα̃ and Δṽ of the last cycle (6). ``est`` (n,): estimates of
the non-navigation states. ``acc`` (19,): Σ C (9), Σ C Δv̂ (3), Σ Δα̂ (3), Σ Δv̂ (3), cycles (1)
since the last grid point. History rows ``h_*`` sorted by (cycle, kind); ``h_status`` 0 never
applied, 1 applied now for the first time (results in ``h_out``: innovation (3), NIS, dof,
accepted), 2 reported.
"""

from __future__ import annotations

import numpy as np

from strapdown_ros.core.aided._fields import gravitation_gradient
from strapdown_ros.core.aided._jit import jit
from strapdown_ros.core.aided._small import rotation_exp
from strapdown_ros.core.aided.dynamics import (
    continuous_noise,
    propagate_covariance,
    propagate_estimates,
    sparse_dynamics,
    van_loan_series,
)
from strapdown_ros.core.aided.layout import B_BA, B_BG, B_GMA, B_GMG, B_SFA, B_SFG, B_WHEEL_QUANT
from strapdown_ros.core.aided.measurement_models import (
    K_BARO,
    K_GNSS_POSITION,
    K_GNSS_VELOCITY,
    K_MAG,
    K_WHEEL,
    baro_model,
    gnss_position_model,
    gnss_velocity_model,
    mag_model,
    wheel_model,
)
from strapdown_ros.core.aided.update import carry_quantization, joseph_update, reset_attitude
from strapdown_ros.core.navigation._kernels import exact_kernel

__all__ = ["advance", "apply_epoch", "inject", "is_grid", "make_posterior", "record_output"]


@jit
def is_grid(k_abs, periods):
    """Whether absolute cycle ``k_abs`` is a multiple of one of ``periods`` (cycles)."""
    for p in periods:
        if k_abs % p == 0:
            return True
    return False


@jit
def inject(nav, est, dx, ni_start):
    """Add the correction ``dx`` to the nominal state.

    R, V by compensated sums, ``C ← exp([dφ×]) C``, the other estimates from index
    ``ni_start`` (= 9).
    """
    for a in range(6):
        y = dx[a] + nav[15 + a]
        t = nav[a] + y
        nav[15 + a] = y - (t - nav[a])
        nav[a] = t
    rot = rotation_exp(dx[6:9])
    c = nav[6:15].reshape(3, 3).copy()
    for i in range(3):
        for j in range(3):
            nav[6 + 3 * i + j] = rot[i, 0] * c[0, j] + rot[i, 1] * c[1, j] + rot[i, 2] * c[2, j]
    for i in range(ni_start, est.shape[0]):
        est[i] += dx[i]


@jit
def apply_epoch(m, ist, nav, est, p, off, pns, h_m, h_kind, h_z, h_r, h_dim, h_status, h_out,
                h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1, igrf_a2, igrf_d, igrf_radius,
                gate):  # fmt: skip
    """Apply the history's measurements of cycle m (canonical order); marks ``ist`` posterior."""
    lo = np.searchsorted(h_m[:h_n], m, side="left")
    hi = np.searchsorted(h_m[:h_n], m, side="right")
    period = pns * 1e-9
    t = (m * pns) * 1e-9
    for row in range(lo, hi):
        kind = h_kind[row]
        r = nav[0:3].copy()
        v = nav[3:6].copy()
        lo6 = nav[15:18].copy()
        c = nav[6:15].reshape(3, 3).copy()
        da = nav[21:24].copy()
        z = h_z[row]
        if kind == K_GNSS_POSITION:
            nu, h = gnss_position_model(r, lo6, c, t, est, off, levers[0], z[0:3], z[3], z[4])
        elif kind == K_GNSS_VELOCITY:
            nu, h = gnss_velocity_model(r, v, c, t, est, off, levers[1], da, period, z[0:3])
        elif kind == K_BARO:
            nu, h = baro_model(r, lo6, c, t, est, off, levers[2], z[0])
        elif kind == K_MAG:
            nu, h = mag_model(r, c, t, est, off, z[0:3], igrf_g, igrf_h, igrf_a1, igrf_a2,
                              igrf_d, igrf_radius)  # fmt: skip
        else:
            nu, h = wheel_model(r, v, c, est, off, levers[4], da, period, z[0:3], wheel_mask)
        d = nu.shape[0]
        rm = h_r[row, :d, :d].copy()
        kq = off[B_WHEEL_QUANT] if kind == K_WHEEL else -1
        fresh = p[kq + 1, kq + 1] if kq >= 0 else 0.0
        dx, nis, accepted = joseph_update(p, nu, h, rm, gate[d])
        if accepted:
            inject(nav, est, dx, 9)
            reset_attitude(p, dx[6:9])
        if kq >= 0:  # the count moved on whether the update was accepted or not
            carry_quantization(est, p, kq, fresh)
        if h_status[row] == 0:
            for i in range(3):
                h_out[row, i] = nu[i] if i < d else 0.0
            h_out[row, 3] = nis
            h_out[row, 4] = d
            h_out[row, 5] = 1.0 if accepted else 0.0
            h_status[row] = 1
    ist[1] = 1


@jit
def _correct(ring, idx, est, bias, gm, sf, period, out, row):
    for a in range(3):
        b = est[bias + a] + (est[gm + a] if gm >= 0 else 0.0)
        x = ring[idx, a] - b * period
        if sf >= 0:
            x = x / (1.0 + est[sf + a])
        out[row, a] = x


@jit
def _cov_step(nav, est, p, acc, off, beta, q, q_ins, ni, period, gmodel):
    cnt = acc[18]
    if cnt == 0.0:
        return
    dt = cnt * period
    cm = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            cm[i, j] = acc[3 * i + j] / cnt
    fe = acc[9:12] / dt
    wb = acc[12:15] / dt
    fb = acc[15:18] / dt
    grad = gravitation_gradient(nav[0:3].copy(), gmodel)
    rows, cols, vals, nnz = sparse_dynamics(cm, fe, wb, fb, grad, est, off, beta, ni)
    qc = continuous_noise(cm, q_ins, q, ni)
    phi, qd = van_loan_series(rows, cols, vals, nnz, qc, dt)
    propagate_covariance(p, phi, qd, beta, q, dt, ni)
    propagate_estimates(est, beta, dt)
    acc[:] = 0.0


@jit
def make_posterior(ist, nav, est, p, off, pns, h_m, h_kind, h_z, h_r, h_dim, h_status, h_out,
                   h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1, igrf_a2, igrf_d,
                   igrf_radius, gate):  # fmt: skip
    """Apply the updates of the current cycle if not done yet."""
    if ist[1] == 0:
        apply_epoch(ist[0], ist, nav, est, p, off, pns, h_m, h_kind, h_z, h_r, h_dim, h_status,
                    h_out, h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1, igrf_a2, igrf_d,
                    igrf_radius, gate)  # fmt: skip


@jit
def record_output(ist, nav, est, p, k0, out_period, out_m, out_nav, out_est, out_p):
    """Store the (posterior) state if the current cycle is an output epoch not stored yet."""
    m = ist[0]
    if (k0 + m) % out_period == 0 and m > ist[2]:
        row = ist[3]
        out_m[row] = m
        out_nav[row] = nav
        out_est[row] = est
        out_p[row] = p
        ist[3] = row + 1
        ist[2] = m


@jit
def advance(m_target, ist, nav, est, p, acc, ring_da, ring_dv, periods, k0, pns, off, beta, q,
            q_ins, ni, gmodel, p_int, gstep, ck_m, ck_nav, ck_est, ck_p, h_m, h_kind, h_z, h_r,
            h_dim, h_status, h_out, h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1, igrf_a2,
            igrf_d, igrf_radius, gate, sr, sv, sc, da_c, dv_c, out_period, record, out_m,
            out_nav, out_est, out_p):  # fmt: skip
    """Run from the current cycle to the prior of ``m_target`` (see the module docstring).

    With ``record``, the posterior at each output epoch (absolute cycle a multiple of
    ``out_period``) after ``ist[2]`` and before ``m_target`` is stored in ``out_*`` (row
    ``ist[3]``, which is advanced; the caller makes room for every epoch of the span) and
    ``ist[2]`` set to it.

    ``ring_da``, ``ring_dv`` (cap, 3): raw increments, cycle m at row ``m % cap`` (filled up to
    ``m_target``). ``sr``, ``sv``, ``sc``, ``da_c``, ``dv_c``: scratch of at least the longest
    stretch between grid points (+1 row for the states).
    """
    if ist[0] >= m_target:
        return
    make_posterior(ist, nav, est, p, off, pns, h_m, h_kind, h_z, h_r, h_dim, h_status, h_out,
                   h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1, igrf_a2, igrf_d,
                   igrf_radius, gate)  # fmt: skip
    if record:
        record_output(ist, nav, est, p, k0, out_period, out_m, out_nav, out_est, out_p)
    cap = ring_da.shape[0]
    period = pns * 1e-9
    bg, gmg, sfg = off[B_BG], off[B_GMG], off[B_SFG]
    ba, gma, sfa = off[B_BA], off[B_GMA], off[B_SFA]
    m = ist[0]
    lo = nav[15:21].copy()
    while m < m_target:
        # the stretch up to the next grid point (or the target)
        stop = m + 1
        while stop < m_target and not is_grid(k0 + stop, periods):
            stop += 1
        k = stop - m
        for i in range(k):
            idx = (m + 1 + i) % cap
            _correct(ring_da, idx, est, bg, gmg, sfg, period, da_c, i)
            _correct(ring_dv, idx, est, ba, gma, sfa, period, dv_c, i)
        sr[0, :] = nav[0:3]
        sv[0, :] = nav[3:6]
        sc[0] = nav[6:15].reshape(3, 3)
        exact_kernel(sr[: k + 1], sv[: k + 1], sc[: k + 1], lo, da_c[:k], dv_c[:k], period, 1,
                     p_int, gmodel)  # fmt: skip
        for i in range(k):
            for a in range(3):
                for b in range(3):
                    acc[3 * a + b] += sc[i, a, b]
                acc[9 + a] += sc[i, a, 0] * dv_c[i, 0] + sc[i, a, 1] * dv_c[i, 1] + (
                    sc[i, a, 2] * dv_c[i, 2])
                acc[12 + a] += da_c[i, a]
                acc[15 + a] += dv_c[i, a]
            acc[18] += 1.0
        nav[0:3] = sr[k]
        nav[3:6] = sv[k]
        nav[6:15] = sc[k].reshape(9)
        nav[15:21] = lo
        last = stop % cap
        nav[21:24] = ring_da[last]
        nav[24:27] = ring_dv[last]
        m = stop
        ist[0] = m
        ist[1] = 0
        if is_grid(k0 + m, periods):
            _cov_step(nav, est, p, acc, off, beta, q, q_ins, ni, period, gmodel)
            ncap = ck_m.shape[0]
            if ncap > 0:
                slot = ((k0 + m) // gstep) % ncap
                ck_m[slot] = m
                ck_nav[slot] = nav
                ck_est[slot] = est
                ck_p[slot] = p
            if m < m_target:
                apply_epoch(m, ist, nav, est, p, off, pns, h_m, h_kind, h_z, h_r, h_dim,
                            h_status, h_out, h_n, levers, wheel_mask, igrf_g, igrf_h, igrf_a1,
                            igrf_a2, igrf_d, igrf_radius, gate)  # fmt: skip
                lo = nav[15:21].copy()
                if record:
                    record_output(ist, nav, est, p, k0, out_period, out_m, out_nav, out_est,
                                  out_p)  # fmt: skip
        else:
            ist[1] = 1
