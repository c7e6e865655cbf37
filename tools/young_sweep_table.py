"""The Markdown table of an orientation sweep, from its series (also of a sweep still running).

Usage: python tools/young_sweep_table.py DIR [--plot TITLE]

Reads DIR/series/<case>.npz (t, actual, nonlinear, linear θ, rad, written by
``strapdown-sim sweep-orientation`` as each case finishes) and prints one row per case: θ0, the
navigator's final angles, eq. (51)'s and the linear model's max |Δθ| and max relative error
(strapdown_ros.analysis.orientation.Agreement) and when the linear model first departs by more
than 10 % of |θ|. ``--plot TITLE``: also DIR/summary_partial.png (sweep_plots.plot_summary).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from strapdown_ros.analysis.orientation import Agreement
from strapdown_ros.analysis.sweep_plots import plot_summary
from strapdown_ros.core.young_nonlinear import wrap_angle

_CASE = re.compile(r"az(m?[\d.]+)_tilt(m?[\d.]+)$")


def _number(text: str) -> float:
    return -float(text[1:]) if text.startswith("m") else float(text)


def rows(out: Path) -> list[dict]:
    found = []
    for path in (out / "series").glob("*.npz"):
        m = _CASE.match(path.stem)
        if m is None:
            continue
        with np.load(path) as d:
            t, act, nl, li = d["t"], d["actual"], d["nonlinear"], d["linear"]
        found.append({
            "name": path.stem, "azimuth_deg": _number(m[1]), "tilt_deg": _number(m[2]),
            "theta0_deg": np.degrees(act[0]).tolist(),
            "final_deg": np.degrees(wrap_angle(act[-1])).tolist(),
            "duration_s": float(t[-1] - t[0]),
            "nonlinear": Agreement.of(t, nl, act).__dict__,
            "linear": Agreement.of(t, li, act).__dict__,
        })  # fmt: skip
    return sorted(found, key=lambda r: (r["tilt_deg"], r["azimuth_deg"]))


def table(found: list[dict]) -> str:
    lines = ["| initial error (az, tilt) | θ0 (deg) | navigator final θ (deg) | "
             "eq. (51): max \\|Δθ\\| (rad) | eq. (51): max rel. | linear: max \\|Δθ\\| (rad) | "
             "linear: max rel. | linear > 10 % of \\|θ\\| from (s) |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in found:
        nl, li = r["nonlinear"], r["linear"]
        dep = "never" if li["departure_s"] is None else f"{li['departure_s']:.0f}"
        th0 = ", ".join(f"{x:.1f}" for x in r["theta0_deg"])
        fin = ", ".join(f"{x:.1f}" for x in r["final_deg"])
        lines.append(f"| {r['azimuth_deg']:g}°, {r['tilt_deg']:g}° | {th0} | {fin} | "
                     f"{nl['max_norm']:.1e} | {nl['max_rel']:.1e} | {li['max_norm']:.2f} | "
                     f"{li['max_rel']:.2f} | {dep} |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    out = Path(argv[0])
    found = rows(out)
    print(table(found))
    if "--plot" in argv:
        title = argv[argv.index("--plot") + 1]
        cases = [{**r, "nonlinear": r["nonlinear"], "linear": r["linear"]} for r in found]
        plot_summary({"scenario": title, "setup": "damped", "cases": cases},
                     out / "summary_partial.png")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
