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


def _rest_stream(n: int, model: str = "spherical"):
    from strapdown_ros.core.stream import Stream

    return Stream(
        5_000, 10_000_000, np.zeros((n - 1, 3)), np.zeros((n - 1, 3)),
        np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), np.tile([6378137.0, 0.0, 0.0], (n, 1)),
        gravity_model=model, e0_epoch_ns=123_456,
    )  # fmt: skip


@pytest.mark.parametrize("method", [1, 2])
def test_window_output_keeps_epoch_model_and_starts_one_period_later(method: int) -> None:
    """With ``lead`` 1 the output starts at reference sample 1 (docstring): t0 + period_ns, by
    hand 5_000 + 10_000_000 ns; E0 epoch and gravity model are the reference's own."""
    from strapdown_ros.core.variation import generate_variation

    out = generate_variation(_rest_stream(7), OffsetArrays.zero(7), method=method, lead=1)
    assert out.t0_ns == 10_005_000
    assert out.e0_epoch_ns == 123_456
    assert out.gravity_model == "spherical"


@pytest.mark.parametrize(
    "lead,cycles,message",
    [
        (5, 6, r"^lead must be 0 or 1, got 5$"),
        (0, 2, r"^a variation needs a reference of at least 3 cycles, got 2$"),
        (1, 3, r"^a variation needs a reference of at least 4 cycles, got 3$"),
    ],
)
def test_generate_variation_messages(lead: int, cycles: int, message: str) -> None:
    """The messages of generate_variation's checks, written out by hand from its docstring (a
    reference of M cycles gives M_var = M - 1 - lead rounded down to even, at least 2)."""
    from strapdown_ros.core.variation import generate_variation

    with pytest.raises(ValueError, match=message):
        generate_variation(_rest_stream(cycles + 1), OffsetArrays.zero(cycles + 1), lead=lead)
