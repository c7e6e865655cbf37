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


__all__ = ["GRAVITY_CODES", "HAVE_NUMBA", "fast_cycle_kernel", "multirate_kernel"]

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
    lat, lon, alt, u0, q0, dalpha, dv, t_gyr, n, p, model, normalize, table1, pos, vel, quat
):
    """All ``T_nav`` cycles of Table 1 in one call.

    Fills ``pos`` (K+1, 3) = (λ, Λ, h), ``vel`` (K+1, 3) and ``quat`` (K+1, 4) with
    K = ``pos.shape[0] - 1`` cycles of ``n`` increments each; ``model`` is a
    :data:`GRAVITY_CODES` value.
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
        lat, lon, alt = lat + t_nav * lat_dot, lon + t_nav * lon_dot, alt - t_nav * uz
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
