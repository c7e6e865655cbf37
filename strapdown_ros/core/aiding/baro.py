"""Barometer: ICAO standard-atmosphere pressure at the sensor's altitude, plus sensor errors.

Pressure of the ICAO Standard Atmosphere (Doc 7488/3, 1993; = ISO 2533:1975 up to 80 km) at the
geopotential altitude ``H = r₀ h / (r₀ + h)`` of the altitude ``h`` given (the stage passes the
ellipsoidal altitude: no geoid model). Errors: fixed bias + per-run turn-on bias + first-order
Gauss–Markov drift (weather) + white noise, then quantization. See ``docs/aiding.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from strapdown_ros.core.aiding.common import GaussMarkov, check_period, sensor_rng
from strapdown_ros.core.array_types import F64

__all__ = [
    "BARO_NORMALS_PER_EPOCH",
    "ICAO_LAYERS",
    "BaroErrorModel",
    "BaroErrors",
    "geopotential_altitude",
    "icao_pressure",
]


#: ICAO constants: sea-level pressure (Pa) and temperature (K), g₀ (m/s²), R (J/(kg K)),
#: effective Earth radius r₀ (m) of the geopotential altitude.
P0_PA = 101325.0
T0_K = 288.15
G0 = 9.80665
R_AIR = 287.05287
R0_M = 6356766.0

#: Layers (base geopotential altitude m, temperature gradient K/m), ICAO 1993 Table D.
ICAO_LAYERS = (
    (-5000.0, -0.0065),
    (11000.0, 0.0),
    (20000.0, 0.001),
    (32000.0, 0.0028),
    (47000.0, 0.0),
    (51000.0, -0.0028),
    (71000.0, -0.002),
)


def _layer_bases() -> tuple[F64, F64, F64, F64]:
    """Reference H, gradient β, temperature and pressure of each layer.

    The references are the layer bases, except for the bottom layer, referred to sea level
    (H = 0, T₀, p₀) so that the sea-level pressure is p₀ exactly.
    """
    h_b = np.array([h for h, _ in ICAO_LAYERS])
    beta = np.array([b for _, b in ICAO_LAYERS])
    t_b = np.empty_like(h_b)
    p_b = np.empty_like(h_b)
    h_b[0], t_b[0], p_b[0] = 0.0, T0_K, P0_PA
    for i in range(1, len(h_b)):
        t_b[i] = t_b[i - 1] + beta[i - 1] * (h_b[i] - h_b[i - 1])
        p_b[i] = _layer_pressure(p_b[i - 1], t_b[i - 1], beta[i - 1], h_b[i - 1], np.array(h_b[i]))
    return h_b, beta, t_b, p_b


def _layer_pressure(p_b: float, t_b: float, beta: float, h_b: float, h: F64) -> F64:
    """Barometric formula within one layer (geopotential altitudes, m)."""
    if beta == 0.0:
        return p_b * np.exp(-G0 * (h - h_b) / (R_AIR * t_b))
    return p_b * (1.0 + beta * (h - h_b) / t_b) ** (-G0 / (beta * R_AIR))


_BASES = _layer_bases()


def geopotential_altitude(h: ArrayLike) -> F64:
    """Geopotential altitude ``H = r₀ h / (r₀ + h)`` (m) of a geometric altitude h (m)."""
    h = np.asarray(h, dtype=np.float64)
    return R0_M * h / (R0_M + h)


def icao_pressure(h: ArrayLike) -> F64:
    """Static pressure (Pa) of the ICAO Standard Atmosphere at geometric altitude h (m).

    Valid from −5 km to 80 km (the ICAO table); outside, the bottom and top layers are
    continued.
    """
    hp = geopotential_altitude(h)
    h_b, beta, t_b, p_b = _BASES
    layer = np.clip(np.searchsorted(h_b, hp, side="right") - 1, 0, len(h_b) - 1)  # H < 0: 0
    out = np.empty_like(hp)
    for i in range(len(h_b)):
        sel = layer == i
        if np.any(sel):
            out[sel] = _layer_pressure(p_b[i], t_b[i], beta[i], h_b[i], hp[sel])
    return out


#: Standard normals per epoch: white 1, drift 1.
BARO_NORMALS_PER_EPOCH = 2


@dataclass(frozen=True)
class BaroErrors:
    """Barometer error parameters (Pa, s)."""

    bias: float = 0.0  #: fixed bias, Pa
    turn_on_bias_sigma: float = 0.0  #: σ of a bias drawn once per run, Pa
    drift_sigma: float = 0.0  #: Gauss–Markov drift σ (weather), Pa
    drift_tau_s: float = 1.0  #: its correlation time, s
    white: float = 0.0  #: white noise σ, Pa
    quantum: float = 0.0  #: output resolution, Pa (0: none)

    @property
    def variance(self) -> float:
        """Variance of one message's random error (Pa²): white² + drift σ² + quantum²/12."""
        return self.white**2 + self.drift_sigma**2 + self.quantum**2 / 12.0


class BaroErrorModel:
    """Seeded barometer errors at consecutive epochs (state carried, chunk-invariant).

    Construction draws 2 normals (turn-on bias, initial drift); each epoch consumes
    :data:`BARO_NORMALS_PER_EPOCH`. Quantization rounds to the nearest multiple of the quantum.
    """

    def __init__(self, errors: BaroErrors, period_s: float, seed: int) -> None:
        self.errors = errors
        self.period_s = check_period(period_s)
        self._rng = sensor_rng(seed, "baro")
        init = self._rng.standard_normal(2)
        self.bias = errors.bias + errors.turn_on_bias_sigma * init[0]
        self._drift = GaussMarkov([errors.drift_sigma], [errors.drift_tau_s], self.period_s,
                                  init[1:2])  # fmt: skip
        self.epochs = 0

    def apply(self, pressure: ArrayLike) -> F64:
        """Measured pressures (n,) of the true ones (n,) at the next n epochs (Pa)."""
        p = np.asarray(pressure, dtype=np.float64)
        n = p.shape[0]
        z = self._rng.standard_normal((n, BARO_NORMALS_PER_EPOCH))
        out = p + (self.bias + (self.errors.white * z[:, 0] + self._drift.take(z[:, 1:2])[:, 0]))
        q = self.errors.quantum
        if q > 0:
            out = np.floor(out / q + 0.5) * q
        self.epochs += n
        return out

    def skip(self, n: int) -> None:
        """Advance over ``n`` epochs without output (random state and drift)."""
        if n > 0:
            z = self._rng.standard_normal((n, BARO_NORMALS_PER_EPOCH))
            self._drift.take(z[:, 1:2])
            self.epochs += n
