"""The report's transfer-alignment part: the slave against its truth, the mounting against the
truths' relative attitude.

A transfer-alignment filter is found by its outputs below a prefix ``P`` (default ``/transfer``,
:data:`strapdown_ros.config.transfer.TRANSFER_OUTPUTS`): ``P/odom``, ``P/vel`` and
``P/mounting/estimate``. Everything is recomputed from the bag's messages
(docs/transfer_alignment.md §1, docs/report.md):

* the slave's errors, σ, NEES: as an aided filter's (:func:`strapdown_ros.report.aided.aided_data`),
  against the slave's truth ``/variation/odom``; the NIS from ``P/nis`` (x: velocity matching,
  y: attitude matching, 3 degrees of freedom each);
* the true mounting ``M = C_Bvar^Bref = C_E^Bref C_Bvar^E`` (body FRD) from ``/reference/odom``
  and ``/variation/odom`` at the filter's stamps: constant for a fixed mount (the bending moves
  the lever arm, not the axes); its largest rotation from the first one is reported. On a
  scanning platform the relative attitude is ``C_mount C_scan(t)`` (Savage 2020 eq. (5),
  ``C_scan`` smoothed by Appendix D): the scan is removed with the offsets the bag's metadata
  records (``variation.offsets``, :func:`remove_scan`), leaving the zero-scan mounting
  ``C_mount`` the filter estimates; without that record the mounting part is omitted;
* the mounting error ``μ = rotvec(M̂ Mᵀ)`` (reference body axes, FLU as ``P/mounting/error``),
  ``M̂`` from the published roll, pitch, yaw of ``P/mounting/estimate``; σ per axis from
  ``P/mounting/sigma`` (the published diagonal: the 3-dof NEES needs the full block, so the
  yaw component's normalized square ``μ_z²/σ_z²`` is recomputed and compared with χ²(1));
* alignment times (first time after which the error stays below 1 mrad and 0.1 mrad) of the
  slave heading (Young's θ1, up) and of the mounting yaw.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.config.transfer import TRANSFER_OUTPUTS
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.rotations import (
    dcm_from_euler,
    euler_from_dcm,
    rotation_angle,
    rotvec_from_dcm,
)
from strapdown_ros.core.transfer.convergence import alignment_time
from strapdown_ros.messages import odometry_state
from strapdown_ros.plan.metadata import VARIATION_OFFSETS
from strapdown_ros.report.aided import (
    ODOMETRY,
    VECTOR3,
    AidedResult,
    Nis,
    _save,
    _scale,
    aided_data,
    chi2_bounds,
)

__all__ = [
    "MASTER_TRUTH",
    "SLAVE_TRUTH",
    "THRESHOLDS",
    "TransferResult",
    "plot_transfer_mounting",
    "remove_scan",
    "transfer_data",
    "transfer_prefixes",
    "transfer_table",
]

#: The slave's truth (the variation stream's Odometry) and the master's (the reference's).
SLAVE_TRUTH = "/variation/odom"
MASTER_TRUTH = "/reference/odom"
#: Alignment-time thresholds (rad) and their names.
THRESHOLDS = ((1e-3, "1 mrad"), (1e-4, "0.1 mrad"))
#: A relative attitude of the truths turning more than this (rad) is a scan, not round-off.
SCAN_TURN_RAD = 1e-9
_FLU = np.array([1.0, -1.0, -1.0])


def _topic(prefix: str, key: str) -> str:
    return f"{prefix}/{TRANSFER_OUTPUTS[key]}"


def transfer_prefixes(contents: BagContents) -> list[str]:
    """Prefixes with a transfer filter's ``odom`` (Odometry) and ``mounting/estimate``."""
    types = {t: d.msgtype for t, d in contents.topics.items() if len(d)}
    tail = "/" + TRANSFER_OUTPUTS["mounting"]
    return [t[: -len(tail)] for t, ty in types.items()
            if ty == VECTOR3 and t.endswith(tail)
            and types.get(_topic(t[: -len(tail)], "odom")) == ODOMETRY]  # fmt: skip


@dataclass
class TransferResult:
    """A transfer filter's slave solution and mounting estimate, recomputed from the bag."""

    prefix: str
    slave: AidedResult  #: the slave's errors against ``/variation/odom``
    t: F64  #: (K,) s since the bag start, the mounting's stamps
    mounting_true: F64  #: (3, 3) ``C_Bvar^Bref`` (FRD) from the truths at the first stamp
    mounting_spread: float  #: largest rotation (rad) of the truths' mounting from the first
    error: F64  #: (K, 3) rotvec(M̂ Mᵀ), reference body FLU (rad)
    sigma: F64  #: (K, 3) published σ of the same components (rad)
    published_error: F64 | None  #: (K, 3) the filter's ``P/mounting/error`` at the same stamps
    scan_removed: bool = False  #: the truths' relative attitude had a scan, removed (zero-scan)

    def yaw_normalized(self) -> F64:
        """(K,) ``μ_z² / σ_z²`` (one degree of freedom)."""
        return self.error[:, 2] ** 2 / self.sigma[:, 2] ** 2

    def inside_3sigma(self) -> F64:
        """(3,) fraction of epochs with |μ| ≤ 3σ per axis."""
        return np.mean(np.abs(self.error) <= 3.0 * self.sigma, axis=0)

    def alignment_times(self) -> dict[str, dict[str, float]]:
        """Threshold name -> {"slave heading", "mounting yaw"} -> time (s, NaN: never)."""
        heading = self.slave.errors["attitude"][:, 0]
        return {name: {"slave heading": alignment_time(self.slave.t, heading, thr),
                       "mounting yaw": alignment_time(self.t, self.error[:, 2], thr)}
                for thr, name in THRESHOLDS}  # fmt: skip


def _vectors(contents: BagContents, topic: str) -> tuple[np.ndarray, F64] | None:
    d = contents.topics.get(topic)
    if d is None or d.msgtype != VECTOR3 or not len(d):
        return None
    f = contents[topic]
    return (np.asarray(f.stamps_ns, dtype=np.int64),  # type: ignore[attr-defined]
            np.asarray(f.vector, dtype=np.float64))  # type: ignore[attr-defined]  # fmt: skip


def _nis(contents: BagContents, prefix: str, start_ns: int) -> list[Nis]:
    topic = _topic(prefix, "nis")
    got = _vectors(contents, topic)
    if got is None:
        return []
    st, v = got
    t = (st - start_ns) * 1e-9
    out = []
    for k, name in enumerate(("velocity", "attitude")):
        if k == 1 and not np.any(v[:, 1] != 0.0):  # attitude matching off: y stays 0
            continue
        n = len(st)
        out.append(Nis(name, topic, t, v[:, k], np.full(n, 3.0), np.ones(n, dtype=bool)))
    return out


def transfer_data(contents: BagContents, prefix: str, start_ns: int) -> TransferResult | str:
    """The :class:`TransferResult` of the filter under ``prefix`` (a string says why not)."""
    slave = aided_data(contents, prefix, start_ns, truth_topic=SLAVE_TRUTH)
    if isinstance(slave, str):
        return slave
    slave.nis = _nis(contents, prefix, start_ns)
    for topic in (MASTER_TRUTH, SLAVE_TRUTH):
        if contents.topics.get(topic) is None or not len(contents.topics[topic]):
            return f"no `{topic}` (the true mounting is the two truths' relative attitude)"
    est = _vectors(contents, _topic(prefix, "mounting"))
    sig = _vectors(contents, _topic(prefix, "mounting_sigma"))
    if est is None or sig is None:
        return f"no `{_topic(prefix, 'mounting')}` or `{_topic(prefix, 'mounting_sigma')}`"
    ref, var = odometry_state(contents[MASTER_TRUTH]), odometry_state(contents[SLAVE_TRUTH])  # type: ignore[arg-type]
    stamps = np.intersect1d(np.intersect1d(est[0], sig[0]),
                            np.intersect1d(ref.stamps_ns, var.stamps_ns))  # fmt: skip
    if not stamps.size:
        return f"`{prefix}` and the truths share no stamp"

    def at(st: np.ndarray, v: np.ndarray) -> np.ndarray:
        return v[np.searchsorted(st, stamps)]

    m_true = np.swapaxes(at(ref.stamps_ns, ref.c_b_e), -1, -2) @ at(var.stamps_ns, var.c_b_e)
    offsets = contents.custom_data.get(VARIATION_OFFSETS)
    if offsets is not None:
        m_true = remove_scan(m_true, stamps, offsets)
    else:
        turn = float(np.max(rotation_angle(m_true @ np.swapaxes(m_true[:1], -1, -2))))
        if turn > SCAN_TURN_RAD:
            return (f"the truths' relative attitude turns by {turn:.3g} rad (a scanning "
                    f"platform) and the bag's metadata has no `{VARIATION_OFFSETS}` to remove "
                    "the scan with: the true zero-scan mounting is unknown")  # fmt: skip
    rph = at(*est)
    m_hat = dcm_from_euler(rph[:, 0], rph[:, 1], rph[:, 2])
    mu = rotvec_from_dcm(m_hat @ np.swapaxes(m_true[:1], -1, -2)) * _FLU
    pub = _vectors(contents, _topic(prefix, "mounting_error"))
    published = None
    if pub is not None:
        published = np.full((stamps.size, 3), np.nan)
        _, a, b = np.intersect1d(stamps, pub[0], return_indices=True)
        published[a] = pub[1][b]
    spread = float(np.max(rotation_angle(m_true @ np.swapaxes(m_true[:1], -1, -2))))
    return TransferResult(prefix, slave, (stamps - start_ns) * 1e-9, m_true[0], spread, mu,
                          at(*sig), published, offsets is not None)  # fmt: skip


def remove_scan(m_true: F64, stamps_ns: np.ndarray, offsets_json: str) -> F64:
    """``C_rel C_scanᵀ`` (K, 3, 3): the zero-scan mounting ``C_mount`` from the truths' relative
    attitude ``C_rel = C_mount C_scan`` at ``stamps_ns``.

    ``C_scan = C_mountᵀ C_Bvar^Bref`` on the cycle grid, rebuilt from the recorded ``variation``
    section (:meth:`~strapdown_ros.core.offsets.OffsetModel.history`, the generator's offsets,
    Appendix D smoothing included); cycle ``m = (stamp − start_time_ns) / period_ns``.
    """
    from strapdown_ros.config.variation import VariationSpec

    rec = json.loads(offsets_json)
    model = VariationSpec.model_validate(rec["variation"]).offset_model()
    cycles = (np.asarray(stamps_ns, dtype=np.int64) - int(rec["start_time_ns"])) // int(
        rec["period_ns"])  # fmt: skip
    hist = model.history(int(rec["period_ns"]) * 1e-9, int(cycles.max()))
    c_scan = np.swapaxes(model.mount, -1, -2) @ hist.c_bvar_bref[cycles]
    return m_true @ np.swapaxes(c_scan, -1, -2)


# ------------------------------------------------------------------------------------------
# table and plot
# ------------------------------------------------------------------------------------------


def _e(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.2e}"


def transfer_table(r: TransferResult) -> list[str]:
    """Markdown lines: the true mounting, the mounting error against ±3σ, the yaw's normalized
    square against χ²(1), the alignment times."""
    roll, pitch, yaw = (np.degrees(float(x)) for x in euler_from_dcm(r.mounting_true))
    scan = (f", the scan removed with the bag's `{VARIATION_OFFSETS}`: the zero-scan mounting"
            if r.scan_removed else "")  # fmt: skip
    lines = [f"True mounting `C_Bvar^Bref` from `{MASTER_TRUTH}` and `{SLAVE_TRUTH}`{scan}: "
             f"roll {roll:.6f}°, pitch {pitch:.6f}°, yaw {yaw:.6f}° (constant to "
             f"{_e(r.mounting_spread)} rad over the {r.t.size} epochs).", ""]  # fmt: skip
    inside = r.inside_3sigma()
    head = "| mounting error | max \\|μ\\| | final μ (t = {:.3f} s) | final σ | inside ±3σ | unit |"
    lines += [head.format(r.t[-1]), "|---|---|---|---|---|---|"]
    for k, axis in enumerate(("x (forward)", "y (left)", "z (up)")):
        e, s = r.error[:, k], r.sigma[:, k]
        lines.append(f"| {axis} | {_e(float(np.abs(e).max()))} | {_e(float(e[-1]))} | "
                     f"{_e(float(s[-1]))} | {100 * inside[k]:.1f} % | rad |")  # fmt: skip
    lo, hi = chi2_bounds(1.0)
    yn = r.yaw_normalized()
    frac = float(np.mean((yn >= lo) & (yn <= hi)))
    lines += ["", f"Mounting yaw μ_z²/σ_z² (1 dof): mean {np.mean(yn):.3g}, {100 * frac:.1f} % "
              f"inside the 95 % χ² interval [{lo:.3g}, {hi:.3g}]."]  # fmt: skip
    if r.published_error is not None:
        ok = np.isfinite(r.published_error[:, 0])
        if ok.any():
            diff = float(np.max(np.abs(r.error[ok] - r.published_error[ok])))
            topic = _topic(r.prefix, "mounting_error")
            lines += ["", f"The mounting error recomputed from the truths agrees with the "
                      f"filter's `{topic}` to {_e(diff)} rad (max)."]  # fmt: skip
    lines += ["", "| alignment time | slave heading (θ1) | mounting yaw |", "|---|---|---|"]
    for name, times in r.alignment_times().items():
        cells = ["never" if not np.isfinite(v) else f"{v:.1f} s" for v in times.values()]
        lines.append(f"| to {name} | {cells[0]} | {cells[1]} |")
    lines += ["", "Alignment time: the first time after which |error| stays below the "
              "threshold until the end of the bag."]  # fmt: skip
    return lines


def plot_transfer_mounting(r: TransferResult, bag_name: str, path: Path) -> Path:
    """Mounting error per axis with the filter's ±3σ (log |error| beside it)."""
    fig = Figure(figsize=(13, 6.5), layout="constrained")
    axes = fig.subplots(2, 3, sharex=True)
    colors = ("tab:red", "tab:green", "tab:blue")
    f, unit = _scale(np.concatenate([r.error, 3 * r.sigma]), "rad")
    for k, axis in enumerate(("x (forward)", "y (left)", "z (up)")):
        ax = axes[0, k]
        band = 3.0 * r.sigma[:, k] * f
        ax.fill_between(r.t, -band, band, color=colors[k], alpha=0.15, lw=0, label="±3σ")
        ax.plot(r.t, r.error[:, k] * f, color=colors[k], lw=0.9, label="error")
        ax.set_title(f"mounting {axis} ({100 * r.inside_3sigma()[k]:.0f} % inside ±3σ)",
                     fontsize=9)  # fmt: skip
        ax.set_ylabel(f"[{unit}]")
        ax.grid(alpha=0.3)
        bx = axes[1, k]
        bx.semilogy(r.t, np.maximum(np.abs(r.error[:, k]), 1e-16), color=colors[k], lw=0.9,
                    label="|error|")  # fmt: skip
        bx.semilogy(r.t, np.maximum(r.sigma[:, k], 1e-16), color="black", lw=0.8, ls="--",
                    label="σ")  # fmt: skip
        for thr, _ in THRESHOLDS:
            bx.axhline(thr, color="gray", lw=0.6, ls=":")
        bx.set(ylabel="[rad]", xlabel="time since start [s]")
        bx.grid(alpha=0.3, which="both")
        if k == 0:
            ax.legend(fontsize=8, loc="upper right")
            bx.legend(fontsize=8, loc="upper right")
    fig.suptitle(f"{bag_name}: {r.prefix} mounting estimate minus the truths' relative attitude "
                 "(reference body FLU; dotted: 1 and 0.1 mrad)", fontsize=11)  # fmt: skip
    return _save(fig, path)
