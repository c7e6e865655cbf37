"""Savage 2020 Methods 1 and 2 applied to a published reference: constraints and exactness."""

import numpy as np
import pytest

from strapdown_ros.config import parse_scenario
from strapdown_ros.core.exactness import stream_residuals
from strapdown_ros.core.rotations import dcm_from_euler, rotation_angle
from strapdown_ros.core.variation import (
    OffsetArrays,
    _window,
    generate_variation,
    variation_constraints,
)
from strapdown_ros.stages.trajectory import generate_reference

SCENARIO = {
    "rate_hz": 200,
    "initial": {"latitude_deg": 45, "longitude_deg": 7, "altitude_m": 500,
                "velocity_ned_mps": [60, 0, 0], "attitude_rph_deg": [0, 2, 0]},
    "trajectory": {"kind": "segments", "segments": [
        {"duration_s": 3, "heading_rate_dps": 8, "roll_rate_dps": 4},
        {"duration_s": 3, "climb_rate_mps": 4, "accel_mps2": 1},
    ]},
}  # fmt: skip


@pytest.fixture(scope="module")
def reference():
    return generate_reference(parse_scenario(SCENARIO))


def offsets(reference, kind):
    n = reference.cycles + 1
    t = np.arange(n) * reference.period
    if kind == "constant":
        return OffsetArrays(np.tile([1.2, -0.4, 0.3], (n, 1)), np.zeros((n, 3)),
                            np.tile(dcm_from_euler(0.01, -0.02, 0.5), (n, 1, 1)))  # fmt: skip
    if kind == "bending":
        lever = np.tile([3.0, 8.0, -0.5], (n, 1))
        lever[:, 2] += 0.02 * np.sin(2 * np.pi * 3.0 * t)
        return OffsetArrays(lever, np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)))
    scan = dcm_from_euler(0 * t, 0.2 * np.sin(0.8 * t), 0.6 * np.sin(1.5 * t))
    return OffsetArrays(np.tile([0.5, 0.0, -1.0], (n, 1)), np.tile([0.0, 0.0, 0.2], (n, 1)), scan)


@pytest.mark.parametrize("kind", ["constant", "bending", "scanning"])
def test_method2_meets_constraints_and_exactness(reference, kind):
    off = offsets(reference, kind)
    var = generate_variation(reference, off)
    assert var.cycles == reference.cycles - 2  # ends at the last even cycle with look-ahead
    res = stream_residuals(var)
    assert res.within_spec(), (res.max_attitude, res.max_velocity, res.max_position)
    con = variation_constraints(reference, off, var.cycles)
    # eq. (5) every cycle; eqs. (6)-(7) and (10) at even cycles
    att = rotation_angle(np.swapaxes(var.c_b_e0, -1, -2) @ con.c_b_e0)
    assert np.max(att) <= 1e-12
    assert np.max(np.abs(var.r_e0[0::2] - con.r_e0[0::2])) <= 1e-8
    assert np.max(np.abs(var.v_e0[0::2] - con.v_e0[0::2])) <= 1e-9
    # the variation really is displaced: |R_var - R_ref| equals |S|
    s = np.linalg.norm(con.s_e0[: var.cycles + 1], axis=1)
    d = np.linalg.norm(var.r_e0[0::2] - reference.r_e0[: var.cycles + 1 : 2], axis=1)
    np.testing.assert_allclose(d, s[0::2], atol=1e-8)
    assert np.min(s) > 0.1


def test_zero_offsets_regenerate_the_reference(reference):
    regen = generate_variation(reference, OffsetArrays.zero(reference.cycles + 1))
    assert stream_residuals(regen).within_spec()
    np.testing.assert_array_equal(regen.dalpha, reference.dalpha[: regen.cycles])
    np.testing.assert_allclose(regen.dv, reference.dv[: regen.cycles], rtol=0, atol=1e-12)
    np.testing.assert_allclose(regen.r_e0, reference.r_e0[: regen.cycles + 1], rtol=0, atol=1e-8)


def test_method1_meets_position_every_cycle_but_oscillates(reference):
    off = offsets(reference, "bending")
    m1 = generate_variation(reference, off, method=1)
    m2 = generate_variation(reference, off, method=2)
    con = variation_constraints(reference, off, m1.cycles)
    assert stream_residuals(m1).within_spec()
    np.testing.assert_array_equal(m1.r_e0, con.r_e0)  # position constraint at every cycle
    # Method 1's velocity departs from the constraint by an odd/even oscillation; Method 2 not
    dev1 = np.linalg.norm(m1.v_e0 - con.v_e0, axis=1)
    dev2 = np.linalg.norm(m2.v_e0[0::2] - con.v_e0[0::2], axis=1)
    assert np.max(dev1) > 1e-4 and np.max(dev2) < 1e-9


def test_first_order_gravity_is_close_to_full(reference):
    off = offsets(reference, "constant")
    full = generate_variation(reference, off, gravity="full")
    first = generate_variation(reference, off, gravity="first_order")
    # Appendix C's error for a 1.3 m offset is ~1e-8 m/s^2 (j2 vs spherical expansion)
    assert np.max(np.abs(full.dv - first.dv)) < 1e-9
    assert stream_residuals(first).max_velocity < 1e-9


def test_windows_give_bit_identical_pairs(reference):
    """The streaming node solves one pair per window; the offline path all pairs at once."""
    off = offsets(reference, "scanning")
    whole = generate_variation(reference, off)
    for n2 in (4, 10, 200, whole.cycles):
        a = n2 - 3
        win = _window(reference, a, 5)
        o = OffsetArrays(off.lever_arm[a : a + 5], off.displacement[a : a + 5],
                         off.c_bvar_bref[a : a + 5])  # fmt: skip
        w = generate_variation(win, o, lead=1)
        np.testing.assert_array_equal(w.dv, whole.dv[n2 - 2 : n2])
        np.testing.assert_array_equal(w.r_e0, whole.r_e0[n2 - 2 : n2 + 1])
        np.testing.assert_array_equal(w.v_e0, whole.v_e0[n2 - 2 : n2 + 1])


def test_bad_arguments(reference):
    off = OffsetArrays.zero(reference.cycles + 1)
    with pytest.raises(ValueError, match="variation.method"):
        generate_variation(reference, off, method=3)
    with pytest.raises(ValueError, match="variation.gravity"):
        generate_variation(reference, off, gravity="egm")
    with pytest.raises(ValueError, match="needs"):
        variation_constraints(reference, OffsetArrays.zero(10), 100)
