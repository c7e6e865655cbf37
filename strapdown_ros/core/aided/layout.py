"""The error-state vector of the aided filter: which states, in which order, where.

Error = estimate minus truth, everywhere (docs/theory/aided_ins.md §2):

* ``0:3`` δR — position error in E0 (m); ``3:6`` δV — inertial velocity error in E0 (m/s);
  ``6:9`` φ — attitude error, the rotation vector of ``Ĉ C⁻¹`` in E0 axes (rad):
  ``Ĉ_B^E0 = exp([φ×]) C_B^E0``;
* then the IMU error states (coupled to the navigation errors through the dynamics): gyro and
  accelerometer biases (random constant + random walk, always), their Gauss–Markov parts and
  their scale factors (optional);
* then the aiding-sensor error states (decoupled scalar processes, optional): barometer bias
  (random constant) and drift (Gauss–Markov), GNSS position and velocity Gauss–Markov errors
  (NED), magnetometer hard iron (random constant, body FRD), wheel scale factor (random
  constant), the wheel encoder's quantization residual (two states, as a speed: the residual
  of the last wheel epoch and the one of the next, see :mod:`.measurement_models`).

A block absent from a layout has offset -1. The compiled kernels take :attr:`StateLayout.offsets`
(an int64 array indexed by the ``B_*`` block codes) and read every index from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "BLOCK_NAMES",
    "BLOCK_SIZES",
    "B_BA",
    "B_BARO_BIAS",
    "B_BARO_DRIFT",
    "B_BG",
    "B_GMA",
    "B_GMG",
    "B_GNSS_POS",
    "B_GNSS_VEL",
    "B_MAG",
    "B_SFA",
    "B_SFG",
    "B_WHEEL_QUANT",
    "B_WHEEL_SF",
    "IMU_BLOCKS",
    "N_BLOCKS",
    "N_INS",
    "SENSOR_BLOCKS",
    "StateLayout",
]

#: Navigation error states δR, δV, φ.
N_INS = 9

B_BG, B_BA, B_GMG, B_GMA, B_SFG, B_SFA = 0, 1, 2, 3, 4, 5
B_BARO_BIAS, B_BARO_DRIFT, B_GNSS_POS, B_GNSS_VEL, B_MAG, B_WHEEL_SF = 6, 7, 8, 9, 10, 11
B_WHEEL_QUANT = 12
N_BLOCKS = 13
#: Size of each block, by block code.
BLOCK_SIZES = (3, 3, 3, 3, 3, 3, 1, 1, 3, 3, 3, 1, 2)
#: Name of each block (docs, reports), by block code.
BLOCK_NAMES = (
    "gyro_bias", "accel_bias", "gyro_gauss_markov", "accel_gauss_markov", "gyro_scale_factor",
    "accel_scale_factor", "baro_bias", "baro_drift", "gnss_position_gm", "gnss_velocity_gm",
    "mag_hard_iron", "wheel_scale_factor", "wheel_quantization",
)  # fmt: skip
#: Suffixes of the states of a block of two (the wheel quantization residuals).
_PAIR = ("last", "next")
#: IMU error blocks (they follow the navigation states, in this order).
IMU_BLOCKS = (B_BG, B_BA, B_GMG, B_GMA, B_SFG, B_SFA)
#: Aiding-sensor error blocks (after the IMU blocks, in this order).
SENSOR_BLOCKS = (B_BARO_BIAS, B_BARO_DRIFT, B_GNSS_POS, B_GNSS_VEL, B_MAG, B_WHEEL_SF,
                 B_WHEEL_QUANT)


@dataclass(frozen=True)
class StateLayout:
    """The blocks present and their offsets.

    Parameters
    ----------
    blocks : tuple of int
        Block codes present besides the navigation states (the biases ``B_BG``, ``B_BA`` are
        always added). Order does not matter: IMU blocks come first, then sensor blocks, each
        in code order.
    """

    blocks: tuple[int, ...] = ()
    offsets: NDArray[np.int64] = field(init=False, repr=False)
    n: int = field(init=False)
    n_coupled: int = field(init=False)

    def __post_init__(self) -> None:
        present = set(self.blocks) | {B_BG, B_BA}
        unknown = present - set(range(N_BLOCKS))
        if unknown:
            raise ValueError(f"unknown state block code(s) {sorted(unknown)}")
        offsets = np.full(N_BLOCKS, -1, dtype=np.int64)
        k = N_INS
        for b in IMU_BLOCKS:
            if b in present:
                offsets[b] = k
                k += BLOCK_SIZES[b]
        coupled = k
        for b in SENSOR_BLOCKS:
            if b in present:
                offsets[b] = k
                k += BLOCK_SIZES[b]
        offsets.setflags(write=False)
        object.__setattr__(self, "blocks", tuple(sorted(present)))
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "n", k)
        object.__setattr__(self, "n_coupled", coupled)

    def has(self, block: int) -> bool:
        """Whether ``block`` is in the layout."""
        return bool(self.offsets[block] >= 0)

    def slice(self, block: int) -> slice:
        """Indices of ``block`` in the state vector (ValueError if absent)."""
        o = int(self.offsets[block])
        if o < 0:
            raise ValueError(f"state block {BLOCK_NAMES[block]} is not in the layout")
        return slice(o, o + BLOCK_SIZES[block])

    def names(self) -> list[str]:
        """One name per state, in order (``dr_x``, ..., ``gyro_bias_x``, ...)."""
        out = [f"{p}_{a}" for p in ("dr", "dv", "phi") for a in "xyz"]
        by_offset = sorted((int(o), b) for b, o in enumerate(self.offsets) if o >= 0)
        for _, b in by_offset:
            size = BLOCK_SIZES[b]
            axes = {1: ("",), 2: _PAIR, 3: tuple("xyz")}[size]
            out += [f"{BLOCK_NAMES[b]}_{a}" if a else BLOCK_NAMES[b] for a in axes]
        return out
