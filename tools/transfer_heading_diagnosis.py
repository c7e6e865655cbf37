"""Diagnosis of the straight-flight heading overconfidence (docs/transfer_alignment.md §6).

Runs the transfer-alignment campaign (:mod:`strapdown_ros.stages.transfer_montecarlo`, same
arguments) with one change to the filter, for hypothesis tests only (``--mode``):

* ``base``: none;
* ``truth_jacobian``: F's ``[f^E0 ×]`` and ``C̄`` evaluated at the true slave attitude
  (``exp(−[φ×])`` applied to them, φ the true attitude error at the interval's end): the ideal
  EKF's F;
* ``no_reset``: the closed-loop reset ``I + ½[d×]`` of P's φ and μ blocks left out;
* ``first_estimate``: F's specific force with the velocity corrections injected at the
  interval's start added back, ``(V̂_k+1|k − V̂_k|k−1)/Δt − ḡ`` (Li & Mourikis 2013, IJRR 32(6),
  first-estimates Jacobians);
* ``attitude_r16``: the attitude-matching R sixteen times the master's (σ × 4);
* ``gyro_bias_x10``: the filter's P0 of the gyro's turn-on bias ten times wider (σ × 10; the
  runs' biases are drawn as before);
* ``no_velocity``: the velocity-matching updates left out (attitude matching alone).

Every run also prints, on stderr, the change of the mounting-yaw variance ``P_μz`` (mrad²)
summed over the velocity updates, the attitude updates (each with its reset) and the
propagations. Example::

    python tools/transfer_heading_diagnosis.py --mode truth_jacobian \\
        config/scenarios/transfer_alignment.yaml --runs 50 --straight --seed 2 --save DIR

``--regress DIR [DIR ...]`` instead reads saved runs and regresses each run's change of the
mounting-yaw error (first to last epoch) on its first value: a filter whose yaw σ falls from
σ_0 to σ_1 claims the slope ``−(1 − σ_1²/σ_0²)``; data without heading information give 0.
"""

import sys

import numpy as np

import strapdown_ros.core.transfer.filter as filt
import strapdown_ros.stages.transfer as stage
import strapdown_ros.stages.transfer_montecarlo as mc
from strapdown_ros.core.aided.layout import B_BG
from strapdown_ros.core.rotations import dcm_from_rotvec, rotvec_from_dcm


def _patch(mode: str) -> dict[str, float]:
    acc = {"velocity": 0.0, "attitude": 0.0, "propagate": 0.0}
    if mode == "truth_jacobian":
        real = filt.sparse_dynamics

        def sparse(cm, fe, *rest):  # type: ignore[no-untyped-def]
            c_true = getattr(filt, "_c_true", None)
            if c_true is not None:  # Ĉ at the interval's end (the prior) against the truth
                r = dcm_from_rotvec(-rotvec_from_dcm(filt._c_hat @ c_true.T))
                cm, fe = np.ascontiguousarray(r @ cm), r @ fe
            return real(cm, fe, *rest)

        filt.sparse_dynamics = sparse
        step, prop = stage.TransferStage._step, filt.TransferFilter.propagate

        def _step(self, m):  # type: ignore[no-untyped-def]
            filt._c_true = stage.dcm_e0_to_ecef(m * self.Ts).T @ self._truth[m][2]
            return step(self, m)

        def propagate(self, da, dv):  # type: ignore[no-untyped-def]
            # the kernel's end attitude is known only inside; use the estimate before it,
            # carried by the truth's own change over the interval (the same increments)
            filt._c_hat = None
            return prop(self, da, dv)

        stage.TransferStage._step = _step
        # Ĉ at the interval's end: taken from the filter after its kernel ran
        real_kernel = filt.exact_kernel

        def kernel(sr, sv, sc, *rest):  # type: ignore[no-untyped-def]
            out = real_kernel(sr, sv, sc, *rest)
            filt._c_hat = sc[-1].copy()
            return out

        filt.exact_kernel = kernel
        filt.TransferFilter.propagate = propagate
    elif mode == "no_reset":
        filt.reset_attitude = lambda p, d: None
        filt._reset_block = lambda p, i, d: None
    elif mode == "first_estimate":
        inject, real = filt.TransferFilter._inject, filt.sparse_dynamics

        def _inject(self, dx):  # type: ignore[no-untyped-def]
            filt._dv_injected = getattr(filt, "_dv_injected", np.zeros(3)) + dx[3:6]
            return inject(self, dx)

        def sparse(cm, fe, wb, fb, grad, est, off, beta, ni):  # type: ignore[no-untyped-def]
            dt = filt._dt
            fe = fe + getattr(filt, "_dv_injected", np.zeros(3)) / dt
            filt._dv_injected = np.zeros(3)
            return real(cm, fe, wb, fb, grad, est, off, beta, ni)

        prop = filt.TransferFilter.propagate

        def propagate(self, da, dv):  # type: ignore[no-untyped-def]
            filt._dt = len(np.asarray(da).reshape(-1, 3)) * self.T
            return prop(self, da, dv)

        filt.TransferFilter._inject = _inject
        filt.sparse_dynamics = sparse
        filt.TransferFilter.propagate = propagate
    elif mode == "attitude_r16":
        r_att = stage.TransferStage._r_attitude
        stage.TransferStage._r_attitude = lambda self, c: 16.0 * r_att(self, c)
    elif mode == "gyro_bias_x10":
        start = stage.TransferStage._start

        def _start(self):  # type: ignore[no-untyped-def]
            start(self)
            p = self.filter.p
            i = int(self.filter.off[B_BG])
            p[i : i + 3, :] *= 10.0
            p[:, i : i + 3] *= 10.0

        stage.TransferStage._start = _start
    elif mode == "no_velocity":
        filt.TransferFilter.update_velocity = (
            lambda self, *a, **k: filt.UpdateResult(np.zeros(3), 0.0, True))
    elif mode != "base":
        raise SystemExit(f"unknown --mode {mode}")

    def wrap(name, fn):  # type: ignore[no-untyped-def]
        def g(self, *a, **k):  # type: ignore[no-untyped-def]
            i = self.layout.i_mu + 2
            before = self.p[i, i]
            out = fn(self, *a, **k)
            acc[name] += self.p[i, i] - before
            return out
        return g

    for name in ("velocity", "attitude"):
        f = getattr(filt.TransferFilter, f"update_{name}")
        setattr(filt.TransferFilter, f"update_{name}", wrap(name, f))
    filt.TransferFilter.propagate = wrap("propagate", filt.TransferFilter.propagate)
    run = mc.run_transfer

    def run_transfer(sc, base, last):  # type: ignore[no-untyped-def]
        for k in acc:
            acc[k] = 0.0
        out = run(sc, base, last)
        print("ΔP_μz (mrad²): " + ", ".join(f"{k} {v * 1e6:.1f}" for k, v in acc.items()),
              file=sys.stderr, flush=True)
        return out

    mc.run_transfer = run_transfer
    return acc


def regress(directories: list[str]) -> None:
    """The yaw-change regression of the saved runs in ``directories`` (see the module doc)."""
    from pathlib import Path

    runs = [r for d in directories for r in mc.load_results(Path(d))]
    first = np.array([r.mounting[0, 2] for r in runs])
    change = np.array([r.mounting[-1, 2] for r in runs]) - first
    slope = float(np.polyfit(first, change, 1)[0])
    s0 = np.mean([r.mounting_sigma[0, 2] for r in runs])
    s1 = np.mean([r.mounting_sigma[-1, 2] for r in runs])
    print(f"{len(runs)} runs: yaw σ {s0 * 1e3:.2f} -> {s1 * 1e3:.2f} mrad, rms error "
          f"{np.sqrt(np.mean(first**2)) * 1e3:.2f} -> "
          f"{np.sqrt(np.mean((first + change) ** 2)) * 1e3:.2f} mrad; slope of the change on "
          f"the first error {slope:.3f}, claimed by σ {-(1 - s1**2 / s0**2):.3f}; mounting "
          f"NEES mean {np.mean([r.mounting_nees[0] for r in runs]):.3f} at the first epoch, "
          f"{np.mean([r.mounting_nees[-1] for r in runs]):.3f} at the last")


if __name__ == "__main__":
    args = sys.argv[1:]
    if args and args[0] == "--regress":
        regress(args[1:])
        sys.exit(0)
    mode = "base"
    if "--mode" in args:
        i = args.index("--mode")
        mode = args[i + 1]
        del args[i : i + 2]
    _patch(mode)
    sys.exit(mc.main(args))
