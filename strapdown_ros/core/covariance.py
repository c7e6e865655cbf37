"""Linear error-state covariance of a free-inertial navigator along a known trajectory.

The navigation errors of a strapdown navigator on a local-level (NED) mechanization obey, to
first order, the phi-angle error equations (Savage 2000, *Strapdown Analytics* §12.2.1;
Titterton & Weston 2004 §12.3; Groves 2013 §14.2.4), with the errors of the computed quantities
(computed minus true):

* position, geodetic: ``δL̇ = δv_N / (R_N+h) - v_N δh / (R_N+h)²``,
  ``δλ̇ = δv_E / ((R_E+h) cos L) + v_E tan L δL / ((R_E+h) cos L) - v_E δh / ((R_E+h)² cos L)``,
  ``δḣ = -δv_D``, plus the terms of the radii's latitude derivatives (order e², kept here, in
  these and in ω_en);
* velocity: ``δv̇ = f^n × φ + C_b^n δf^b - (2ω_ie + ω_en) × δv - (2δω_ie + δω_en) × v + δg``;
* attitude (``Ĉ_b^n = (I - φ×) C_b^n``): ``φ̇ = -ω_in × φ + δω_in - C_b^n δω_ib^b``,

with ``ω_ie = Ω (cos L, 0, -sin L)``, ``ω_en = (v_E/(R_E+h), -v_N/(R_N+h), -v_E tan L/(R_E+h))``,
``ω_in = ω_ie + ω_en``, δω their first-order changes with (δL, δh, δv), and δg the gravity
model's change with (δL, δh) (its -2g/R δh term makes the vertical channel unstable).
Optional vertical damping on an external altitude, the loop of the navigator's paper mode:
``δḣ += -k1 δh``, ``δv̇_D += k2 δh``.

The sensor errors are those of :mod:`strapdown_ros.core.imu_errors` (body axes)::

    δω_ib^b = b_g + b_GM,g + b_RW,g + (S_g + M_g) ω + G f + n_g
    δf^b    = b_a + b_GM,a + b_RW,a + (S_a + M_a) f + n_a

carried as states: the per-run constants (bias = fixed + turn-on draw, the 3 scale factors and
6 misalignments of each triad, the 9 g-sensitivities) with zero dynamics, first-order
Gauss–Markov biases ``ḃ = -b/τ_c + w`` (steady state σ_GM) and rate random walks ``ḃ = K w``;
white noise drives φ and δv directly. Quantization (its error over any window is under one
quantum) and saturation are not modelled.

The state vector (:data:`STATE_NAMES`, 54 entries): δL, δλ, δh, δv (NED), φ (NED), b_GM,g,
b_GM,a, b_RW,g, b_RW,a, b_g, b_a, (s, m)_g, (s, m)_a, G. The mean propagates with the same
transition (fixed biases, scale factors, misalignments and G are the constants' means), the
covariance as ``P_{k+1} = Φ_k P_k Φ_kᵀ + Q_k``.

Discretization over a step (t_k, t_{k+1}] of IMU cycles c: the couplings of the constants are
the exact first-order sums over the cycles, ``Σ_c C_b^n(t_c) T`` for a bias and
``Σ_c C_b^n(t_c) D(Δα_c)`` for the scale factors and misalignments (D the 3×9 matrix with
``D(Δα) (s, m) = (diag(s) + M(m)) Δα``), so oscillating rates (vibration, a scanning mount)
need no sub-step; ``Φ_k = exp(A_k)`` by a 4th-order Taylor series of the step's ``A_k``
(‖A_k‖ ≲ 1e-3 at 20 Hz steps), ``Q_k`` by the trapezoidal rule ``(Φ Q_c Φᵀ + Q_c) Δt / 2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import OMEGA_IE, radii
from strapdown_ros.core.gravity import gravity_ned
from strapdown_ros.core.imu_errors import ImuErrorParameters, SensorErrors

__all__ = [
    "N_NAV",
    "N_STATES",
    "STATE_NAMES",
    "CovarianceResult",
    "PropagationSteps",
    "VerticalDampingGains",
    "error_matrix_design",
    "g_sensitivity_design",
    "gravity_partials",
    "initial_moments",
    "navigation_error_dynamics",
    "position_to_ned_jacobian",
    "propagate_covariance",
]


#: Navigation error states: δL, δλ (rad), δh (m), δv_NED (m/s), φ_NED (rad).
N_NAV = 9
_GM_G, _GM_A, _RW_G, _RW_A = 9, 12, 15, 18
_B_G, _B_A, _E_G, _E_A, _G = 21, 24, 27, 36, 45
N_STATES = 54
_PAIRS = ("xy", "xz", "yx", "yz", "zx", "zy")
#: Names of the 54 states, in order.
STATE_NAMES: tuple[str, ...] = (
    "dlat", "dlon", "dh", "dv_n", "dv_e", "dv_d", "phi_n", "phi_e", "phi_d",
    *(f"gm_gyro_{a}" for a in "xyz"), *(f"gm_accel_{a}" for a in "xyz"),
    *(f"rw_gyro_{a}" for a in "xyz"), *(f"rw_accel_{a}" for a in "xyz"),
    *(f"bias_gyro_{a}" for a in "xyz"), *(f"bias_accel_{a}" for a in "xyz"),
    *(f"sf_gyro_{a}" for a in "xyz"), *(f"mis_gyro_{p}" for p in _PAIRS),
    *(f"sf_accel_{a}" for a in "xyz"), *(f"mis_accel_{p}" for p in _PAIRS),
    *(f"g_sens_{i}{j}" for i in "xyz" for j in "xyz"),
)  # fmt: skip
assert len(STATE_NAMES) == N_STATES

# Off-diagonal positions [xy, xz, yx, yz, zx, zy] of the 6 misalignments (imu_errors' layout).
_OFF_DIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))


def _skew(v: F64) -> F64:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@dataclass(frozen=True)
class VerticalDampingGains:
    """Vertical-channel damping on an external altitude.

    ``δḣ -= k1 δh``, ``δv̇_D += k2 δh`` (k1 in 1/s, k2 in 1/s²), the navigator's stable-sign loop.
    """

    k1: float
    k2: float


def error_matrix_design(u: ArrayLike) -> F64:
    """D(u), (..., 3, 9): ``(diag(s) + M(m)) u = D(u) (s, m)``.

    For the 3 scale factors s and the 6 misalignments m in the layout [xy, xz, yx, yz, zx, zy]
    (row i, column j: axis i senses M_ij of axis j).
    """
    u = np.asarray(u, dtype=np.float64)
    d = np.zeros(u.shape[:-1] + (3, 9))
    for i in range(3):
        d[..., i, i] = u[..., i]
    for k, (i, j) in enumerate(_OFF_DIAG):
        d[..., i, 3 + k] = u[..., j]
    return d


def g_sensitivity_design(f: ArrayLike) -> F64:
    """(..., 3, 9): ``G f = design(f) vec(G)`` with vec row-major (G_xx, G_xy, …, G_zz)."""
    f = np.asarray(f, dtype=np.float64)
    d = np.zeros(f.shape[:-1] + (3, 9))
    for i in range(3):
        d[..., i, 3 * i : 3 * i + 3] = f
    return d


@dataclass(frozen=True)
class PropagationSteps:
    """What the error model needs per step k over (t_k, t_{k+1}] along the truth.

    Attributes
    ----------
    t : array (K+1,)
        Step boundaries (s); the outputs are at these times.
    lat, alt : arrays (K,)
        True geodetic latitude (rad) and altitude (m) in the step.
    v_ned : array (K, 3)
        True Earth-relative velocity (m/s, NED).
    f_ned : array (K, 3)
        Mean true specific force over the step, NED (m/s²): ``Σ_c C_b^n Δv_c / Δt``.
    c_sum : array (K, 3, 3)
        ``Σ_c C_b^n(t_c) T`` (s): how a constant body rate error becomes an NED angle.
    d_gyro, d_accel : arrays (K, 3, 9)
        ``Σ_c C_b^n(t_c) D(Δα_c)``, ``Σ_c C_b^n(t_c) D(Δv_c)`` (:func:`error_matrix_design`).
    d_gsens : array (K, 3, 9)
        ``Σ_c C_b^n(t_c) design(Δv_c)`` (:func:`g_sensitivity_design`).
    c_mid : array (K, 3, 3)
        ``C_b^n`` in the middle of the step (maps the white noises).
    """

    t: F64
    lat: F64
    alt: F64
    v_ned: F64
    f_ned: F64
    c_sum: F64
    d_gyro: F64
    d_accel: F64
    d_gsens: F64
    c_mid: F64

    def __post_init__(self) -> None:
        k = np.shape(self.t)[0] - 1
        shapes = {"lat": (k,), "alt": (k,), "v_ned": (k, 3), "f_ned": (k, 3), "c_sum": (k, 3, 3),
                  "d_gyro": (k, 3, 9), "d_accel": (k, 3, 9), "d_gsens": (k, 3, 9),
                  "c_mid": (k, 3, 3)}  # fmt: skip
        if k < 1 or not np.all(np.diff(self.t) > 0):
            raise ValueError("PropagationSteps.t: need at least 2 strictly increasing times")
        for name, shape in shapes.items():
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.shape != shape:
                raise ValueError(f"PropagationSteps.{name}: expected shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"PropagationSteps.{name}: non-finite values")

    @classmethod
    def from_cycles(
        cls,
        t: ArrayLike,
        cycles_per_step: int,
        lat: ArrayLike,
        alt: ArrayLike,
        v_ned: ArrayLike,
        c_b_n_mid: ArrayLike,
        dalpha: ArrayLike,
        dv: ArrayLike,
        period_s: float,
    ) -> PropagationSteps:
        """Steps of ``cycles_per_step`` IMU cycles from per-cycle truth and ideal increments.

        ``t`` (M+1,) cycle boundaries (s); ``lat``, ``alt``, ``v_ned`` (M+1,…) the truth at
        them; ``c_b_n_mid`` (M, 3, 3) the true attitude in the middle of each cycle; ``dalpha``,
        ``dv`` (M, 3) the ideal increments (body). M must be a multiple of ``cycles_per_step``.
        """
        t = np.asarray(t, dtype=np.float64)
        c = np.asarray(c_b_n_mid, dtype=np.float64)
        dalpha, dv = np.asarray(dalpha, dtype=np.float64), np.asarray(dv, dtype=np.float64)
        m, n = c.shape[0], int(cycles_per_step)
        if n < 1 or m % n or m < n:
            raise ValueError(f"{m} cycles are not a whole number (>= 1) of steps of {n}")
        k = m // n

        def per_step(a: F64) -> F64:
            return a.reshape((k, n) + a.shape[1:]).sum(axis=1)

        dv_n = np.einsum("mij,mj->mi", c, dv)
        mid = np.arange(k) * n + n // 2  # a cycle boundary in the step (its middle for even n)
        ends = np.arange(k + 1) * n
        lat, alt = np.asarray(lat, dtype=np.float64), np.asarray(alt, dtype=np.float64)
        v = np.asarray(v_ned, dtype=np.float64)
        t_steps = t[ends]
        return cls(
            t_steps,
            0.5 * (lat[ends[:-1]] + lat[ends[1:]]),
            0.5 * (alt[ends[:-1]] + alt[ends[1:]]),
            0.5 * (v[ends[:-1]] + v[ends[1:]]),
            per_step(dv_n) / np.diff(t_steps)[:, None],
            per_step(c) * period_s,
            per_step(c @ error_matrix_design(dalpha)),
            per_step(c @ error_matrix_design(dv)),
            per_step(c @ g_sensitivity_design(dv)),
            c[np.minimum(mid, m - 1)],
        )


def navigation_error_dynamics(
    lat: float,
    alt: float,
    v_ned: ArrayLike,
    f_ned: ArrayLike,
    gravity_model: str = "j2",
    damping: VerticalDampingGains | None = None,
    omega: float = OMEGA_IE,
    dg_dp: ArrayLike | None = None,
) -> F64:
    """F (9×9) of the navigation errors (δL, δλ, δh, δv_NED, φ_NED) (module docstring).

    At true latitude ``lat`` (rad), altitude ``alt`` (m), velocity ``v_ned`` (m/s) and specific
    force ``f_ned`` (m/s²). ``dg_dp`` (3×3): gravity's partials with respect to (δL, δλ, δh)
    (default :func:`gravity_partials`).
    """
    v = np.asarray(v_ned, dtype=np.float64)
    f = np.asarray(f_ned, dtype=np.float64)
    vn, ve, vd = v
    r_n, r_e = (float(r) for r in radii(lat))
    rn, re = r_n + alt, r_e + alt
    sl, cl, tl = np.sin(lat), np.cos(lat), np.tan(lat)
    w_ie = omega * np.array([cl, 0.0, -sl])
    rho = np.array([ve / re, -vn / rn, -ve * tl / re])
    # Partials of ω_ie and ω_en with respect to (δL, δλ, δh) and δv.
    dwie_dp = np.zeros((3, 3))
    dwie_dp[:, 0] = omega * np.array([-sl, 0.0, -cl])
    # Radii's latitude derivatives (central differences, 1e-6 rad).
    rn_l, re_l = (np.asarray(radii(lat + 1e-6)) - np.asarray(radii(lat - 1e-6))) / 2e-6
    drho_dp = np.zeros((3, 3))
    drho_dp[:, 0] = [-ve * re_l / re**2, vn * rn_l / rn**2,
                     -ve / (re * cl**2) + ve * tl * re_l / re**2]  # fmt: skip
    drho_dp[:, 2] = [-ve / re**2, vn / rn**2, ve * tl / re**2]
    drho_dv = np.array([[0.0, 1.0 / re, 0.0], [-1.0 / rn, 0.0, 0.0], [0.0, -tl / re, 0.0]])
    if dg_dp is None:
        dg_dp = gravity_partials(lat, alt, gravity_model)

    F = np.zeros((N_NAV, N_NAV))
    # Position.
    F[0, 3] = 1.0 / rn
    F[0, 0] = -vn * rn_l / rn**2
    F[0, 2] = -vn / rn**2
    F[1, 4] = 1.0 / (re * cl)
    F[1, 0] = ve * tl / (re * cl) - ve * re_l / (re**2 * cl)
    F[1, 2] = -ve / (re**2 * cl)
    F[2, 5] = -1.0
    # Velocity: f × φ - (2ω_ie + ω_en) × δv - (2δω_ie + δω_en) × v + δg.
    vx = _skew(v)
    F[3:6, 6:9] = _skew(f)
    F[3:6, 3:6] = -_skew(2.0 * w_ie + rho) + vx @ drho_dv
    F[3:6, 0:3] = vx @ (2.0 * dwie_dp + drho_dp) + dg_dp
    # Attitude: -ω_in × φ + δω_in.
    F[6:9, 6:9] = -_skew(w_ie + rho)
    F[6:9, 0:3] = dwie_dp + drho_dp
    F[6:9, 3:6] = drho_dv
    if damping is not None:
        F[2, 2] -= damping.k1
        F[5, 2] += damping.k2
    return F


def gravity_partials(lat: ArrayLike, alt: ArrayLike, gravity_model: str = "j2") -> F64:
    """(…, 3, 3): ∂g_NED / ∂(L, λ, h) by central differences of ``gravity_ned``.

    Steps 1e-6 rad and 1 m; the λ column is zero (the models are zonal).
    """
    lat, alt = np.asarray(lat, dtype=np.float64), np.asarray(alt, dtype=np.float64)
    dl, dh = 1e-6, 1.0
    out = np.zeros(np.broadcast(lat, alt).shape + (3, 3))
    out[..., :, 0] = (gravity_ned(lat + dl, alt, gravity_model)
                      - gravity_ned(lat - dl, alt, gravity_model)) / (2 * dl)  # fmt: skip
    out[..., :, 2] = (gravity_ned(lat, alt + dh, gravity_model)
                      - gravity_ned(lat, alt - dh, gravity_model)) / (2 * dh)  # fmt: skip
    return out


def position_to_ned_jacobian(lat: ArrayLike, alt: ArrayLike) -> F64:
    """(…, 3, 3): ``δr_NED = J (δL, δλ, δh)`` (m) at the true latitude and altitude."""
    lat, alt = np.asarray(lat, dtype=np.float64), np.asarray(alt, dtype=np.float64)
    r_n, r_e = radii(lat)
    j = np.zeros(lat.shape + (3, 3))
    j[..., 0, 0] = r_n + alt
    j[..., 1, 1] = (r_e + alt) * np.cos(lat)
    j[..., 2, 2] = -1.0
    return j


def _sensor_moments(s: SensorErrors, with_g: bool) -> tuple[F64, F64]:
    """Means and variances of one triad's constants: bias 3, (s, m) 9, [G 9]."""
    mean = [s.bias, s.scale_factor, [s.misalignment[i, j] for i, j in _OFF_DIAG]]
    var = [s.turn_on_bias_sigma**2, s.scale_factor_sigma**2,
           [s.misalignment_sigma[i, j] ** 2 for i, j in _OFF_DIAG]]  # fmt: skip
    if with_g:
        mean.append(s.g_sensitivity.ravel())
        var.append(np.zeros(9))
    return np.concatenate(mean), np.concatenate(var)


def initial_moments(
    params: ImuErrorParameters,
    nav_mean: ArrayLike | None = None,
    nav_cov: ArrayLike | None = None,
) -> tuple[F64, F64]:
    """Mean (54,) and covariance (54, 54) at the start.

    Navigation errors: ``nav_mean`` (9,) and ``nav_cov`` (9, 9) (default zero: started from
    truth); Gauss–Markov biases stationary N(0, σ_GM²); random walks 0; constants N(fixed, σ²)
    (turn-on bias, scale factor, misalignment draws), g-sensitivity its fixed value.
    """
    mean = np.zeros(N_STATES)
    cov = np.zeros((N_STATES, N_STATES))
    if nav_mean is not None:
        mean[:N_NAV] = nav_mean
    if nav_cov is not None:
        cov[:N_NAV, :N_NAV] = nav_cov
    g, a = params.gyro, params.accel
    idx = np.arange(N_STATES)
    var = np.zeros(N_STATES)
    var[_GM_G:_GM_G + 3] = g.gauss_markov_sigma**2
    var[_GM_A:_GM_A + 3] = a.gauss_markov_sigma**2
    gm, gv = _sensor_moments(g, with_g=True)
    am, av = _sensor_moments(a, with_g=False)
    mean[_B_G:_B_G + 3], var[_B_G:_B_G + 3] = gm[:3], gv[:3]
    mean[_E_G:_E_G + 9], var[_E_G:_E_G + 9] = gm[3:12], gv[3:12]
    mean[_G:_G + 9] = gm[12:]
    mean[_B_A:_B_A + 3], var[_B_A:_B_A + 3] = am[:3], av[:3]
    mean[_E_A:_E_A + 9], var[_E_A:_E_A + 9] = am[3:12], av[3:12]
    cov[idx, idx] += var
    return mean, cov


@dataclass(frozen=True)
class CovarianceResult:
    """Propagated moments at the step boundaries ``t`` (K+1,).

    ``mean`` (K+1, 54) of the whole state, ``cov`` (K+1, 9, 9) of the navigation errors
    (δL, δλ, δh, δv, φ), ``final_cov`` (54, 54) of the whole state at the end; the navigation
    errors in the units of the navigator's error topics by :meth:`navigation_moments`.
    """

    t: F64
    mean: F64
    cov: F64
    lat: F64
    alt: F64
    final_cov: F64

    def navigation_moments(self) -> tuple[F64, F64]:
        """Mean and standard deviation (K+1, 9) of (δr_NED m, δv_NED m/s, φ_NED rad)."""
        j = np.zeros((self.t.shape[0], N_NAV, N_NAV))
        j[:, 0:3, 0:3] = position_to_ned_jacobian(self.lat, self.alt)
        j[:, 3:9, 3:9] = np.eye(6)
        mean = np.einsum("kij,kj->ki", j, self.mean[:, :N_NAV])
        cov = j @ self.cov @ np.swapaxes(j, 1, 2)
        return mean, np.sqrt(np.maximum(np.einsum("kii->ki", cov), 0.0))


def _expm_taylor(a: F64, order: int = 4) -> F64:
    out = np.eye(a.shape[0])
    term = np.eye(a.shape[0])
    for k in range(1, order + 1):
        term = term @ a / k
        out = out + term
    return out


def propagate_covariance(
    steps: PropagationSteps,
    params: ImuErrorParameters,
    *,
    mean0: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
    gravity_model: str = "j2",
    damping: VerticalDampingGains | None = None,
) -> CovarianceResult:
    """Propagate the mean and covariance of the 54 states along ``steps`` (module docstring).

    ``mean0``, ``cov0``: start moments (default :func:`initial_moments` of ``params``).
    """
    m0, p0 = initial_moments(params)
    mean = m0 if mean0 is None else np.asarray(mean0, dtype=np.float64)
    cov = p0 if cov0 is None else np.asarray(cov0, dtype=np.float64)
    if mean.shape != (N_STATES,) or cov.shape != (N_STATES, N_STATES):
        raise ValueError(f"mean0/cov0: expected shapes ({N_STATES},), ({N_STATES}, {N_STATES})")
    g, a = params.gyro, params.accel
    tau_g, tau_a = g.correlation_time_s, a.correlation_time_s
    k_steps = steps.t.shape[0] - 1
    means = np.empty((k_steps + 1, N_STATES))
    covs = np.empty((k_steps + 1, N_NAV, N_NAV))
    means[0], covs[0] = mean, cov[:N_NAV, :N_NAV]
    dts = np.diff(steps.t)
    lat_out = np.concatenate([[steps.lat[0]], steps.lat])
    alt_out = np.concatenate([[steps.alt[0]], steps.alt])
    dg = gravity_partials(steps.lat, steps.alt, gravity_model)
    nq = _RW_A + 3  # the noise enters states [0, nq)
    for k in range(k_steps):
        dt = float(dts[k])
        A = np.zeros((N_STATES, N_STATES))
        A[:N_NAV, :N_NAV] = dt * navigation_error_dynamics(
            steps.lat[k], steps.alt[k], steps.v_ned[k], steps.f_ned[k], gravity_model, damping,
            dg_dp=dg[k],
        )
        cs = steps.c_sum[k]
        # φ̇ = … - C δω_ib^b;  δv̇ = … + C δf^b.
        for col in (_GM_G, _RW_G, _B_G):
            A[6:9, col:col + 3] = -cs
        for col in (_GM_A, _RW_A, _B_A):
            A[3:6, col:col + 3] = cs
        A[6:9, _E_G:_E_G + 9] = -steps.d_gyro[k]
        A[6:9, _G:_G + 9] = -steps.d_gsens[k]
        A[3:6, _E_A:_E_A + 9] = steps.d_accel[k]
        gm = np.arange(3)
        A[_GM_G + gm, _GM_G + gm] = -dt / tau_g
        A[_GM_A + gm, _GM_A + gm] = -dt / tau_a
        phi = _expm_taylor(A)
        qc = np.zeros((N_STATES, N_STATES))  # continuous noise, times dt
        c = steps.c_mid[k]
        qc[6:9, 6:9] = c @ np.diag(g.white**2) @ c.T * dt
        qc[3:6, 3:6] = c @ np.diag(a.white**2) @ c.T * dt
        qc[_GM_G + gm, _GM_G + gm] = 2.0 * g.gauss_markov_sigma**2 / tau_g * dt
        qc[_GM_A + gm, _GM_A + gm] = 2.0 * a.gauss_markov_sigma**2 / tau_a * dt
        qc[_RW_G + gm, _RW_G + gm] = g.random_walk**2 * dt
        qc[_RW_A + gm, _RW_A + gm] = a.random_walk**2 * dt
        mean = phi @ mean
        pq = phi[:, :nq]
        cov = phi @ cov @ phi.T
        cov += 0.5 * (pq @ qc[:nq, :nq] @ pq.T)
        cov += 0.5 * qc
        cov = 0.5 * (cov + cov.T)
        means[k + 1], covs[k + 1] = mean, cov[:N_NAV, :N_NAV]
    return CovarianceResult(steps.t.copy(), means, covs, lat_out, alt_out, cov)
