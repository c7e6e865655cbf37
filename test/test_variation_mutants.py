"""Savage 2020 eq. (10): the variation velocity ``v_var = v_ref + ds/dt`` of the constraints.

A reference at rest at identity attitude and a displacement quadratic in time,
``s(t) = p + q t + w t²``: both the central difference and the one-sided three-point formula
of eq. (10) are exact for a quadratic, so ``ds/dt = q + 2 w t`` in closed form (the numbers are
binary fractions: every operation is exact).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from strapdown_ros.core.variation import OffsetArrays, variation_constraints

T = 0.25  # s, cycle period
P = np.array([1.0, -2.0, 0.5])  # m
Q = np.array([0.5, 1.0, -1.5])  # m/s
W = np.array([0.25, -0.5, 2.0])  # m/s²
V_REF = np.array([3.0, -4.0, 0.75])  # m/s, constant reference velocity


def _case(n: int) -> tuple[SimpleNamespace, OffsetArrays, np.ndarray]:
    t = T * np.arange(n)
    r_ref = np.array([6.0e6, 0.0, 0.0]) + t[:, None] * V_REF
    ref = SimpleNamespace(
        c_b_e0=np.tile(np.eye(3), (n, 1, 1)),
        r_e0=r_ref,
        v_e0=np.tile(V_REF, (n, 1)),
        period=T,
        cycles=n - 1,
    )
    s = P + t[:, None] * Q + (t * t)[:, None] * W
    off = OffsetArrays(np.zeros((n, 3)), s, np.tile(np.eye(3), (n, 1, 1)))
    return ref, off, t


@pytest.mark.parametrize("lead", [0, 1])
def test_variation_velocity_is_reference_plus_displacement_rate(lead: int) -> None:
    cycles = 5
    ref, off, t = _case(lead + cycles + 2)
    con = variation_constraints(ref, off, cycles, lead=lead)  # type: ignore[arg-type]
    tm = t[lead : lead + cycles + 1]
    expected = V_REF + Q + 2.0 * tm[:, None] * W
    np.testing.assert_array_equal(con.v_e0, expected)
    np.testing.assert_array_equal(
        con.r_e0, ref.r_e0[lead : lead + cycles + 1] + P + tm[:, None] * Q + (tm * tm)[:, None] * W
    )


def test_variation_needs_one_cycle_ahead() -> None:
    ref, off, _ = _case(7)
    variation_constraints(ref, off, 5)  # type: ignore[arg-type]  # 7 = 5 + 2 samples: enough
    ref.cycles = 5  # 6 reference samples
    with pytest.raises(ValueError, match=r"needs 7 reference and offset samples .* got 6 and 7"):
        variation_constraints(ref, off, 5)  # type: ignore[arg-type]
