"""Velocity and attitude matching: the master's state carried to the slave (E0 frame).

Notation (docs/transfer_alignment.md §2): master (reference IMU) attitude ``C_r = C_Br^E0``,
inertial velocity ``V_r``; slave (variation IMU) ``C_s = C_Bs^E0``, ``V_s``; mounting
``M = C_Bs^Br``, lever arm ``l`` (Br FRD, m). A fixed mount gives ``C_s = C_r M`` (Savage 2020
eq. (5)) and ``R_s = R_r + C_r l`` (eqs. (6)–(7) with s = 0), so

    V_s = V_r + d(C_r l)/dt = V_r + C_r (ω_ib^Br × l)                         (velocity)

which the simulation meets at even cycles in the form of eq. (10),
``V_s,m = V_r,m + (C_r,m+1 − C_r,m−1) l / 2T``. The filter's error states (estimate minus
truth): ``δV``, ``φ`` (``Ĉ_s = exp([φ×]) C_s``), the mounting misalignment ``μ``
(``M̂ = exp([μ×]) M``, Br axes) and the lever-arm error ``δl``.

* **Velocity matching** (Kain & Cloutier 1989; Groves 2013 §15.1.1):
  ``z = V_r``, ``h(x̂) = V̂_s − D l̂`` with ``D = (C_r,m+1 − C_r,m−1)/2T`` (``central_difference``)
  or ``D = C_r [ω_ib×]`` (``rate``, ``ω_ib`` the master's body rate); ``H_δV = I``,
  ``H_δl = −D``.
* **Attitude matching**: ``z = C_r``, ``h(x̂) = Ĉ_s M̂ᵀ``, innovation the rotation vector
  ``ν = rotvec(C_r M̂ Ĉ_sᵀ) ≈ −(φ − C_r μ)``; ``H_φ = I``, ``H_μ = −C_r``.

**Scanning platform** (docs/transfer_alignment.md §5). The slave sits on a platform turning by
``C_scan(θ) = Rot(a, θ)`` about the Bvar axis ``a`` (a sweep) with a displacement ``d`` (Bvar
FRD, m) on it: ``C_Bs^Br = M C_scan(θ)`` (eq. (5)) and ``S = C_r (l + M C_scan d)`` (eq. (7)),
so ``V_s,m = V_r,m + (S_m+1 − S_m−1)/2T`` (eq. (10)). The slave reads ``θ̃`` from a resolver
and carries ``Ŝ_j = C_r,j (l̂ + w_j)``, ``w_j = M̂ Ĉ_scan(θ̃_j) d`` (Br):

* velocity: ``h = V̂_s − D l̂ − e``, ``e = (C_r,m+1 w_m+1 − C_r,m−1 w_m−1)/2T``; the μ
  Jacobian ``H_μ = (C_r,m+1 [w_m+1×] − C_r,m−1 [w_m−1×])/2T`` (``M̂ → exp([δμ×]) M̂`` moves
  ``w_j`` by ``−[w_j×] δμ``);
* attitude: ``h = Ĉ_s (M̂ Ĉ_scan)ᵀ``, ``ν = rotvec(C_r M̂ Ĉ_scan Ĉ_sᵀ)``, ``H_φ = I``,
  ``H_μ = −C_r`` as for the fixed mount.

A resolver error ``ε`` (``θ̃ = θ + ε``) turns the platform by ``Rot(a, ε)``: in the attitude
innovation it adds ``C_r M a ε`` (exactly a mounting error ``ε M a``: rotations about one axis
commute), in ``Ŝ_j`` it adds ``C_r,j M C_scan,j (a × d) ε_j``; white noise of σ per reading is
measurement noise of those gains (:func:`resolver_noise_velocity`,
:func:`resolver_noise_attitude`).
"""

from __future__ import annotations

import numpy as np

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm, skew

__all__ = [
    "attitude_jacobian_at_estimate",
    "attitude_matching",
    "carried_position",
    "displacement_transport",
    "platform_offset",
    "resolver_noise_attitude",
    "resolver_noise_velocity",
    "scan_angle",
    "scan_dcm",
    "start_velocity",
    "transport_matrix",
    "velocity_matching",
]


def transport_matrix(kind: str, c_prev: F64, c_mid: F64, c_next: F64, w_ib: F64,
                     period_s: float) -> F64:  # fmt: skip
    """``D`` (3, 3) with ``V_s = V_r + D l``: central difference of eq. (10) or ``C_r [ω×]``.

    ``c_prev``, ``c_mid``, ``c_next``: master attitude at cycles m−1, m, m+1; ``w_ib`` the
    master's inertial body rate (rad/s, Br FRD); ``period_s`` the IMU period T.
    """
    if kind == "central_difference":
        return (np.asarray(c_next) - np.asarray(c_prev)) / (2.0 * period_s)
    if kind == "rate":
        return np.asarray(c_mid) @ skew(np.asarray(w_ib))
    raise ValueError(f"unknown velocity transport {kind!r}")


def start_velocity(c0: F64, c1: F64, c2: F64, v0: F64, lever: F64, period_s: float,
                   platform: tuple[F64, F64, F64] | None = None) -> F64:  # fmt: skip
    """Slave velocity at cycle 0: ``V_r + (−3 S_0 + 4 S_1 − S_2)/2T``, ``S = C_r l``.

    The second-order one-sided difference the variation uses at its first cycle. ``platform``:
    the displacement on a scanning platform at cycles 0, 1, 2, ``w_j`` (Br, m,
    :func:`platform_offset`): then ``S_j = C_r,j (l + w_j)`` (eq. (7)).
    """
    offsets = (lever, lever, lever) if platform is None else (
        tuple(np.asarray(lever) + np.asarray(w) for w in platform))  # fmt: skip
    s0, s1, s2 = (np.asarray(c) @ u for c, u in zip((c0, c1, c2), offsets, strict=True))
    return np.asarray(v0) + (-3.0 * s0 + 4.0 * s1 - s2) / (2.0 * period_s)


def carried_position(r_ref: F64, c_ref: F64, lever: F64) -> F64:
    """``R_s = R_r + C_r l`` (eqs. (6)–(7), no displacement)."""
    return np.asarray(r_ref) + np.asarray(c_ref) @ np.asarray(lever)


def velocity_matching(v_hat: F64, v_master: F64, d: F64, lever_hat: F64, n: int, i_v: int,
                      i_l: int, platform: tuple[F64, F64, int] | None = None,
                      ) -> tuple[F64, F64]:  # fmt: skip
    """Innovation ``ν = V_r − (V̂_s − D l̂ − e)`` (3,) and H (3, n).

    ``i_v``: index of δV; ``i_l``: index of δl (−1: no lever-arm states). ``platform``: the
    displacement term of a scanning platform, ``(e, H_μ, i_mu)`` from
    :func:`displacement_transport` (None: a fixed mount without displacement, ``e = 0``).
    """
    carried = d @ np.asarray(lever_hat)
    if platform is not None:
        carried = carried + platform[0]
    nu = np.asarray(v_master) - (np.asarray(v_hat) - carried)
    h = np.zeros((3, n))
    h[:, i_v : i_v + 3] = np.eye(3)
    if i_l >= 0:
        h[:, i_l : i_l + 3] = -d
    if platform is not None:
        _, h_mu, i_mu = platform
        h[:, i_mu : i_mu + 3] = h_mu
    return nu, h


def attitude_matching(c_hat: F64, c_master: F64, mount_hat: F64, n: int, i_phi: int,
                      i_mu: int, at_estimate: bool = False) -> tuple[F64, F64]:  # fmt: skip
    """Innovation ``ν = rotvec(C_r M̂ Ĉ_sᵀ)`` (3,) and H (3, n) (``H_φ = I``, ``H_μ = −C_r``).

    ``at_estimate``: ``H_μ = −ĥ``, ``ĥ = Ĉ_s M̂ᵀ`` the master attitude the estimate predicts,
    instead of ``−C̃_r``, the measured one (:func:`attitude_jacobian_at_estimate`).
    """
    c_master = np.asarray(c_master)
    nu = rotvec_from_dcm(c_master @ np.asarray(mount_hat) @ np.asarray(c_hat).T)
    h = np.zeros((3, n))
    h[:, i_phi : i_phi + 3] = np.eye(3)
    h[:, i_mu : i_mu + 3] = (-attitude_jacobian_at_estimate(c_hat, mount_hat) if at_estimate
                             else -c_master)  # fmt: skip
    return np.asarray(nu, dtype=np.float64), h


def attitude_jacobian_at_estimate(c_hat: F64, mount_hat: F64) -> F64:
    """``ĥ = Ĉ_s M̂ᵀ`` (3, 3): attitude matching's ``−H_μ`` at the estimate (Br to E0).

    The EKF's measurement Jacobian is ``∂h/∂x`` at the predicted state (Bar-Shalom, Li &
    Kirubarajan 2001, *Estimation with Applications to Tracking and Navigation*, §10.3): with
    ``h(x̂) = Ĉ_s M̂ᵀ`` and ``M̂ → exp([δμ×]) M̂``, ``h → ĥ exp(−[δμ×]) = exp(−[(ĥ δμ)×]) ĥ``, so
    ``H_μ = −ĥ`` (``H_φ = I``). Then ``(φ, μ) = (u, ĥᵀ u)`` — slave and mounting turned together,
    which no attitude measurement sees — is in H's nullspace at every epoch, as the
    observability-constrained EKF asks of its Jacobians (Huang, Mourikis & Roumeliotis 2010,
    "Observability-based rules for designing consistent EKF SLAM estimators", IJRR 29(5)).
    ``H_μ = −C̃_r`` with the *measured* master attitude ``C̃_r = C_r exp([ε×])`` instead turns
    that direction by the master's noise ε at every epoch: the filter takes ``C_r (ε × μ)`` for
    signal (about 2 rad⁻² of information per epoch on each component of μ, whatever σ_ε), which
    the measurement does not carry (docs/transfer_alignment.md §6). ``c_hat`` ``Ĉ_s`` (slave
    body to E0), ``mount_hat`` the nominal ``C_Bs^Br`` (``M̂``, or ``M̂ Ĉ_scan`` on a platform).
    """
    return np.asarray(c_hat) @ np.asarray(mount_hat).T


# -- the scanning platform -----------------------------------------------------------------------


def scan_dcm(axis: F64, angle: float) -> F64:
    """``C_scan = Rot(a, θ)`` (3, 3): the platform's turn by ``angle`` (rad) about ``axis``.

    ``axis`` a (unit, Bvar FRD): a sweep (docs/theory/offsets.md).
    """
    return dcm_from_rotvec(np.asarray(axis, dtype=np.float64) * float(angle))


def scan_angle(c_bvar_bref: F64, mount: F64, axis: F64) -> F64:
    """True scan angles θ (rad, (N,)) of a single-axis platform: ``a · rotvec(Mᵀ C_Bvar^Bref)``.

    ``c_bvar_bref`` (N, 3, 3) the offsets the generator used (``M C_scan`` smoothed by
    Savage 2020 Appendix D: for a scan about one axis the smoothing ``C_scan G_C(γ)`` has γ
    along that axis, so the result is again a turn about ``a``, by the smoothed angle);
    ``mount`` M (3, 3) the zero-scan mounting; ``axis`` a (unit, Bvar). Valid for |θ| < π.
    """
    rel = np.swapaxes(np.asarray(mount), -1, -2) @ np.asarray(c_bvar_bref)
    return np.asarray(rotvec_from_dcm(rel) @ np.asarray(axis), dtype=np.float64)


def platform_offset(mount_hat: F64, c_scan: F64, displacement: F64) -> F64:
    """``w = M̂ Ĉ_scan d`` (m, Br FRD): the displacement on the platform in reference body axes.

    The second term of Savage 2020 eq. (7) before ``C_r``.
    """
    return np.asarray(mount_hat) @ (np.asarray(c_scan) @ np.asarray(displacement))


def displacement_transport(c_prev: F64, c_next: F64, w_prev: F64, w_next: F64,
                           period_s: float) -> tuple[F64, F64]:  # fmt: skip
    """The displacement's part of eq. (10) and its μ Jacobian.

    ``e = (C_r,m+1 w_m+1 − C_r,m−1 w_m−1)/2T`` (m/s, E0) and
    ``H_μ = ∂h/∂μ = (C_r,m+1 [w_m+1×] − C_r,m−1 [w_m−1×])/2T`` (3, 3): with
    ``h = V̂_s − D l̂ − e`` and ``M̂ → exp([δμ×]) M̂``, ``w_j → w_j − [w_j×] δμ``.
    ``c_prev``, ``c_next``: master attitude ``C_Br^E0`` at m−1, m+1; ``w_prev``, ``w_next``:
    :func:`platform_offset` there (Br); ``period_s`` the IMU period T.
    """
    cp, cn = np.asarray(c_prev), np.asarray(c_next)
    k = 1.0 / (2.0 * period_s)
    e = (cn @ np.asarray(w_next) - cp @ np.asarray(w_prev)) * k
    h_mu = (cn @ skew(np.asarray(w_next)) - cp @ skew(np.asarray(w_prev))) * k
    return e, h_mu


def resolver_noise_velocity(c_prev: F64, c_next: F64, mount_hat: F64, cs_prev: F64,
                            cs_next: F64, axis: F64, displacement: F64, sigma_rad: float,
                            period_s: float) -> F64:  # fmt: skip
    """Velocity-matching noise (3, 3, (m/s)²) of the resolver's white noise σ (rad per reading).

    A reading error ``ε_j`` turns ``Ŝ_j`` by ``g_j ε_j``, ``g_j = C_r,j M̂ Ĉ_scan,j (a × d)``,
    so ``e`` by ``(g_m+1 ε_m+1 − g_m−1 ε_m−1)/2T``: ``R = σ² (g_m+1 g_m+1ᵀ + g_m−1 g_m−1ᵀ)/4T²``
    (independent readings).
    """
    ad = np.cross(np.asarray(axis), np.asarray(displacement))
    g = [np.asarray(c) @ (np.asarray(mount_hat) @ (np.asarray(cs) @ ad))
         for c, cs in ((c_prev, cs_prev), (c_next, cs_next))]  # fmt: skip
    return sigma_rad**2 * (np.outer(g[0], g[0]) + np.outer(g[1], g[1])) / (2.0 * period_s) ** 2


def resolver_noise_attitude(c_master: F64, mount_hat: F64, axis: F64, sigma_rad: float) -> F64:
    """Attitude-matching noise (3, 3, rad²) of the resolver's white noise: ``σ² q qᵀ``.

    ``q = C_r M̂ a``: the reading error is a turn about ``a``, seen in E0.
    """
    q = np.asarray(c_master) @ (np.asarray(mount_hat) @ np.asarray(axis))
    return sigma_rad**2 * np.outer(q, q)
