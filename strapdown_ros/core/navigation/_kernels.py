"""Compiled hot loop of the multirate b–l split navigator (Waldmann Table 1, ``paper`` mode).

All of :func:`strapdown_ros.core.navigation.multirate.navigate_multirate`'s per-cycle work —
rates (9)/(14)/(33), plumb-bob gravity ``g_l``, the N-step fast layer (19)/(33), the P-step
intermediate layer (29) and the slow update (9)/(32) — for *all* ``T_nav`` cycles in one call,
written in scalar arithmetic and compiled with numba when it is importable (``HAVE_NUMBA``).
Without numba the same functions are plain Python (correct, slow); the core still imports.

The operations mirror the Python path in ``multirate.py`` term for term. Differences are in
rounding only: ``g_l`` uses float64 ``geodetic_to_ecef`` (the Python path evaluates it in
``np.longdouble``) and the ``C_E^N`` / ``D_l^b`` products are summed in a fixed order; the two
paths agree to ~1e-13 relative (``test/test_navigation_kernels.py``).
"""

from __future__ import annotations

import math

import numpy as np

from strapdown_ros.core import series as _series
from strapdown_ros.core.earth import (
    A_WGS84,
    E2_WGS84,
    F_WGS84,
    GM_WGS84,
    J2_WGS84,
    OMEGA_IE,
)

try:  # numba is optional: the ROS-free core must import without it.
    import numba

    HAVE_NUMBA = True
    _jit = numba.njit(cache=True, nogil=True)
except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None
    HAVE_NUMBA = False

    def _jit(fn):
        return fn


__all__ = [
    "GRAVITY_CODES",
    "HAVE_NUMBA",
    "exact_fast_kernel",
    "exact_kernel",
    "fast_cycle_kernel",
    "multirate_kernel",
    "rotation_coefficients_scalar",
]

#: Gravitation model name → integer code passed to the kernel.
GRAVITY_CODES = {"j2": 0, "spherical": 1}


@_jit
def fast_cycle_kernel(q, dalpha, dv, start, n, lx, ly, lz, normalize, q_out, v_out):
    """Eqs. (19) and (33) over increments ``start .. start+n-1`` (``lx, ly, lz = ½ Δφ_l``).

    The one implementation of the fast loop (``multirate.fast_cycle`` calls its plain-Python
    form). Writes ``q_out`` (4,) and ``v_out`` (3,); ``q_out`` may alias ``q``.
    """
    w, x, y, z = q[0], q[1], q[2], q[3]
    vx = 0.0
    vy = 0.0
    vz = 0.0
    for k in range(start, start + n):
        ax, ay, az = dalpha[k, 0], dalpha[k, 1], dalpha[k, 2]
        cx = ay * vz - az * vy
        cy = az * vx - ax * vz
        cz = ax * vy - ay * vx
        vx, vy, vz = vx - cx + dv[k, 0], vy - cy + dv[k, 1], vz - cz + dv[k, 2]
        bx, by, bz = 0.5 * ax, 0.5 * ay, 0.5 * az
        dw = -(x * bx + y * by + z * bz) + (lx * x + ly * y + lz * z)
        dx = w * bx + (y * bz - z * by) - (w * lx + (ly * z - lz * y))
        dy = w * by + (z * bx - x * bz) - (w * ly + (lz * x - lx * z))
        dz = w * bz + (x * by - y * bx) - (w * lz + (lx * y - ly * x))
        w, x, y, z = w + dw, x + dx, y + dy, z + dz
        if normalize:
            s = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
            w, x, y, z = w * s, x * s, y * s, z * s
    q_out[0], q_out[1], q_out[2], q_out[3] = w, x, y, z
    v_out[0], v_out[1], v_out[2] = vx, vy, vz


@_jit
def _gravity_ned(lat, alt, model):
    """``gravity_ned(lat, alt, model)`` in float64 scalars (plumb-bob, NED; lon = 0)."""
    s, c = math.sin(lat), math.cos(lat)
    rne = A_WGS84 / math.sqrt(1.0 - E2_WGS84 * s * s)
    rx = (rne + alt) * c
    rz = (rne * (1.0 - E2_WGS84) + alt) * s
    r2 = rx * rx + rz * rz
    m = -GM_WGS84 / (r2 * math.sqrt(r2))
    if model == 0:
        k = 1.5 * J2_WGS84 * A_WGS84 * A_WGS84 / r2
        zz = 5.0 * rz * rz / r2
        gx = m * (1.0 + k * (1.0 - zz)) * rx
        gz = m * (1.0 + k * (3.0 - zz)) * rz
    else:
        gx = m * rx
        gz = m * rz
    gx += OMEGA_IE * OMEGA_IE * rx
    # C_E^N at lon = 0: north = [-s, 0, c], east = [0, 1, 0], down = [-c, 0, -s].
    return -s * gx + c * gz, 0.0, -c * gx - s * gz


@_jit
def multirate_kernel(
    lat, lon, alt, u0, q0, dalpha, dv, t_gyr, n, p, model, normalize, table1, pos, vel, quat,
    damp, c1, c2, haux,
):
    """All ``T_nav`` cycles of Table 1 in one call.

    Fills ``pos`` (K+1, 3) = (λ, Λ, h), ``vel`` (K+1, 3) and ``quat`` (K+1, 4) with
    K = ``pos.shape[0] - 1`` cycles of ``n`` increments each; ``model`` is a
    :data:`GRAVITY_CODES` value. With ``damp``, the vertical channel of Table 1 is damped by
    the auxiliary altitude ``haux[j]`` of cycle j: ``ḣ = -V_D + c1 (h - h_aux)`` (9) and
    ``U̇_D += c2 (h - h_aux)`` in (29) (Table 1 prints ``c1 = +1``, ``c2 = -1``).
    """
    cycles = pos.shape[0] - 1
    t_nav = n * t_gyr
    t_int = t_nav / p
    ux, uy, uz = u0[0], u0[1], u0[2]
    q = np.empty(4)
    q[:] = q0
    vfb = np.empty(3)
    pos[0, 0], pos[0, 1], pos[0, 2] = lat, lon, alt
    vel[0, 0], vel[0, 1], vel[0, 2] = ux, uy, uz
    quat[0, :] = q
    for j in range(cycles):
        # Rates (9), (33), (14) from the start-of-cycle state.
        sl, cl = math.sin(lat), math.cos(lat)
        if table1:
            s2 = sl * sl
            rn = A_WGS84 * (1.0 - 2.0 * F_WGS84 + 3.0 * F_WGS84 * s2)
            re = A_WGS84 * (1.0 + F_WGS84 * s2)
        else:
            w2 = 1.0 - E2_WGS84 * sl * sl
            rn = A_WGS84 * (1.0 - E2_WGS84) / (w2 * math.sqrt(w2))
            re = A_WGS84 / math.sqrt(w2)
        lat_dot = ux / (rn + alt)
        lon_dot = uy / ((re + alt) * cl)
        wil_x = (OMEGA_IE + lon_dot) * cl
        wil_y = -lat_dot
        wil_z = -(OMEGA_IE + lon_dot) * sl
        wc_x = (2 * OMEGA_IE + lon_dot) * cl
        wc_y = -lat_dot
        wc_z = -(2 * OMEGA_IE + lon_dot) * sl
        gn, ge, gd = _gravity_ned(lat, alt, model)
        sv = 0.0
        if damp:
            sv = alt - haux[j]
            gd = gd + c2 * sv

        # Fast layer (19), (33).
        lx = 0.5 * (t_gyr * wil_x)
        ly = 0.5 * (t_gyr * wil_y)
        lz = 0.5 * (t_gyr * wil_z)
        fast_cycle_kernel(q, dalpha, dv, j * n, n, lx, ly, lz, normalize, q, vfb)

        # Intermediate layer (29) from U_g,l = U_l (27).
        gx, gy, gz = ux, uy, uz
        for _ in range(p):
            cx = wc_y * gz - wc_z * gy
            cy = wc_z * gx - wc_x * gz
            cz = wc_x * gy - wc_y * gx
            gx, gy, gz = gx + t_int * (-cx + gn), gy + t_int * (-cy + ge), gz + t_int * (-cz + gd)

        # Slow: position (9) with V(k), then U_l (32) with D_l^b of the normalized q.
        if damp:
            alt_next = alt + t_nav * (-uz + c1 * sv)
        else:
            alt_next = alt - t_nav * uz
        lat, lon, alt = lat + t_nav * lat_dot, lon + t_nav * lon_dot, alt_next
        nq = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        w, x, y, z = q[0] / nq, q[1] / nq, q[2] / nq, q[3] / nq
        c00 = w * w + x * x - y * y - z * z
        c11 = w * w - x * x + y * y - z * z
        c22 = w * w - x * x - y * y + z * z
        c01 = 2 * (x * y - w * z)
        c10 = 2 * (x * y + w * z)
        c02 = 2 * (x * z + w * y)
        c20 = 2 * (x * z - w * y)
        c12 = 2 * (y * z - w * x)
        c21 = 2 * (y * z + w * x)
        ux = gx + (c00 * vfb[0] + c01 * vfb[1] + c02 * vfb[2])
        uy = gy + (c10 * vfb[0] + c11 * vfb[1] + c12 * vfb[2])
        uz = gz + (c20 * vfb[0] + c21 * vfb[1] + c22 * vfb[2])
        pos[j + 1, 0], pos[j + 1, 1], pos[j + 1, 2] = lat, lon, alt
        vel[j + 1, 0], vel[j + 1, 1], vel[j + 1, 2] = ux, uy, uz
        quat[j + 1, :] = q


# --------------------------------------------------------------------------------------------
# High-accuracy (``exact``) mode: exact per-increment composition, Earth-fixed slow layer
# --------------------------------------------------------------------------------------------

#: Taylor coefficients of f1..f4 (strapdown_ros.core.series), read once as kernel constants.
_F1C = _series._COEFFS[1]
_F2C = _series._COEFFS[2]
_F3C = _series._COEFFS[3]
_F4C = _series._COEFFS[4]
_SWITCH = _series.SERIES_SWITCH


@_jit
def _horner(c, x2):
    out = c[c.shape[0] - 1]
    for i in range(c.shape[0] - 2, -1, -1):
        out = out * x2 + c[i]
    return out


@_jit
def rotation_coefficients_scalar(x):
    """``(f1, f2, f3, f4)`` of angle ``x`` (rad): :func:`strapdown_ros.core.series` in scalars."""
    if x < _SWITCH:
        x2 = x * x
        return _horner(_F1C, x2), _horner(_F2C, x2), _horner(_F3C, x2), _horner(_F4C, x2)
    s = math.sin(x) / x
    h = 0.5 * x
    sh = math.sin(h) / h
    c = 0.5 * sh * sh
    x2 = x * x
    return s, c, (1.0 - s) / x2, (0.5 - c) / x2


@_jit
def exact_fast_kernel(dalpha, dv, start, n, t_gyr, gam, w, s):
    """Body-frame fast layer of the ``exact`` mode over increments ``start .. start+n-1``.

    From ``Γ = I``, ``W = S = 0`` at the cycle start ``t_k`` (body frame ``B_k``), for each
    increment ``(Δα_j, Δv_j)`` (Savage 2020 eqs. (2)-(4) without gravity, i.e. Savage 1998's
    moderate-speed algorithms run at the sensor rate):
    ``S ← S + W T + Γ G_R(Δα_j) Δv_j T``, ``W ← W + Γ G_V(Δα_j) Δv_j``, ``Γ ← Γ G_C(Δα_j)``.
    At the end ``Γ = C_{B(t_k+1)}^{B_k}``, ``W = ∫ C_B^{B_k} a_SF dt`` (Waldmann's ``V_f,b``
    expressed in ``B_k``: ``V_f,b = Γᵀ W``) and ``S = ∫∫ C_B^{B_k} a_SF dt dt`` — exactly, under
    constant rate and specific force within each increment, with the coning, sculling and
    scrolling of the cycle included. Writes ``gam`` (3, 3), ``w`` (3,), ``s`` (3,).
    """
    g00, g01, g02 = 1.0, 0.0, 0.0
    g10, g11, g12 = 0.0, 1.0, 0.0
    g20, g21, g22 = 0.0, 0.0, 1.0
    wx = wy = wz = 0.0
    sx = sy = sz = 0.0
    for k in range(start, start + n):
        ax, ay, az = dalpha[k, 0], dalpha[k, 1], dalpha[k, 2]
        vx, vy, vz = dv[k, 0], dv[k, 1], dv[k, 2]
        f1, f2, f3, f4 = rotation_coefficients_scalar(math.sqrt(ax * ax + ay * ay + az * az))
        # a × Δv and a × (a × Δv)
        cx, cy, cz = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
        ccx, ccy, ccz = ay * cz - az * cy, az * cx - ax * cz, ax * cy - ay * cx
        gvx, gvy, gvz = vx + f2 * cx + f3 * ccx, vy + f2 * cy + f3 * ccy, vz + f2 * cz + f3 * ccz
        grx = 0.5 * vx + f3 * cx + f4 * ccx
        gry = 0.5 * vy + f3 * cy + f4 * ccy
        grz = 0.5 * vz + f3 * cz + f4 * ccz
        # S += W T + Γ G_R Δv T (uses W before its update), W += Γ G_V Δv.
        sx += t_gyr * (wx + g00 * grx + g01 * gry + g02 * grz)
        sy += t_gyr * (wy + g10 * grx + g11 * gry + g12 * grz)
        sz += t_gyr * (wz + g20 * grx + g21 * gry + g22 * grz)
        wx += g00 * gvx + g01 * gvy + g02 * gvz
        wy += g10 * gvx + g11 * gvy + g12 * gvz
        wz += g20 * gvx + g21 * gvy + g22 * gvz
        # Γ ← Γ G_C, G_C = I + f1 [a×] + f2 [a×]².
        xx, yy, zz = ax * ax, ay * ay, az * az
        c00 = 1.0 - f2 * (yy + zz)
        c11 = 1.0 - f2 * (xx + zz)
        c22 = 1.0 - f2 * (xx + yy)
        c01 = -f1 * az + f2 * ax * ay
        c10 = f1 * az + f2 * ax * ay
        c02 = f1 * ay + f2 * ax * az
        c20 = -f1 * ay + f2 * ax * az
        c12 = -f1 * ax + f2 * ay * az
        c21 = f1 * ax + f2 * ay * az
        g00, g01, g02 = (
            g00 * c00 + g01 * c10 + g02 * c20,
            g00 * c01 + g01 * c11 + g02 * c21,
            g00 * c02 + g01 * c12 + g02 * c22,
        )
        g10, g11, g12 = (
            g10 * c00 + g11 * c10 + g12 * c20,
            g10 * c01 + g11 * c11 + g12 * c21,
            g10 * c02 + g11 * c12 + g12 * c22,
        )
        g20, g21, g22 = (
            g20 * c00 + g21 * c10 + g22 * c20,
            g20 * c01 + g21 * c11 + g22 * c21,
            g20 * c02 + g21 * c12 + g22 * c22,
        )
    gam[0, 0], gam[0, 1], gam[0, 2] = g00, g01, g02
    gam[1, 0], gam[1, 1], gam[1, 2] = g10, g11, g12
    gam[2, 0], gam[2, 1], gam[2, 2] = g20, g21, g22
    w[0], w[1], w[2] = wx, wy, wz
    s[0], s[1], s[2] = sx, sy, sz


@_jit
def _gravitation(x, y, z, model):
    """docs/interface.md §1 gravitation (mass attraction) at ``(x, y, z)`` in E or E0, m/s²."""
    r2 = x * x + y * y + z * z
    m = -GM_WGS84 / (r2 * math.sqrt(r2))
    if model == 0:
        k = 1.5 * J2_WGS84 * A_WGS84 * A_WGS84 / r2
        zz = 5.0 * z * z / r2
        fxy = m * (1.0 + k * (1.0 - zz))
        return fxy * x, fxy * y, m * (1.0 + k * (3.0 - zz)) * z
    return m * x, m * y, m * z


@_jit
def exact_kernel(r0, v0, c0, lo, dalpha, dv, t_gyr, n, p, model):
    """All ``T_nav`` cycles of the ``exact`` mode in the inertial frame E0 of the navigator.

    ``r0`` (K+1, 3) position ``R^E0`` (m), ``v0`` (K+1, 3) inertial velocity ``V^E0`` (m/s),
    ``c0`` (K+1, 3, 3) ``C_B^E0``; row 0 is the state at the start, rows 1..K are written.
    ``lo`` (6,): the low-order parts of R and V (compensated summation, Kahan), carried in/out,
    so that adding centimetre increments to 6.4e6 m does not accumulate rounding.

    Cycle k (``T = N T_gyr``):

    * fast (``T_gyr``): :func:`exact_fast_kernel` → ``Γ, W, S`` in the body frame ``B_k``;
    * intermediate (``T_int = T / P``): gravitation ``∫g``, ``∫∫g`` by the trapezoid rule of
      docs/interface.md §3 on P sub-steps, at positions of the cubic Hermite arc through the start
      state and
      a predicted end state (``g(R_k)`` held); in an inertial frame the Coriolis and
      transport-rate terms of (29) do not arise;
    * slow (``T``): ``R' = R + V T + C S + ∫∫g``, ``V' = V + C W + ∫g``, ``C' = C Γ`` with one
      orthonormalization step ``C ← C − ½ (C Cᵀ − I) C``. The Earth's (and the l frame's)
      rotation enters only when outputs are mapped to ECEF, in closed form.
    """
    cycles = r0.shape[0] - 1
    t_nav = n * t_gyr
    h = t_nav / p
    gam = np.empty((3, 3))
    w = np.empty(3)
    s = np.empty(3)
    cg = np.empty((3, 3))
    dr = np.empty(3)
    dvv = np.empty(3)
    for j in range(cycles):
        rx, ry, rz = r0[j, 0] + lo[0], r0[j, 1] + lo[1], r0[j, 2] + lo[2]
        vx, vy, vz = v0[j, 0] + lo[3], v0[j, 1] + lo[4], v0[j, 2] + lo[5]
        exact_fast_kernel(dalpha, dv, j * n, n, t_gyr, gam, w, s)
        c = c0[j]
        cwx = c[0, 0] * w[0] + c[0, 1] * w[1] + c[0, 2] * w[2]
        cwy = c[1, 0] * w[0] + c[1, 1] * w[1] + c[1, 2] * w[2]
        cwz = c[2, 0] * w[0] + c[2, 1] * w[1] + c[2, 2] * w[2]
        csx = c[0, 0] * s[0] + c[0, 1] * s[1] + c[0, 2] * s[2]
        csy = c[1, 0] * s[0] + c[1, 1] * s[1] + c[1, 2] * s[2]
        csz = c[2, 0] * s[0] + c[2, 1] * s[1] + c[2, 2] * s[2]
        # Predicted end state with g(R_k) held, for the Hermite arc.
        g0x, g0y, g0z = _gravitation(rx, ry, rz, model)
        hh = 0.5 * t_nav * t_nav
        px = rx + (vx * t_nav + csx + g0x * hh)
        py = ry + (vy * t_nav + csy + g0y * hh)
        pz = rz + (vz * t_nav + csz + g0z * hh)
        qx, qy, qz = vx + cwx + g0x * t_nav, vy + cwy + g0y * t_nav, vz + cwz + g0z * t_nav
        # Intermediate layer: trapezoid (docs/interface.md §3 form) on P sub-steps.
        dvx = dvy = dvz = 0.0
        drx = dry = drz = 0.0
        gpx, gpy, gpz = g0x, g0y, g0z
        k6 = h * h / 6.0
        for i in range(1, p + 1):
            u = i / p
            u2 = u * u
            u3 = u2 * u
            h00 = 2.0 * u3 - 3.0 * u2 + 1.0
            h10 = (u3 - 2.0 * u2 + u) * t_nav
            h01 = -2.0 * u3 + 3.0 * u2
            h11 = (u3 - u2) * t_nav
            gx, gy, gz = _gravitation(
                h00 * rx + h10 * vx + h01 * px + h11 * qx,
                h00 * ry + h10 * vy + h01 * py + h11 * qy,
                h00 * rz + h10 * vz + h01 * pz + h11 * qz,
                model,
            )
            drx += dvx * h + (gx + 2.0 * gpx) * k6
            dry += dvy * h + (gy + 2.0 * gpy) * k6
            drz += dvz * h + (gz + 2.0 * gpz) * k6
            dvx += 0.5 * (gx + gpx) * h
            dvy += 0.5 * (gy + gpy) * h
            dvz += 0.5 * (gz + gpz) * h
            gpx, gpy, gpz = gx, gy, gz
        # Slow layer: increments, then compensated addition to the carried R, V.
        dr[0] = vx * t_nav + csx + drx
        dr[1] = vy * t_nav + csy + dry
        dr[2] = vz * t_nav + csz + drz
        dvv[0] = cwx + dvx
        dvv[1] = cwy + dvy
        dvv[2] = cwz + dvz
        for a in range(3):
            y = dr[a] + lo[a]
            t = r0[j, a] + y
            lo[a] = y - (t - r0[j, a])
            r0[j + 1, a] = t
            y = dvv[a] + lo[3 + a]
            t = v0[j, a] + y
            lo[3 + a] = y - (t - v0[j, a])
            v0[j + 1, a] = t
        for a in range(3):
            for b in range(3):
                cg[a, b] = c[a, 0] * gam[0, b] + c[a, 1] * gam[1, b] + c[a, 2] * gam[2, b]
        # One orthonormalization step: C - ½ (C Cᵀ - I) C.
        out = c0[j + 1]
        for a in range(3):
            for b in range(3):
                acc = 0.0
                for m in range(3):
                    e = cg[a, 0] * cg[m, 0] + cg[a, 1] * cg[m, 1] + cg[a, 2] * cg[m, 2]
                    if a == m:
                        e -= 1.0
                    acc += e * cg[m, b]
                out[a, b] = cg[a, b] - 0.5 * acc
