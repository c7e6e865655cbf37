"""Plot a reference bag: ground track, altitude, speed and the interface.md §3 one-step residuals.

Usage: python tools/plot_reference.py BAG_DIR OUT.png

Reads the bag back from disk with the loader of ``strapdown-sim report``
(:func:`strapdown_ros.report.data.load_bag`: Odometry and Imu of /reference), so the figure
shows what a user of the dataset gets. Used for the README picture
(docs/images/default_reference.png); ``strapdown-sim report`` draws the full set of plots.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from strapdown_ros.core.earth import dcm_ecef_to_ned  # noqa: E402
from strapdown_ros.report.data import load_bag  # noqa: E402


def main(bag: str, out: str) -> None:
    # the report's loader: streams (geodetic, NED velocity), IMU topics and docs/interface.md §3
    # residuals
    data = load_bag(bag, allan=False)
    ref = data.streams["/reference"]
    t, alt, v_ned = ref.t, ref.alt, ref.v_ned
    _, res = data.residuals["/reference"]
    ned = (ref.r_e - ref.r_e[0]) @ dcm_ecef_to_ned(ref.lat[0], ref.lon[0]).T
    north, east = ned[:, 0], ned[:, 1]

    fig, ax = plt.subplots(2, 2, figsize=(11, 7.5))
    ax[0, 0].plot(east / 1e3, north / 1e3)
    ax[0, 0].plot(east[0] / 1e3, north[0] / 1e3, "go", label="start")
    ax[0, 0].plot(east[-1] / 1e3, north[-1] / 1e3, "rs", label="end")
    ax[0, 0].set(xlabel="east [km]", ylabel="north [km]", title="ground track", aspect="equal")
    ax[0, 0].legend()
    ax[0, 1].plot(t, alt, label="altitude [m]")
    ax[0, 1].plot(t, np.linalg.norm(v_ned[:, :2], axis=1), label="ground speed [m/s]")
    ax[0, 1].set(xlabel="time [s]", title="altitude and ground speed")
    ax[0, 1].legend()
    f = data.imus["/reference"].accel
    ax[1, 0].plot(t[1:], f[:, 0], lw=0.6, label="x (forward)")
    ax[1, 0].plot(t[1:], f[:, 1], lw=0.6, label="y (left)")
    ax[1, 0].plot(t[1:], f[:, 2], lw=0.6, label="z (up)")
    ax[1, 0].set(xlabel="time [s]", ylabel="Δv/T [m/s²]", title="published specific force (FLU)")
    ax[1, 0].legend()
    for values, label in (
        (res.position, "position [m]"),
        (res.velocity, "velocity [m/s]"),
        (res.attitude, "attitude [rad]"),
    ):
        ax[1, 1].semilogy(t[1:], np.maximum(values, 1e-20), ".", ms=1, label=label)
    for tol in (1e-7, 1e-9, 1e-11):
        ax[1, 1].axhline(tol, color="k", lw=0.5, ls="--")
    ax[1, 1].set(
        xlabel="time [s]",
        title="one-step residuals, eqs. (2)-(4) (dashed: docs/interface.md §3 limits)",
        ylim=(1e-18, 1e-5),
    )
    ax[1, 1].legend(markerscale=8)
    name = Path(bag).name
    fig.suptitle(f"reference stream of {name}: {res.position.size} cycles, read back from the bag")
    fig.tight_layout()
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
