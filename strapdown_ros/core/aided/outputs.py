"""What the aided filter reports at an output epoch, from its state and covariance (numpy).

Vectorized over K snapshots (times ``t`` since E0, ``nav`` (K, 27), ``est`` (K, n), ``p``
(K, n, n)). Frames: core (body FRD, NED, ECEF); the message boundary converts to FLU/ENU.
The covariances are those of the reported quantities through the first-order Jacobians of
docs/theory/aided_ins.md §8:

* position ``r^E = C_E0^E R``, ``δr^E = C_E0^E δR``; attitude about ECEF axes ``φ^E = C_E0^E φ``;
* NED position error of the navigator's definition ``C_E^N (r̂ - r)``: ``C_E^N C_E0^E δR``;
* NED velocity error (each velocity in its own local level): ``δv^N = C_E^N C_E0^E (δV -
  ω_ie × δR) + [v^N×] D δr^N`` with ``D δr^N`` the turn of the local level by the position error;
* Young attitude error angles (up, east, north) ``θ = -C_NED→UEN (C_E^N φ^E - D δr^N)``
  (Young 1980 eq. (28): ``H ≈ I - [θ×]``);
* body velocity ``v^B = Cᵀ (V - ω_ie × R)`` and rate ``ω̂_eb`` (the twist);
* total biases ``b̂ + m̂`` (random constant + Gauss–Markov part).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.core.aided.layout import B_BA, B_BG, B_GMA, B_GMG, B_SFG, StateLayout
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    A_WGS84,
    E2_WGS84,
    OMEGA_IE,
    dcm_e0_to_ecef,
    dcm_ecef_to_ned,
    ecef_to_geodetic,
)
from strapdown_ros.core.young import C_NED_TO_UEN

__all__ = ["Reported", "nees", "reported", "skew_stack"]

_W = np.array([[0.0, -OMEGA_IE, 0.0], [OMEGA_IE, 0.0, 0.0], [0.0, 0.0, 0.0]])
_NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def skew_stack(v: F64) -> F64:
    """``[v×]`` (K, 3, 3) of vectors (K, 3)."""
    s = np.zeros(v.shape[:-1] + (3, 3))
    s[..., 0, 1], s[..., 0, 2] = -v[..., 2], v[..., 1]
    s[..., 1, 0], s[..., 1, 2] = v[..., 2], -v[..., 0]
    s[..., 2, 0], s[..., 2, 1] = -v[..., 1], v[..., 0]
    return s


def _mv(m: F64, v: F64) -> F64:
    return np.einsum("kij,kj->ki", m, v)


def _sandwich(j: F64, p: F64) -> F64:
    out = np.einsum("kia,kab,kjb->kij", j, p, j)
    return 0.5 * (out + np.swapaxes(out, -1, -2))


def _frame_turn(lat: F64, alt: F64) -> F64:
    """``D`` (K, 3, 3): ``δθ = D δr^N``, the local level's turn by a position error (NED)."""
    s = np.sin(lat)
    w2 = 1.0 - E2_WGS84 * s * s
    re = A_WGS84 / np.sqrt(w2)
    rn = A_WGS84 * (1.0 - E2_WGS84) / (w2 * np.sqrt(w2))
    d = np.zeros(lat.shape + (3, 3))
    d[:, 0, 1] = 1.0 / (re + alt)
    d[:, 1, 0] = -1.0 / (rn + alt)
    d[:, 2, 1] = -np.tan(lat) / (re + alt)
    return d


@dataclass(frozen=True)
class Reported:
    """The reported quantities of K snapshots (core frames) and their covariances.

    Attributes
    ----------
    r_e, v_e : (K, 3)
        ECEF position (m) and velocity relative to the Earth (m/s).
    c_b_e : (K, 3, 3)
        ``C_FRD^E``.
    omega_eb_b : (K, 3)
        Body rate relative to the Earth (FRD, rad/s), the corrected mean rate of the last cycle.
    lat, lon, alt : (K,)
    v_ned : (K, 3)
    pose_cov : (K, 6, 6)
        Position (ECEF axes) and rotation about the ECEF axes.
    twist_cov_frd : (K, 6, 6)
        Body velocity and rate, FRD axes.
    pos_cov_ned, vel_cov_ned, att_cov_young : (K, 3, 3)
        Covariances of the navigator's error definitions (position NED, velocity NED, Young).
    gyro_bias, accel_bias, gyro_bias_sigma, accel_bias_sigma : (K, 3)
        Total bias estimates (FRD) and their σ.
    """

    r_e: F64
    v_e: F64
    c_b_e: F64
    omega_eb_b: F64
    lat: F64
    lon: F64
    alt: F64
    v_ned: F64
    pose_cov: F64
    twist_cov_frd: F64
    pos_cov_ned: F64
    vel_cov_ned: F64
    att_cov_young: F64
    gyro_bias: F64
    accel_bias: F64
    gyro_bias_sigma: F64
    accel_bias_sigma: F64


def _bias_rows(layout: StateLayout, bias: int, gm: int, k: int) -> F64:
    t = np.zeros((k, 3, layout.n))
    for block in (bias, gm):
        if layout.has(block):
            t[:, :, layout.slice(block)] = np.eye(3)
    return t


def reported(t: F64, nav: F64, est: F64, p: F64, layout: StateLayout, period_s: float,
             rate_variance: F64) -> Reported:  # fmt: skip
    """The :class:`Reported` quantities of snapshots (see the module docstring).

    ``rate_variance`` (3,): variance of a cycle's mean-rate white noise (rad/s)², added to the
    twist's angular block.
    """
    k = len(t)
    n = layout.n
    r0, v0 = nav[:, 0:3], nav[:, 3:6]
    c0 = nav[:, 6:15].reshape(k, 3, 3)
    ce = dcm_e0_to_ecef(np.asarray(t, dtype=np.float64)).reshape(k, 3, 3)
    r_e = _mv(ce, r0)
    u0 = v0 - (r0 @ _W.T)  # V - ω × R (E0)
    v_e = _mv(ce, u0)
    c_b_e = ce @ c0
    lat, lon, alt = ecef_to_geodetic(r_e)
    cen = dcm_ecef_to_ned(lat, lon).reshape(k, 3, 3)
    v_ned = _mv(cen, v_e)
    # body rate (FRD) and its Jacobian
    bg, gm, sf = layout.offsets[B_BG], layout.offsets[B_GMG], layout.offsets[B_SFG]
    raw = nav[:, 21:24] / period_s - est[:, bg : bg + 3]
    if gm >= 0:
        raw = raw - est[:, gm : gm + 3]
    kk = 1.0 / (1.0 + est[:, sf : sf + 3]) if sf >= 0 else np.ones((k, 3))
    w_ib = raw * kk
    earth = np.einsum("kji,j->ki", c0, np.array([0.0, 0.0, OMEGA_IE]))
    w_eb = w_ib - earth
    jw = np.zeros((k, 3, n))
    for block in (bg, gm):
        if block >= 0:
            jw[:, :, block : block + 3] = -kk[:, :, None] * np.eye(3)
    if sf >= 0:
        jw[:, :, sf : sf + 3] = -(w_ib * kk)[:, :, None] * np.eye(3)
    jw[:, :, 6:9] = -np.swapaxes(c0, -1, -2) @ _W
    # body velocity Jacobian
    ct = np.swapaxes(c0, -1, -2)
    jvb = np.zeros((k, 3, n))
    jvb[:, :, 0:3] = -ct @ _W
    jvb[:, :, 3:6] = ct
    jvb[:, :, 6:9] = ct @ skew_stack(u0)
    twist = _sandwich(np.concatenate([jvb, jw], axis=1), p)
    twist[:, 3:, 3:] += np.diag(np.asarray(rate_variance, dtype=np.float64))
    # pose (ECEF axes)
    jpose = np.zeros((k, 6, n))
    jpose[:, 0:3, 0:3] = ce
    jpose[:, 3:6, 6:9] = ce
    pose = _sandwich(jpose, p)
    # the navigator's error definitions
    m = cen @ ce  # C_E^N C_E0^E
    d = _frame_turn(lat, alt)
    jp = np.zeros((k, 3, n))
    jp[:, :, 0:3] = m
    jv = np.zeros((k, 3, n))
    jv[:, :, 0:3] = -m @ _W + skew_stack(v_ned) @ d @ m
    jv[:, :, 3:6] = m
    ja = np.zeros((k, 3, n))
    ja[:, :, 0:3] = C_NED_TO_UEN @ d @ m
    ja[:, :, 6:9] = -C_NED_TO_UEN @ m
    # biases
    tg = _bias_rows(layout, B_BG, B_GMG, k)
    ta = _bias_rows(layout, B_BA, B_GMA, k)
    bias_g = np.einsum("kin,kn->ki", tg, est)
    bias_a = np.einsum("kin,kn->ki", ta, est)
    sg = np.sqrt(np.maximum(np.diagonal(_sandwich(tg, p), axis1=1, axis2=2), 0.0))
    sa = np.sqrt(np.maximum(np.diagonal(_sandwich(ta, p), axis1=1, axis2=2), 0.0))
    return Reported(
        r_e, v_e, c_b_e, w_eb, lat, lon, alt, v_ned, pose, twist, _sandwich(jp, p),
        _sandwich(jv, p), _sandwich(ja, p), bias_g, bias_a, sg, sa,
    )  # fmt: skip


def nees(error: F64, cov: F64) -> F64:
    """``eᵀ S⁻¹ e`` (K,) of errors (K, d) with covariances (K, d, d)."""
    sol = np.linalg.solve(cov, error[..., None])[..., 0]
    return np.einsum("ki,ki->k", error, sol)
