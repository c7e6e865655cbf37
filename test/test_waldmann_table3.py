"""Waldmann Table 3 study (``bench/waldmann_table3.py``): trends and their mechanisms.

The study runs 100 s instead of 300 s here. At 100 s the paper's trends that do not depend on
the distance travelled already hold (exact mode ≫ paper mode; N = 120 ≫ N = 12 at rest;
multirate better than simultaneous at N = 12 when moving; multirate worse at rest, N = 12), and
the error of every scheme splits, to a few per cent, into the two first-order parts
docs/navigator.md derives: an Euler-truncation part proportional to T_nav and a
rotation-compensation part proportional to T_gyr, equal and opposite in the two schemes.
"Multirate better than simultaneous when moving at N = 120" and "N = 120 much better than N = 12
when moving" need the T_gyr part, which grows with the distance travelled, to dominate: they
hold at 300 s only (at 100 s the multirate's T_nav part, -½ T_nav ΔU, is larger), and
:func:`test_moving_trends_at_300_s` checks them at the paper's duration.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.core.navigation import navigate_simultaneous, state_from_stream, truth_navigation
from strapdown_ros.core.rotations import dcm_from_quat

BENCH = Path(__file__).resolve().parents[1] / "bench" / "waldmann_table3.py"


def _load_bench():
    spec = importlib.util.spec_from_file_location("waldmann_table3", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve annotations through sys.modules
    spec.loader.exec_module(module)
    return module


wt3 = _load_bench()
DURATION = 100.0

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def study():
    return wt3.run_study(DURATION, variants=False, phase=False)


def _h(study, data: str, case: str, label: str, scheme) -> float:
    return study.h(data, case, label, scheme.name)


def test_table2_reads_only_the_sampled_increment() -> None:
    """The simultaneous scheme uses Δβ only at the first increment of each T_nav cycle.

    That is what lets ``shifted_sample`` emulate the other reading of Table 2 (the increment
    ending at t_k) without touching the navigator.
    """
    s = wt3.load_streams("moving", wt3.PERIOD_SLOW, "exact", 6.0).imu
    initial, t_gyr, n = state_from_stream(s), s.period, 12
    keep = np.zeros_like(s.dv)
    keep[::n] = s.dv[::n]
    a = navigate_simultaneous(initial, s.dalpha, s.dv, t_gyr, n)
    b = navigate_simultaneous(initial, s.dalpha, keep, t_gyr, n)
    for field in ("lat", "lon", "alt", "v_ned", "q_b_n"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    shifted = wt3.shifted_sample(s.dv)
    np.testing.assert_array_equal(shifted[1:], s.dv[:-1])
    np.testing.assert_array_equal(shifted[0], s.dv[0])


def test_integrated_data_has_no_method2_odd_even_term() -> None:
    """Single Method 2 increments alternate by ⅓ T |ω × g|; pair sums (``integrated``) do not.

    Savage 2020 eqs. (49)-(50): ±(1/6) Δα × (Cᵀ g) T on Δv. In the local level the horizontal
    specific force of consecutive increments of the CM at rest then has a second difference of
    norm ⅓ T |ω × g|; summing each pair cancels it, which is why the ``integrated`` data set
    stands for the paper's data integrated from a continuous-time simulation.
    """
    for data, lo, hi in (("exact", 0.95, 1.05), ("integrated", 0.0, 1e-3)):
        s = wt3.load_streams("rest", wt3.PERIOD_SLOW, data, 24.0).cm
        c = dcm_from_quat(truth_navigation(s, np.arange(s.cycles))[5])
        f = np.einsum("nij,nj->ni", c, s.dv) / s.period
        w = np.einsum("nij,nj->ni", c, s.dalpha) / s.period
        second = f[1:-1] - 0.5 * (f[:-2] + f[2:])
        odd_even = np.linalg.norm(np.cross(w, [0.0, 0.0, -9.79])[1:-1, :2], axis=1) * s.period / 3
        ratio = np.linalg.norm(second[:, :2], axis=1).mean() / odd_even.mean()
        assert lo <= ratio <= hi, (data, ratio)


def test_exact_mode_at_least_10x_better_than_paper_at_n12(study) -> None:
    """Acceptance: the high-accuracy mode is ≥ 10× better than the paper mode at N = 12.

    On the exact streams it is at rounding/quadrature level; on integrated data (whose
    increments are not constant-rate) it keeps the error of a single-sample algorithm, still
    > 50× below the paper mode at 100 s (≈ 33× at 300 s).
    """
    for data in wt3.DATA:
        for case in wt3.CASES:
            for label in ("N=12", "Tnav/10"):
                for paper, exact in ((wt3.PAPER4, wt3.EXACT4), (wt3.PAPER40, wt3.EXACT40)):
                    p = _h(study, data, case, label, paper)
                    e = _h(study, data, case, label, exact)
                    assert p >= 10.0 * e, (data, case, label, paper.p, p, e)
                    if data == "exact":
                        assert e < 1e-5, (case, label, e)
                    else:
                        assert p >= 30.0 * e, (case, label, p, e)


def test_n120_much_better_than_n12_at_rest(study) -> None:
    """Paper mode at rest: N = 120 ≥ 5× better than N = 12 (paper: 17 m → 1 m)."""
    for data in wt3.DATA:
        for scheme in (wt3.PAPER4, wt3.PAPER40):
            ratio = _h(study, data, "rest", "N=12", scheme) / _h(
                study, data, "rest", "N=120", scheme
            )
            assert ratio >= 5.0, (data, scheme.name, ratio)


def test_scheme_order_at_n12(study) -> None:
    """N = 12: multirate better than simultaneous when moving, worse at rest (as in Table 3).

    Integrated data (the paper's kind). At rest the b–l split's own errors dominate (§4.1:
    the forced separation "diverges from reality when the vehicle is resting").
    """
    moving_s = _h(study, "integrated", "moving", "N=12", wt3.SIMULT)
    moving_m = _h(study, "integrated", "moving", "N=12", wt3.PAPER4)
    assert moving_m < 0.85 * moving_s, (moving_m, moving_s)
    rest_s = _h(study, "integrated", "rest", "N=12", wt3.SIMULT)
    rest_m = _h(study, "integrated", "rest", "N=12", wt3.PAPER4)
    assert rest_m > 1.5 * rest_s, (rest_m, rest_s)


def test_intermediate_rate_irrelevant(study) -> None:
    """§6: "No relevant change in performance resulted from varying T_int" (P = 4 vs 40)."""
    for data in wt3.DATA:
        for case in wt3.CASES:
            for label in ("N=12", "N=120", "Tnav/10"):
                a = _h(study, data, case, label, wt3.PAPER4)
                b = _h(study, data, case, label, wt3.PAPER40)
                assert abs(b / a - 1.0) < 0.2, (data, case, label, a, b)


def test_tnav_part_is_euler_truncation(study) -> None:
    """e(N=120) − e(T_nav/10) (same T_gyr) equals the Euler-truncation formulas.

    Multirate: −½ T_nav ΔU (eq. (9) with the start-of-cycle velocity). Simultaneous:
    ½ T_nav a(0) t − T_nav ΔU (eq. (14) with the start-of-cycle specific force, then (9)).
    """
    for data in wt3.DATA:
        parts = wt3.tnav_parts(study, data)
        assert len(parts) == 4
        for key, (measured, predicted) in parts.items():
            miss = np.linalg.norm(measured - predicted)
            assert miss < 0.15 + 0.05 * np.linalg.norm(predicted), (data, key, measured, predicted)
        # the IMU's initial acceleration (lever arm: 2 Ω_p² · 1 m) drives Table 2 at rest
        rest_s = parts[("rest", wt3.SIMULT.name)][0]
        assert rest_s[0] > 2.0


def test_tgyr_parts_equal_and_opposite(study) -> None:
    """e(N=12) − e(N=120) (same T_nav): ±δx, the first-order rotation-compensation term.

    Eq. (19)'s Euler step leaves out ½ Δφ × Δβ (+δx); Table 2's D_l^b(t_k) times the specific
    force of the next increment is late by T_gyr/2 (−δx; −⅔ δx on the exact streams, whose
    single increments carry Method 2's odd/even term). Their half-difference is δx (⅚ δx), the
    shared remainder is the attitude drift of the common eq. (33).
    """
    for data in wt3.DATA:
        parts = wt3.tgyr_parts(study, data)
        assert set(parts) == set(wt3.CASES)
        for case, (anti, predicted, common) in parts.items():
            miss = np.linalg.norm(anti - predicted)
            assert miss < 0.1 * np.linalg.norm(predicted), (data, case, anti, predicted)
            assert np.linalg.norm(common) < 0.5 * np.linalg.norm(anti), (data, case, common)


def test_moving_trends_at_300_s() -> None:
    """The distance-driven trends of Table 3, at the paper's 300 s (integrated data, CM moving).

    Multirate better than simultaneous at N = 12 and N = 120 (paper: 79 vs 119 m, 15 vs 45 m),
    and N = 120 much better than N = 12 for the multirate scheme (paper: 79 → 15 m).
    """
    cols = [c for c in wt3.COLUMNS if c.case == "moving" and c.label != "Tnav/10"]
    st = wt3.run_study(
        300.0, columns=cols, schemes=(wt3.SIMULT, wt3.PAPER4), data_sets=("integrated",),
        variants=False, phase=False, decomposition=False,
    )  # fmt: skip
    for label in ("N=12", "N=120"):
        s = _h(st, "integrated", "moving", label, wt3.SIMULT)
        m = _h(st, "integrated", "moving", label, wt3.PAPER4)
        assert m < s, (label, m, s)
    m12 = _h(st, "integrated", "moving", "N=12", wt3.PAPER4)
    m120 = _h(st, "integrated", "moving", "N=120", wt3.PAPER4)
    assert m12 > 5.0 * m120, (m12, m120)
