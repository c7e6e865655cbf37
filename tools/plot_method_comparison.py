"""Savage 2020 test example: Method 1 vs Method 2 velocity through the two rate changes.

Usage: python tools/plot_method_comparison.py OUT.png
Builds the example of test/test_savage_example.py ("paper" set: T = 0.01 s, ω = 0.5 rad/s,
ω' = 1.5 rad/s about body z, l = 1 m along body x) and plots the variation-minus-reference
velocity component along C(ω' × l), with the theoretical tangential velocities ω × l and
ω' × l. Prints the measured numbers quoted in docs/variation.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
from test_savage_example import SETS, K, example  # noqa: E402

from strapdown_ros.core.gravity import gravitation  # noqa: E402
from strapdown_ros.core.variation import OffsetArrays, generate_variation  # noqa: E402


def main(out: str) -> None:
    p = SETS["paper"]
    ref, off, rate, axis = example(**p)
    lever, T = np.asarray(p["lever"]), p["T"]
    m1 = generate_variation(ref, off, method=1)
    m2 = generate_variation(ref, off, method=2)
    regen = generate_variation(ref, OffsetArrays.zero(ref.cycles + 1), method=2)
    n = m1.cycles + 1
    c = ref.c_b_e0[:n]
    u = np.einsum("nij,j->ni", c, np.cross(axis, lever))
    u /= np.linalg.norm(u, axis=1, keepdims=True)  # direction of the tangential velocity
    d1 = np.einsum("ni,ni->n", m1.v_e0 - ref.v_e0[:n], u)
    d2 = np.einsum("ni,ni->n", m2.v_e0 - ref.v_e0[:n], u)
    paper_m = np.arange(n) - K
    w_l = p["w"] * np.linalg.norm(np.cross(axis, lever))
    w2_l = p["w2"] * np.linalg.norm(np.cross(axis, lever))
    theory = np.where(paper_m <= -9, 0.0, np.where(paper_m <= 0, w_l, w2_l))

    fig, ax = plt.subplots(figsize=(9, 4.8))
    ax.plot(paper_m, d1, "o-", ms=3, lw=0.8, label="Method 1 (eq. (9))")
    ax.plot(paper_m, d2, "s-", ms=3, lw=0.8, label="Method 2 (eq. (31))")
    ax.step(paper_m, theory, "k--", where="pre", lw=1, label="theory ω×l, ω'×l (eq. (44))")
    ax.axvline(-9, color="grey", lw=0.5)
    ax.axvline(0, color="grey", lw=0.5)
    ax.set(
        xlabel="paper cycle m (T = 10 ms)",
        ylabel="variation − reference velocity along C(ω'×l) [m/s]",
        title="Savage 2020 test example: |l| = 1 m, ω = 0.5 rad/s (m > −9), ω' = 1.5 rad/s (m > 0)",
    )
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=90)

    late = np.arange(K + 10, n - 1)
    print(
        f"Method 1 swing, -9 < m <= 0: {np.mean(np.abs(np.diff(d1[K - 8 : K + 1]))):.4f} m/s "
        f"(2|Δα×l|/T = {2 * w_l:.4f})"
    )
    print(f"Method 1 swing after m > 0: {np.mean(np.abs(np.diff(d1[late]))):.4f} m/s (sustained)")
    print(
        f"Method 2 after settling: {d2[late].mean():.6f} m/s (ω'×l = {w2_l:.6f}), "
        f"max odd/even swing {np.max(np.abs(np.diff(d2[late]))):.2e} m/s"
    )
    g_b = np.einsum("nji,nj->ni", c, gravitation(ref.r_e0[:n], "spherical"))
    term = np.linalg.norm(np.cross(p["w2"] * T * axis, g_b[late]), axis=1) * T / 6
    dv = regen.dv
    alt = np.linalg.norm(dv[late[2:] - 1] - 2 * dv[late[1:-1] - 1] + dv[late[:-2] - 1], axis=1) / 4
    print(
        f"Method 2 gravity alternation {np.median(alt):.3e} m/s per cycle vs |Δα×g|T/6 = "
        f"{np.median(term):.3e}"
    )


if __name__ == "__main__":
    main(sys.argv[1])
