"""The interface.md §3 exactness rule applied to a whole :class:`~strapdown_ros.core.stream.Stream`.

``stream_residuals`` evaluates the one-step residuals of Savage 2020 eqs. (2)-(4) with gravity
``g_m = g(R_m)`` from the stream's gravitation model at the published positions;
``reintegration_drift`` re-integrates the increments from the first truth state and reports how
far the result drifts from the published truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.core.exact_update import Residuals, integrate, one_step_residuals
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.rotations import rotation_angle
from strapdown_ros.core.stream import Stream

__all__ = ["Drift", "reintegration_drift", "stream_residuals"]


def stream_residuals(stream: Stream) -> Residuals:
    """One-step residuals (rad, m/s, m) of a stream against Savage 2020 eqs. (2)-(4) in E0.

    Gravity is the stream's model (docs/interface.md §1) evaluated at the published positions
    ``R_m``.
    """
    g = gravitation(stream.r_e0, stream.gravity_model)
    return one_step_residuals(
        stream.c_b_e0, stream.v_e0, stream.r_e0, stream.dalpha, stream.dv, g, stream.period
    )


@dataclass(frozen=True)
class Drift:
    """Largest difference between re-integrated and published truth over the stream.

    Attributes
    ----------
    attitude : float
        rad. velocity : m/s (E0). position : m (E0).
    """

    attitude: float
    velocity: float
    position: float


def reintegration_drift(stream: Stream) -> Drift:
    """Re-integrate the increments from the first truth state with eqs. (2)-(4), compare.

    The recursion is sequential (:func:`~strapdown_ros.core.exact_update.integrate`), gravity
    from the stream's model at the integrated positions.
    """
    model = stream.gravity_model
    c, v, r = integrate(
        stream.c_b_e0[0],
        stream.v_e0[0],
        stream.r_e0[0],
        stream.dalpha,
        stream.dv,
        stream.period,
        lambda x: gravitation(x, model),
    )
    att = rotation_angle(np.swapaxes(stream.c_b_e0, -1, -2) @ c)
    return Drift(
        attitude=float(np.max(att)),
        velocity=float(np.max(np.linalg.norm(v - stream.v_e0, axis=-1))),
        position=float(np.max(np.linalg.norm(r - stream.r_e0, axis=-1))),
    )
