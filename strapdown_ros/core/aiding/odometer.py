"""Wheel odometer: speed of a wheel contact point along the body x axis, plus sensor errors.

Truth: ``v_c^B = C_E^B v^E + ω_eb^B × l`` (the contact point at lever arm ``l``, body FRD),
speed ``u = v_c^B · x``. Errors: scale factor (fixed + drawn per run), white noise of the
rolling wheel (its σ bounded by the speed: a wheel at rest neither slips nor turns), then
quantization by the encoder's pulses per metre with the residual carried (the distance
counted over any span differs from the distance rolled by less than one pulse). A vehicle at
rest therefore counts no pulse and reports exactly zero speed, as an encoder does. See
``docs/aiding.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.aiding.common import check_period, mat_t_vec, rate_cross_lever, sensor_rng
from strapdown_ros.core.array_types import F64

__all__ = [
    "ODOMETER_NORMALS_PER_EPOCH",
    "OdometerErrorModel",
    "OdometerErrors",
    "contact_point_speed",
    "contact_point_velocity",
]


#: Standard normals per epoch: white 1.
ODOMETER_NORMALS_PER_EPOCH = 1


def contact_point_velocity(
    v_e: ArrayLike, c_b_e: ArrayLike, omega_eb_b: ArrayLike, lever_arm_b: ArrayLike
) -> F64:
    """Earth-relative velocity (m/s, body FRD) of the point at ``lever_arm_b`` (m, FRD).

    ``C_E^B v^E + ω_eb^B × l`` with ``c_b_e = C_FRD^E`` (n, 3, 3), ``v_e`` (n, 3) ECEF and
    ``omega_eb_b`` (n, 3) rad/s FRD.
    """
    v = np.asarray(v_e, dtype=np.float64)
    c = np.asarray(c_b_e, dtype=np.float64)
    return mat_t_vec(c, v) + rate_cross_lever(omega_eb_b, lever_arm_b)


def contact_point_speed(
    v_e: ArrayLike, c_b_e: ArrayLike, omega_eb_b: ArrayLike, lever_arm_b: ArrayLike
) -> F64:
    """Speed (m/s) along body x of the contact point (see :func:`contact_point_velocity`)."""
    return contact_point_velocity(v_e, c_b_e, omega_eb_b, lever_arm_b)[:, 0]


@dataclass(frozen=True)
class OdometerErrors:
    """Odometer error parameters."""

    scale_factor: float = 0.0  #: fixed scale-factor error (dimensionless; 1e-3 = 1000 ppm)
    scale_factor_sigma: float = 0.0  #: σ of a scale-factor error drawn per run
    white: float = 0.0  #: white noise σ, m/s
    pulses_per_m: float = 0.0  #: encoder pulses per metre (0: no quantization)

    def variance(self, period_s: float) -> float:
        """Variance of one speed's random error ((m/s)²) rolling at |u| ≥ σ_w.

        white² + (q/P)²/6, q = 1/pulses_per_m; below σ_w an upper bound, at rest the error is 0.

        (The quantization error of a speed is the difference of two residuals uniform over
        one pulse, divided by the epoch period P.)
        """
        return self.white**2 + self.quantization_variance(period_s)

    def quantization_variance(self, period_s: float) -> float:
        """Variance ((m/s)²) of the quantization error of one speed: ``(q/P)²/6``.

        The error is ``(ρ_{k-1} − ρ_k) / P``, ρ the count's residual distance, uniform over one
        pulse q (variance q²/12 each, successive errors correlated −½).
        """
        q = 1.0 / self.pulses_per_m if self.pulses_per_m > 0 else 0.0
        return (q / period_s) ** 2 / 6.0


class OdometerErrorModel:
    """Seeded odometer errors at consecutive epochs (chunk-invariant).

    1 normal at construction (scale factor), :data:`ODOMETER_NORMALS_PER_EPOCH` per epoch.

    The wheel's speed is ``ũ = (1 + s) u + min(σ_w, |u|) ξ``: the white noise stands for slip
    and tread deformation, which exist only while the wheel rolls, so its σ is bounded by the
    speed (zero at rest, the full σ_w from |u| = σ_w up). The measured speed of an epoch is the
    mean over the epoch period P an encoder gives: the count is ``floor(D_k / q)`` with ``D_k``
    the running sum of ``ũ_k P`` from ``D_0 = q/2`` (the start mid-pulse), and the emitted
    speed is ``q (n_k − n_{k−1}) / P``. At rest ``ũ`` is the truth's round-off (~1e-14 m/s),
    far below the half pulse: the count stays and the speed is exactly 0.
    """

    def __init__(self, errors: OdometerErrors, period_s: float, seed: int) -> None:
        self.errors = errors
        self.period_s = check_period(period_s)
        self._rng = sensor_rng(seed, "wheel_odometer")
        init = self._rng.standard_normal(1)
        self.scale_factor = errors.scale_factor + errors.scale_factor_sigma * float(init[0])
        self.quantum = 1.0 / errors.pulses_per_m if errors.pulses_per_m > 0 else 0.0
        # Running sum of the quantizer inputs (m), starting mid-pulse: the wheel's phase at the
        # start is inside a pulse, so the truth's round-off at rest (~1e-14 m/s) never counts.
        self._distance = 0.5 * self.quantum
        self._count = 0.0  # floor(distance / q) after the last epoch
        self.epochs = 0

    def apply(self, speed: ArrayLike) -> F64:
        """Measured speeds (n,) of the true ones (n,) at the next n epochs (m/s)."""
        u = np.asarray(speed, dtype=np.float64)
        n = u.shape[0]
        z = self._rng.standard_normal((n, ODOMETER_NORMALS_PER_EPOCH))
        sigma = np.minimum(self.errors.white, np.abs(u))  # no slip without rolling
        out = u + (self.scale_factor * u + sigma * z[:, 0])
        q = self.quantum
        if q > 0 and n:
            period = self.period_s
            cum = np.cumsum(np.concatenate([[self._distance], out * period]))
            counts = np.floor(cum[1:] / q)
            previous = np.concatenate([[self._count], counts[:-1]])
            out = (counts - previous) * q / period
            self._distance = float(cum[-1])
            self._count = float(counts[-1])
        self.epochs += n
        return out

    def skip(self, n: int) -> None:
        """Advance over ``n`` epochs without output.

        The random state advances; the encoder count misses the distance of those epochs.
        """
        if n > 0:
            self._rng.standard_normal((n, ODOMETER_NORMALS_PER_EPOCH))
            self.epochs += n
