"""Young 1980's nonlinear orientation error model against a navigator run read from a bag.

:func:`compare_orientation` takes a :class:`~strapdown_ros.analysis.navigator_record.
NavigatorRecord` (truth and the navigator's outputs, from disk) and the deterministic gyro errors
of the IMU error model (:class:`GyroErrors`), integrates eqs. (51a)–(51c) and their small-angle
(phi-angle) limit along the true and the indicated positions
(:mod:`strapdown_ros.core.young_nonlinear`) and compares both with the navigator's published
Young angles (eq. (28)). Theory: docs/theory/young_nonlinear.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.analysis.navigator_record import NavigatorRecord
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm
from strapdown_ros.core.young import young_error_angles
from strapdown_ros.core.young_nonlinear import (
    OrientationInputs,
    drift_in_platform,
    integrate_orientation,
    wrap_angle,
)

__all__ = [
    "Agreement",
    "GyroErrors",
    "OrientationComparison",
    "compare_orientation",
    "drift_angle_platform",
    "orientation_inputs",
]


#: Floor of the relative agreement (rad): "1 % of the error or 1e-6 rad, the larger".
FLOOR_RAD = 1e-6


@dataclass(frozen=True)
class GyroErrors:
    """The deterministic gyro errors of one IMU run (body FRD, SI units).

    ``δα = b T + E Δα + G Δv`` per cycle (docs/theory/imu_errors.md): ``bias`` b (rad/s, fixed
    plus the run's turn-on draw), ``error_matrix`` E = S + M (scale factors and
    misalignments, the run's draws included), ``g_sensitivity`` G (rad/s per m/s²).
    ``stochastic`` names the error terms the model has but this does not carry (white noise,
    Gauss–Markov bias, rate random walk, quantization, saturation).
    """

    bias: F64
    error_matrix: F64 = field(default_factory=lambda: np.zeros((3, 3)))
    g_sensitivity: F64 = field(default_factory=lambda: np.zeros((3, 3)))
    stochastic: tuple[str, ...] = ()

    @classmethod
    def from_parameters(cls, params: ImuErrorParameters, period_s: float) -> GyroErrors:
        """The run's realized constants (``ImuErrorModel``: the same draws as the data)."""
        model = ImuErrorModel(params, period_s)
        g = params.gyro
        stochastic = tuple(
            name
            for name, value in (
                ("white noise", g.white),
                ("Gauss-Markov bias", g.bias_instability),
                ("rate random walk", g.random_walk),
                ("quantization", g.quantum),
                ("saturation", g.range),
            )
            if np.any(np.asarray(value) != 0)
        )
        return cls(model.gyro_bias, model.gyro_error_matrix, g.g_sensitivity.copy(), stochastic)

    def increments(self, dalpha: F64, dv: F64, period_s: float) -> F64:
        """Gyro error angles δα (rad, body FRD) of cycles with ideal increments Δα, Δv."""
        return self.bias * period_s + dalpha @ self.error_matrix.T + dv @ self.g_sensitivity.T


def drift_angle_platform(record: NavigatorRecord, gyro: GyroErrors) -> tuple[F64, F64]:
    """``(t, D^P)``: the cumulative gyro error angle in the true local level (up, east, north).

    ``D^P(t_m) = Σ_{k ≤ m} C_NED_TO_UEN C_B^N(t_{k-½}) δα_k`` over the IMU cycles from the
    navigator's start, with δα_k of :meth:`GyroErrors.increments` on the record's ideal IMU
    increments and the true attitude at the middle of each cycle (the geodesic midpoint of the
    truth at its ends); ``D^P(t_0) = 0``.
    """
    if record.imu is None:
        raise ValueError("the record has no IMU topic: read it with imu_topic=<ideal IMU>")
    imu, truth = record.imu, record.truth
    # IMU message m closes the cycle (t_{m-1}, t_m]; the truth has every cycle's end stamp.
    end = np.searchsorted(truth.stamps_ns, imu.stamps_ns)
    ok = (end >= 1) & (end < truth.stamps_ns.shape[0])
    ok[ok] &= truth.stamps_ns[end[ok]] == imu.stamps_ns[ok]
    rows = np.flatnonzero(ok)
    if rows.size == 0:
        raise ValueError("no IMU cycle lies within the truth record")
    if not np.array_equal(end[rows], np.arange(1, rows.size + 1)):
        raise ValueError("the IMU cycles do not cover the truth record contiguously")
    c0, c1 = truth.c_b_n[end[rows] - 1], truth.c_b_n[end[rows]]
    half = 0.5 * rotvec_from_dcm(np.swapaxes(c0, -1, -2) @ c1)
    c_mid = c0 @ dcm_from_rotvec(half)
    period = imu.period_ns * 1e-9
    dalpha = gyro.increments(imu.dalpha[rows], imu.dv[rows], period)
    d = np.cumsum(drift_in_platform(c_mid, dalpha), axis=0)
    t = np.concatenate([[truth.t[0]], truth.t[end[rows]]])
    return t, np.vstack([np.zeros(3), d])


def orientation_inputs(
    record: NavigatorRecord, gyro: GyroErrors | None = None, interpolation: str = "spline"
) -> OrientationInputs:
    """Inputs of eq. (51) from a record: truth → Σ_P, navigator outputs → Σ_C, gyro errors."""
    drift_t = drift = None
    if gyro is not None:
        drift_t, drift = drift_angle_platform(record, gyro)
    return OrientationInputs(
        record.truth.track(),
        record.navigator.track(),
        drift_t,
        drift,
        interpolation=interpolation,
    )


@dataclass(frozen=True)
class Agreement:
    """How a prediction θ_pred matches the navigator's θ_act (wrapped differences, rad).

    ``max_abs``: max over the span of |θ_pred,i - θ_act,i| per component; ``max_norm``: of
    ``e(t) = |θ_pred - θ_act|``; ``max_rel``: max of ``e(t) / max(|θ_act(t)|, 1e-6 rad)`` (the
    "1 % of the error or 1e-6 rad" measure); ``rel_change``: ``max e / max |θ_act - θ_act(0)|``;
    ``departure_s``: first time ``e(t)`` exceeds 10 % of ``max(|θ_act(t)|, 1e-6 rad)``, None if
    never; ``departure_change_s``: first time ``e(t)`` exceeds 10 % of the largest change
    ``max_{s ≤ t} |θ_act(s) - θ_act(0)|`` (plus 1e-6 rad), None if never.
    """

    max_abs: tuple[float, float, float]
    max_norm: float
    max_rel: float
    rel_change: float
    departure_s: float | None
    departure_change_s: float | None

    @classmethod
    def of(cls, t: F64, pred: F64, act: F64) -> Agreement:
        """Agreement of ``pred`` with ``act`` (both (K, 3), rad) at times ``t``."""
        diff = wrap_angle(pred - act)
        e = np.linalg.norm(diff, axis=1)
        size = np.maximum(np.linalg.norm(act, axis=1), FLOOR_RAD)
        change = np.maximum.accumulate(np.linalg.norm(wrap_angle(act - act[0]), axis=1))
        return cls(
            tuple(float(x) for x in np.max(np.abs(diff), axis=0)),  # type: ignore[arg-type]
            float(e.max()),
            float(np.max(e / size)),
            float(e.max() / max(change[-1], FLOOR_RAD)),
            _first(t, e > 0.1 * size),
            _first(t, e > 0.1 * change + FLOOR_RAD),
        )


def _first(t: F64, mask: NDArray[np.bool_]) -> float | None:
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


@dataclass(frozen=True)
class OrientationComparison:
    """Navigator's Young angles against eq. (51) and its linear limit on one run.

    ``t`` (s), ``theta0`` (the initial angles, rad, from the initial truth and navigator
    attitudes), ``actual`` (the published angles), ``nonlinear`` (eq. (51)), ``linear``
    (phi-angle model), all (K, 3) rad with θ1, θ3 of the predictions unwrapped.
    """

    t: F64
    theta0: F64
    actual: F64
    nonlinear: F64
    linear: F64
    nonlinear_agreement: Agreement
    linear_agreement: Agreement
    nfev: int

    def summary(self) -> dict[str, Any]:
        """Final and max-over-span values (deg) and the agreements, as a JSON-able mapping."""

        def stats(theta: F64) -> dict[str, list[float]]:
            w = wrap_angle(theta)
            return {
                "final_deg": np.degrees(w[-1]).tolist(),
                "max_abs_deg": np.degrees(np.max(np.abs(w), axis=0)).tolist(),
            }

        return {
            "duration_s": float(self.t[-1] - self.t[0]),
            "theta0_deg": np.degrees(self.theta0).tolist(),
            "actual": stats(self.actual),
            "nonlinear": {**stats(self.nonlinear), **self.nonlinear_agreement.__dict__},
            "linear": {**stats(self.linear), **self.linear_agreement.__dict__},
        }


def compare_orientation(
    record: NavigatorRecord,
    gyro: GyroErrors | None = None,
    *,
    interpolation: str = "spline",
    rtol: float = 1e-10,
    atol: float = 1e-12,
) -> OrientationComparison:
    """Integrate eq. (51) and the phi-angle model along ``record`` and compare them with the
    published angles. θ0 comes from the initial truth and navigator attitudes (eq. (28))."""
    inputs = orientation_inputs(record, gyro, interpolation)
    lo, hi = inputs.span
    rows = np.flatnonzero((record.t >= lo) & (record.t <= hi))
    t = record.t[rows]
    theta0 = young_error_angles(
        record.navigator.c_b_n[rows[0]], record.truth.c_b_n[record.truth_index[rows[0]]]
    )
    young = integrate_orientation(inputs, theta0, t, rtol=rtol, atol=atol)
    linear = integrate_orientation(inputs, theta0, t, method="phi_angle", rtol=rtol, atol=atol)
    act = record.theta_actual[rows]
    return OrientationComparison(
        t,
        theta0,
        act,
        young.theta,
        linear.theta,
        Agreement.of(t, young.theta, act),
        Agreement.of(t, linear.theta, act),
        young.nfev + linear.nfev,
    )
