"""Measurement models of the aided filter: predicted measurement, innovation and Jacobian.

Each model takes the nominal state — position ``R``, inertial velocity ``V``, attitude
``C = C_B^E0`` in the inertial frame E0, the time ``t`` since E0 (``C_E0^E = Rz(-ω_ie t)``), the
estimates ``est`` of the other states (indexed by the layout ``off``) and the raw gyro
increment ``Δα̃`` of the cycle ending at the epoch — and returns the innovation
``ν = z̃ - h(x̂)`` and ``H = ∂h/∂x`` for the error state ``x = x̂ - x`` (docs/theory/aided_ins.md
§5 has the equations):

* GNSS position (NED of the measured fix): ``h = C_E^N C_E0^E (R + C l) + ĝ_p``;
* GNSS velocity (NED of the estimated antenna): ``h = C_E^N C_E0^E (V - ω_ie × R + C (ω̂_eb × l))
  + ĝ_v`` with ``ω̂_eb = ω̂_ib - Cᵀ ω_ie``, ``ω̂_ib = (Δα̃/T - b̂_g - ĝm_g) / (1 + ŝ_g)`` — the mean
  rate of the cycle ending at the epoch, the truth's own definition (docs/messages.md);
* barometer: ``h = p_ICAO(alt(C_E0^E (R + C l))) + b̂ + d̂``;
* magnetometer (3-axis, body FRD): ``h = Cᵀ C_E^E0 C_N^E B^N(r) + ĥ_hi`` (IGRF);
* wheel odometer: ``v_c = Cᵀ (V - ω_ie × R) + ω̂_eb × l``, ``h = ((1 + ŝ_w) v_c,x, v_c,y,
  v_c,z)`` (speed; the last two rows are the non-holonomic constraint, selected by ``mask``);
  with the quantization states the speed row adds ``ρ̂_last − ρ̂_next``: an encoder's speed is
  ``q (n_k − n_{k−1}) / P = ũ + (ρ_{k−1} − ρ_k) / P``, ρ_k the distance rolled but not counted
  at epoch k (uniform over one pulse q), here as speeds ρ/P. The filter carries ρ_{k−1} from
  the last wheel epoch, adds ρ_k as a fresh state of variance (q/P)²/12 and, after the update,
  makes it the last one (:func:`strapdown_ros.core.aided.update.carry_quantization`).

Attitude convention ``Ĉ = exp([φ×]) C``: ``δ(Ĉ a) = -[(Ĉ a)×] φ``, ``δ(Ĉᵀ b) = Ĉᵀ [b×] φ``.
The field gradient of the magnetometer (|∂B/∂r| ≈ 3|B|/r ≈ 2e-11 T/m) is neglected.
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core.aided._fields import (
    ecef_to_geodetic1,
    ecef_to_ned1,
    icao_pressure1,
    igrf_ned1,
)
from strapdown_ros.core.aided._jit import jit
from strapdown_ros.core.aided._small import cross, matmul3, matvec3, matvec3_t, rot_z, skew
from strapdown_ros.core.aided.layout import (
    B_BARO_BIAS,
    B_BARO_DRIFT,
    B_BG,
    B_GMG,
    B_GNSS_POS,
    B_GNSS_VEL,
    B_MAG,
    B_SFG,
    B_WHEEL_QUANT,
    B_WHEEL_SF,
)
from strapdown_ros.core.earth import A_WGS84, E2_WGS84, OMEGA_IE

__all__ = [
    "K_BARO",
    "K_GNSS_POSITION",
    "K_GNSS_VELOCITY",
    "K_MAG",
    "K_WHEEL",
    "KINDS",
    "baro_model",
    "body_rate",
    "gnss_position_model",
    "gnss_velocity_model",
    "mag_model",
    "wheel_model",
]

#: Measurement kinds; the order is the canonical order of measurements at one epoch.
K_GNSS_POSITION, K_GNSS_VELOCITY, K_BARO, K_MAG, K_WHEEL = 0, 1, 2, 3, 4
KINDS = ("gnss_position", "gnss_velocity", "baro", "mag", "wheel")


@jit
def _ecef_rot(t):
    """``C_E0^E(t) = Rz(-ω_ie t)``."""
    return rot_z(-OMEGA_IE * t)


@jit
def _omega_cross(v):
    """``ω_ie × v`` (ω_ie along z, E or E0 axes)."""
    out = np.empty(3)
    out[0], out[1], out[2] = -OMEGA_IE * v[1], OMEGA_IE * v[0], 0.0
    return out


@jit
def body_rate(c, da_raw, period, est, off):
    """``ω̂_eb^B`` (3,) and its Jacobian ``∂ω̂_eb/∂x`` (3, n).

    The mean rate of the cycle of ``da_raw`` corrected by the estimates, minus the Earth rate
    with the attitude ``c``.
    """
    n = est.shape[0]
    jw = np.zeros((3, n))
    w = np.empty(3)
    bg, gm, sf = off[B_BG], off[B_GMG], off[B_SFG]
    for i in range(3):
        k = 1.0 / (1.0 + est[sf + i]) if sf >= 0 else 1.0
        raw = da_raw[i] / period - est[bg + i] - (est[gm + i] if gm >= 0 else 0.0)
        w[i] = raw * k
        jw[i, bg + i] = -k
        if gm >= 0:
            jw[i, gm + i] = -k
        if sf >= 0:
            jw[i, sf + i] = -w[i] * k
    wie = np.zeros(3)
    wie[2] = OMEGA_IE
    earth = matvec3_t(c, wie)
    # δ(-Cᵀ ω_ie) = -Cᵀ [ω_ie×] φ
    m = matmul3(c.T.copy(), skew(wie))
    for i in range(3):
        w[i] -= earth[i]
        for j in range(3):
            jw[i, 6 + j] = -m[i, j]
    return w, jw


@jit
def _put3(h, row, col, m, sign):
    for i in range(3):
        for j in range(3):
            h[row + i, col + j] += sign * m[i, j]


@jit
def _measurement_bias(nu, h, est, k):
    """An additive measurement bias state at ``k`` (none if ``k < 0``): ``ν -= b̂``, ``H_b = I``."""
    if k >= 0:
        for i in range(3):
            nu[i] -= est[k + i]
            h[i, k + i] = 1.0


@jit
def gnss_position_model(r, lo, c, t, est, off, lever, r_meas, lat_m, lon_m):
    """GNSS antenna position: ``(ν, H)`` in NED of the measured fix (m).

    ``r_meas``: the fix in ECEF (m); ``lat_m``, ``lon_m``: its geodetic coordinates (rad).
    """
    n = est.shape[0]
    c_e = _ecef_rot(t)
    cen = ecef_to_ned1(lat_m, lon_m)
    cl = matvec3(c, lever)
    ra = matvec3(c_e, r)
    ta = matvec3(c_e, lo[:3] + cl)
    nu = matvec3(cen, (r_meas - ra) - ta)
    m = matmul3(cen, c_e)
    h = np.zeros((3, n))
    _put3(h, 0, 0, m, 1.0)
    _put3(h, 0, 6, matmul3(m, skew(cl)), -1.0)
    _measurement_bias(nu, h, est, off[B_GNSS_POS])
    return nu, h


@jit
def _frame_rotation(lat, alt):
    """``D`` with ``δθ = D δr^N``: rotation of the local level by a position error (NED)."""
    s = math.sin(lat)
    w2 = 1.0 - E2_WGS84 * s * s
    re = A_WGS84 / math.sqrt(w2)
    rn = A_WGS84 * (1.0 - E2_WGS84) / (w2 * math.sqrt(w2))
    d = np.zeros((3, 3))
    d[0, 1] = 1.0 / (re + alt)
    d[1, 0] = -1.0 / (rn + alt)
    d[2, 1] = -math.tan(lat) / (re + alt)
    return d


@jit
def _subtract_product(h, a, jw):
    """``H[:3] -= A J`` in place for ``a`` (3, 3), ``jw`` (3, n) (each sum over k ascending)."""
    for i in range(3):
        for j in range(jw.shape[1]):
            s = 0.0
            for k in range(3):
                s += a[i, k] * jw[k, j]
            h[i, j] -= s


@jit
def gnss_velocity_model(r, v, c, t, est, off, lever, da_raw, period, v_meas_ned):
    """GNSS antenna velocity relative to the Earth: ``(ν, H)`` (m/s).

    In NED of the estimated antenna position; ``v_meas_ned``: the measured velocity in NED
    axes.
    """
    n = est.shape[0]
    c_e = _ecef_rot(t)
    w, jw = body_rate(c, da_raw, period, est, off)
    lev = matvec3(c, cross(w, lever))
    va0 = (v - _omega_cross(r)) + lev
    cl = matvec3(c, lever)
    ra = matvec3(c_e, r + cl)
    lat, lon, alt = ecef_to_geodetic1(ra[0], ra[1], ra[2])
    cen = ecef_to_ned1(lat, lon)
    m = matmul3(cen, c_e)
    vn = matvec3(m, va0)
    nu = v_meas_ned - vn
    h = np.zeros((3, n))
    wie = np.zeros(3)
    wie[2] = OMEGA_IE
    sw = skew(wie)
    _put3(h, 0, 0, matmul3(m, sw), -1.0)  # -ω_ie × δR
    _put3(h, 0, 3, m, 1.0)
    _put3(h, 0, 6, matmul3(m, skew(lev)), -1.0)  # -[(C(ω×l))×] φ
    # lever term through the rate: -C [l×] δω_eb
    _subtract_product(h, matmul3(m, matmul3(c, skew(lever))), jw)
    # the local level of the antenna turns with its position: δ(C_E^N) v = [v^N×] D δr^N
    g = matmul3(skew(vn), _frame_rotation(lat, alt))
    gm_ = matmul3(g, m)
    _put3(h, 0, 0, gm_, 1.0)
    _put3(h, 0, 6, matmul3(gm_, skew(cl)), -1.0)
    _measurement_bias(nu, h, est, off[B_GNSS_VEL])
    return nu, h


@jit
def baro_model(r, lo, c, t, est, off, lever, p_meas):
    """Barometer static pressure: ``(ν, H)`` (Pa), ICAO atmosphere at the sensor altitude."""
    n = est.shape[0]
    c_e = _ecef_rot(t)
    cl = matvec3(c, lever)
    rs = matvec3(c_e, r + (lo[:3] + cl))
    lat, lon, alt = ecef_to_geodetic1(rs[0], rs[1], rs[2])
    p, dp = icao_pressure1(alt)
    up = np.empty(3)
    cp = math.cos(lat)
    up[0], up[1], up[2] = cp * math.cos(lon), cp * math.sin(lon), math.sin(lat)
    g = matvec3_t(c_e, up)  # C_E0^Eᵀ up: the altitude gradient in E0
    nu = np.empty(1)
    nu[0] = p_meas - p
    h = np.zeros((1, n))
    for j in range(3):
        h[0, j] = dp * g[j]
    # δ(C l) = -[(C l)×] φ: row gᵀ (-[cl×]) = (cl × g)ᵀ
    clg = cross(cl, g)
    for j in range(3):
        h[0, 6 + j] = dp * clg[j]
    for b in (B_BARO_BIAS, B_BARO_DRIFT):
        k = off[b]
        if k >= 0:
            nu[0] -= est[k]
            h[0, k] = 1.0
    return nu, h


@jit
def mag_model(r, c, t, est, off, m_meas, g, hc, a1, a2, diag, radius):
    """3-axis magnetometer: ``(ν, H)`` (T, body FRD) against the IGRF main field at ``r``."""
    n = est.shape[0]
    c_e = _ecef_rot(t)
    re = matvec3(c_e, r)
    lat, lon, _ = ecef_to_geodetic1(re[0], re[1], re[2])
    bn, be_, bd = igrf_ned1(re[0], re[1], re[2], lat, g, hc, a1, a2, diag, radius)
    b_ned = np.empty(3)
    b_ned[0], b_ned[1], b_ned[2] = bn * 1e-9, be_ * 1e-9, bd * 1e-9
    cen = ecef_to_ned1(lat, lon)
    b_e = matvec3_t(cen, b_ned)
    b0 = matvec3_t(c_e, b_e)
    nu = m_meas - matvec3_t(c, b0)
    h = np.zeros((3, n))
    _put3(h, 0, 6, matmul3(c.T.copy(), skew(b0)), 1.0)
    _measurement_bias(nu, h, est, off[B_MAG])
    return nu, h


@jit
def wheel_model(r, v, c, est, off, lever, da_raw, period, z_meas, mask):
    """Wheel odometer speed and non-holonomic constraints: ``(ν, H)`` (m/s, body FRD).

    ``z_meas`` (3,): measured speed and the constraint values (0); ``mask`` (3,) bool: the rows
    used (speed, lateral, vertical). Returns the used rows only.
    """
    n = est.shape[0]
    w, jw = body_rate(c, da_raw, period, est, off)
    u = v - _omega_cross(r)
    vc = matvec3_t(c, u) + cross(w, lever)
    hf = np.zeros((3, n))
    ct = c.T.copy()
    wie = np.zeros(3)
    wie[2] = OMEGA_IE
    _put3(hf, 0, 0, matmul3(ct, skew(wie)), -1.0)
    _put3(hf, 0, 3, ct, 1.0)
    _put3(hf, 0, 6, matmul3(ct, skew(u)), 1.0)
    _subtract_product(hf, skew(lever), jw)
    pred = vc.copy()
    ks = off[B_WHEEL_SF]
    if ks >= 0:
        scale = 1.0 + est[ks]
        pred[0] = scale * vc[0]
        for j in range(n):
            hf[0, j] *= scale
        hf[0, ks] = vc[0]
    kq = off[B_WHEEL_QUANT]
    if kq >= 0:  # the count's residuals as speeds: z = ũ + ρ_last − ρ_next
        pred[0] += est[kq] - est[kq + 1]
        hf[0, kq] = 1.0
        hf[0, kq + 1] = -1.0
    m = 0
    for i in range(3):
        if mask[i]:
            m += 1
    nu = np.empty(m)
    h = np.zeros((m, n))
    row = 0
    for i in range(3):
        if mask[i]:
            nu[row] = z_meas[i] - pred[i]
            for j in range(n):
                h[row, j] = hf[i, j]
            row += 1
    return nu, h
