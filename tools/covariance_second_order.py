"""Second-order diagnostics of a free-inertial campaign against the linear covariance model.

Usage: python tools/covariance_second_order.py CAMPAIGN_DIR BAG

CAMPAIGN_DIR, BAG as for tools/plot_covariance_campaign.py. Prints, at the last epoch:

* the down position against the Earth's curvature under the horizontal error,
  ``c = (δr_N²/(R_N+h) + δr_E²/(R_E+h)) / 2`` (the error topic's NED vector at the true
  position puts a horizontally displaced point c below the tangent plane): RMS of both, their
  correlation and the RMS of ``δr_D - c``;
* at a quarter, half and all of the run, the down velocity's residual about the predicted mean
  against ``w = (δv_N² + δv_E²)/R_N``: its RMS, mean, correlation with w, and the RMS left
  after a least-squares line on w, beside σ_pred;
* the RMS over the runs of the drawn turn-on bias normals (in σ) per axis of both triads
  (the draws of ``covariance_check.realized_initial_covariance``).
"""

from __future__ import annotations

import sys

import numpy as np

from strapdown_ros.analysis import covariance_check as cc
from strapdown_ros.campaign.results import finished_runs
from strapdown_ros.config import navigator_spec
from strapdown_ros.core.earth import radii


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    out, bag = argv
    scenario = cc.campaign_scenario(out)
    ensemble = cc.read_ensemble(out)
    pred = cc.predict_scenario(scenario, bag)
    _, ip, ie = np.intersect1d(pred.stamps_ns, ensemble.stamps_ns, return_indices=True)
    lat, alt = np.radians(scenario.initial.latitude_deg), scenario.initial.altitude_m
    r_n, r_e = (float(r) + alt for r in radii(lat))
    x = ensemble.errors[:, ie[-1]]
    c = 0.5 * (x[:, 0] ** 2 / r_n + x[:, 1] ** 2 / r_e)

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(a**2)))

    print(f"{out}: {x.shape[0]} runs")
    print(f"pos_d: RMS {rms(x[:, 2]):.4g} m, curvature c RMS {rms(c):.4g} m, correlation "
          f"{np.corrcoef(c, x[:, 2])[0, 1]:.10f}, RMS(pos_d - c) {rms(x[:, 2] - c):.3g} m, "
          f"σ_pred {pred.sigma[ip[-1], 2]:.3g} m")  # fmt: skip
    k_all = ip.shape[0]
    for k in (k_all // 4, k_all // 2, k_all - 1):
        e = ensemble.errors[:, ie[k]]
        r = e[:, 5] - pred.mean[ip[k], 5]
        w = (e[:, 3] ** 2 + e[:, 4] ** 2) / r_n
        fit = np.polyfit(w, r, 1)
        t = (pred.stamps_ns[ip[k]] - pred.stamps_ns[ip[0]]) * 1e-9
        print(f"vel_d at {t:.0f} s: residual RMS {rms(r):.3g} m/s, mean {r.mean():+.3g} m/s, "
              f"corr with w {np.corrcoef(w, r)[0, 1]:.2f}, RMS after a line on w "
              f"{rms(r - np.polyval(fit, w)):.3g} m/s, σ_pred {pred.sigma[ip[k], 5]:.3g} m/s")
    nav = navigator_spec(scenario)
    assert nav is not None
    spec = scenario.imu_errors_of(nav.imu_topic)  # the navigator's model
    index = scenario.imu_errors.index(spec)
    key = "imu_errors.seed" if len(scenario.imu_errors) == 1 else f"imu_errors.{index}.seed"
    seeds = cc.campaign_seeds(out, sorted(finished_runs(out)), key)
    u = np.array([np.random.Generator(np.random.PCG64(s)).standard_normal((2, 15))
                  for s in seeds])  # fmt: skip
    for k, name in enumerate(("gyro", "accel")):
        print(f"{name} turn-on bias draws, RMS in σ (x, y, z): "
              + ", ".join(f"{v:.3f}" for v in np.sqrt(np.mean(u[:, k, 0:3] ** 2, axis=0))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
