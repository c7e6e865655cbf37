"""Figures of a ``strapdown-sim sweep-orientation`` output directory.

Usage: python tools/plot_young_sweep.py DIR [CASE ...]

Writes DIR/summary.png (max |θ_pred − θ_navigator| of Young 1980 eq. (51) and of the linear
model against the initial azimuth error) and DIR/series_<case>.png for every case (or the named
ones): the navigator's Young angles, eq. (51) and the linear model over time
(strapdown_ros.analysis.sweep_plots).
"""

from __future__ import annotations

import sys

from strapdown_ros.analysis.sweep_plots import plot_sweep


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    for path in plot_sweep(argv[0], argv[1:] or None):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
