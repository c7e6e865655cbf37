"""The report's aiding part: measured minus truth of every aiding topic, ±σ, outages, statistics.

The truth is the bag's own aiding section (``custom_data["aiding"]``, written by ``generate`` and
the recorder) re-run with its errors off (:func:`~strapdown_ros.stages.aiding.error_free_spec`)
on the bag's ``/reference/odom``: the same epochs, lever arms and frames, so each measured
message has its truth twin with the same stamp. Without that entry the sensors are taken at the
IMU (zero lever arms), which the report states. The band is ±σ of the message's own covariance
(the random part of the model; constant offsets and biases show as a shift). Errors: GNSS
position and velocity in NED (m, m/s), pressure (Pa), magnetic field in body FLU (µT), wheel
speed (m/s). See docs/aiding.md and docs/report.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.config.aiding import AIDING_TOPICS
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, geodetic_to_ecef

__all__ = ["AidingError", "aiding_errors", "aiding_table", "plot_aiding"]


_SENSOR_OF_TOPIC = {
    AIDING_TOPICS["gnss_fix"]: "gnss",
    AIDING_TOPICS["gnss_vel"]: "gnss",
    AIDING_TOPICS["baro"]: "barometer",
    AIDING_TOPICS["mag"]: "magnetometer",
    AIDING_TOPICS["wheel"]: "wheel_odometer",
}


@dataclass
class AidingError:
    """Measured minus truth of one aiding topic."""

    topic: str
    what: str  #: e.g. "GNSS position"
    unit: str
    axes: tuple[str, ...]
    t: F64  #: (N,) s since the start (header stamps)
    error: F64  #: (N, k)
    sigma: F64  #: (N, k) ±σ of the message covariance
    gaps: list[tuple[float, float]] = field(default_factory=list)  #: outage windows, s
    note: str = ""


def _gaps(t: F64, period: float) -> list[tuple[float, float]]:
    """Windows between consecutive stamps more than 1.5 periods apart (outages)."""
    if len(t) < 2:
        return []
    d = np.diff(t)
    idx = np.flatnonzero(d > 1.5 * period)
    return [(float(t[i]), float(t[i + 1])) for i in idx]


def aiding_errors(contents: BagContents, start_ns: int) -> dict[str, AidingError]:
    """Measured minus truth of every aiding topic in ``contents`` (empty dict: none)."""
    present = [t for t in _SENSOR_OF_TOPIC if t in contents.topics]
    if not present or "/reference/odom" not in contents.topics:
        return {}
    from strapdown_ros.stages.aiding import AidingStage, error_free_spec

    odom = contents["/reference/odom"]
    note = ""
    document = contents.custom_data.get("aiding")
    if document:
        doc = json.loads(document)
    else:
        doc = {_SENSOR_OF_TOPIC[t]: {} for t in present}
        note = "no aiding section in the bag's custom_data: sensors taken at the IMU"
    for t in present:  # the rates from the recorded stamps where the section is missing
        sensor = _SENSOR_OF_TOPIC[t]
        stamps = contents.topics[t].fields.stamps_ns  # type: ignore[union-attr]
        if "rate_hz" not in doc.get(sensor, {}) and len(stamps) > 1:
            doc.setdefault(sensor, {})["rate_hz"] = 1e9 / float(np.min(np.diff(stamps)))
    ideal = AidingStage.for_truth(
        error_free_spec(doc), int(odom.stamps_ns[0]), odom.child_frame_id  # type: ignore[attr-defined]
    )
    truth = {o.topic: o.fields for o in ideal.feed_fields(odom)}  # type: ignore[arg-type]
    out: dict[str, AidingError] = {}
    for topic in present:
        meas = contents[topic]
        ref = truth.get(topic)
        if ref is None:
            continue
        common, im, it = np.intersect1d(meas.stamps_ns, ref.stamps_ns, return_indices=True)
        if not len(common):
            continue
        t = (common - start_ns) * 1e-9
        period = 1.0 / doc[_SENSOR_OF_TOPIC[topic]]["rate_hz"]
        err: AidingError
        if topic == AIDING_TOPICS["gnss_fix"]:
            r_m = geodetic_to_ecef(np.radians(meas.latitude[im]), np.radians(meas.longitude[im]),
                                   meas.altitude[im])  # fmt: skip
            lat, lon = np.radians(ref.latitude[it]), np.radians(ref.longitude[it])
            r_t = geodetic_to_ecef(lat, lon, ref.altitude[it])
            e = np.einsum("nij,nj->ni", dcm_ecef_to_ned(lat, lon), r_m - r_t)
            cov = meas.position_covariance[im]
            sig = np.sqrt(np.abs(cov[:, [4, 0, 8]]))  # ENU diagonal -> N, E, U (=D) σ
            err = AidingError(topic, "GNSS position", "m", ("north", "east", "down"), t, e, sig)
        elif topic == AIDING_TOPICS["gnss_vel"]:
            d = meas.linear[im] - ref.linear[it]  # ENU
            e = np.stack([d[:, 1], d[:, 0], -d[:, 2]], axis=-1)
            sig = np.sqrt(np.abs(meas.covariance[im][:, [7, 0, 14]]))
            err = AidingError(topic, "GNSS velocity", "m/s", ("north", "east", "down"), t, e, sig)
        elif topic == AIDING_TOPICS["baro"]:
            e = (meas.fluid_pressure[im] - ref.fluid_pressure[it])[:, None]
            sig = np.sqrt(np.abs(meas.variance[im]))[:, None]
            err = AidingError(topic, "pressure", "Pa", ("p",), t, e, sig)
        elif topic == AIDING_TOPICS["mag"]:
            e = (meas.magnetic_field[im] - ref.magnetic_field[it]) * 1e6
            sig = np.sqrt(np.abs(meas.magnetic_field_covariance[im][:, [0, 4, 8]])) * 1e6
            err = AidingError(topic, "magnetic field", "µT", ("x (FLU)", "y", "z"), t, e, sig)
        else:
            e = (meas.linear[im, 0] - ref.linear[it, 0])[:, None]
            sig = np.sqrt(np.abs(meas.covariance[im][:, 0]))[:, None]
            err = AidingError(topic, "wheel speed", "m/s", ("x",), t, e, sig)
        err.gaps = _gaps(t, period)
        err.note = note
        out[topic] = err
    return out


def aiding_table(errors: dict[str, AidingError]) -> list[str]:
    """Markdown: per topic and axis, N, mean, std, RMS, max |error| and the model's σ."""
    lines = [
        "Measured minus truth (truth: the bag's aiding section with its errors off; σ: the "
        "message covariance, the random part of the model):",
        "",
        "| topic | axis | N | mean | std | RMS | max abs | σ (model) | unit |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for e in errors.values():
        for k, axis in enumerate(e.axes):
            x = e.error[:, k]
            lines.append(
                f"| `{e.topic}` | {axis} | {len(x)} | {x.mean():.4g} | {x.std():.4g} | "
                f"{np.sqrt(np.mean(x**2)):.4g} | {np.max(np.abs(x)):.4g} | "
                f"{float(np.median(e.sigma[:, k])):.4g} | {e.unit} |"
            )
    outages = [(e.topic, g) for e in errors.values() for g in e.gaps]
    if outages:
        lines += ["", "Outages (no message between): " + "; ".join(
            f"`{topic}` {a:.2f}–{b:.2f} s" for topic, (a, b) in outages)]  # fmt: skip
    notes = sorted({e.note for e in errors.values() if e.note})
    lines += ["", *notes] if notes else []
    return lines


AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")


def plot_aiding(errors: dict[str, AidingError], title: str, path: Path) -> Path:
    """One panel per topic: error per axis over time, the ±σ band, outages shaded."""
    n = len(errors)
    fig = Figure(figsize=(12, 2.6 * n + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    for ax, e in zip(axes, errors.values(), strict=True):
        for k in range(len(e.axes)):
            color = AXIS_COLORS[k % 3]
            ax.plot(e.t, e.error[:, k], ".", ms=1.5, color=color)
            ax.fill_between(e.t, -e.sigma[:, k], e.sigma[:, k], color=color, alpha=0.12,
                            lw=0)  # fmt: skip
        for a, b in e.gaps:
            ax.axvspan(a, b, color="grey", alpha=0.25, lw=0)
        handles = [Line2D([], [], ls="", marker="o", color=AXIS_COLORS[k % 3], label=axis)
                   for k, axis in enumerate(e.axes)]  # fmt: skip
        if e.gaps:
            handles.append(Patch(color="grey", alpha=0.25, label="outage"))
        handles.append(Patch(color="grey", alpha=0.12, label="±σ (message covariance)"))
        ax.set(ylabel=f"{e.what} [{e.unit}]", title=f"{e.topic}: measured − truth")
        ax.grid(alpha=0.3)
        ax.legend(handles=handles, fontsize=8, loc="upper right", ncol=len(handles))
    axes[-1].set_xlabel("time since start [s]")
    fig.suptitle(title, fontsize=12)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path
