"""Samples of a ``samples`` trajectory from files: a CSV table or a bag's Odometry topic.

Both return :class:`~strapdown_ros.core.trajectory.samples.Samples` (canonical frames, SI, rad)
through :func:`~strapdown_ros.core.trajectory.samples.samples_from_arrays`. Errors are
:class:`SamplesInputError`, whose ``key`` names the scenario key at fault (``file``,
``columns``, ``rate_frame``, ``bag`` or ``topic`` under ``trajectory``). The CSV columns:
docs/theory/samples.md.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from strapdown_ros.core.array_types import F64
from strapdown_ros.core.trajectory.samples import Samples, check_times, samples_from_arrays

__all__ = [
    "CSV_COLUMNS",
    "CSV_NAMES",
    "SamplesInputError",
    "load_samples_csv",
    "odometry_samples",
]


#: CSV columns understood by :func:`load_samples_csv`, by group (all of a group or none).
CSV_COLUMNS: dict[str, tuple[str, ...]] = {
    "time": ("t",),  # or "time_s"
    "geodetic": ("lat_deg", "lon_deg", "alt_m"),
    "ecef": ("x_m", "y_m", "z_m"),
    "v_ned": ("vn_mps", "ve_mps", "vd_mps"),
    "v_ecef": ("vx_mps", "vy_mps", "vz_mps"),
    "euler": ("roll_deg", "pitch_deg", "heading_deg"),
    "quaternion": ("qw", "qx", "qy", "qz"),
    "rate": ("wx_radps", "wy_radps", "wz_radps"),
}
#: Every canonical column name (what ``columns`` may rename).
CSV_NAMES: tuple[str, ...] = (
    "t",
    "time_s",
    *(c for key, group in CSV_COLUMNS.items() if key != "time" for c in group),
)

RATE_FRAMES = ("inertial", "earth")


class SamplesInputError(ValueError):
    """Samples cannot be read; ``key`` is the ``trajectory`` key at fault (e.g. ``file``)."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}")

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # picklable
        return (type(self), (self.key, self.problem))


def load_samples_csv(
    path: str | Path, *, columns: Mapping[str, str] | None = None, rate_frame: str = "inertial"
) -> Samples:
    """Read samples from a CSV file with a header row.

    Accepted columns (units in the names; a group is all-or-nothing; other columns are
    ignored; blank lines and lines starting with ``#`` are skipped):

    ================================  ===========================================================
    ``t`` or ``time_s``               time (s), strictly increasing (required)
    ``lat_deg, lon_deg, alt_m``       geodetic WGS-84 position, ellipsoidal altitude — or
    ``x_m, y_m, z_m``                 ECEF position (one of the two is required)
    ``vn_mps, ve_mps, vd_mps``        velocity relative to the Earth, NED — or
    ``vx_mps, vy_mps, vz_mps``        the same in ECEF (optional)
    ``roll_deg, pitch_deg,            attitude of body FRD w.r.t. NED — or
    heading_deg``
    ``qw, qx, qy, qz``                quaternion ``q_B^N`` (FRD to NED, scalar first) (optional)
    ``wx_radps, wy_radps, wz_radps``  body rate, FRD axes (optional); relative to inertial
                                      space (gyro, ``rate_frame="inertial"``) or to the Earth
                                      (``rate_frame="earth"``)
    ================================  ===========================================================

    Parameters
    ----------
    path : str or Path
    columns : mapping, optional
        Renames: canonical column name (above) → the header name used in the file.
    rate_frame : {"inertial", "earth"}

    Raises
    ------
    SamplesInputError
        ``key`` ``file`` (naming the column and row: a missing column, a non-numeric or NaN
        cell, non-increasing time, an unreadable file), ``columns`` or ``rate_frame``.
    """
    path = Path(path)
    rename = dict(columns or {})
    unknown = sorted(set(rename) - set(CSV_NAMES))
    if unknown:
        raise SamplesInputError("columns", f"unknown canonical column name(s) {unknown}")
    if rate_frame not in RATE_FRAMES:
        raise SamplesInputError("rate_frame", f"'inertial' or 'earth', got {rate_frame!r}")
    if not path.is_file():
        raise SamplesInputError("file", f"{str(path)!r} does not exist")
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            lines = [ln for ln in fh if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise SamplesInputError("file", f"cannot read {path}: {exc}") from None
    rows = list(csv.reader(lines))
    if not rows:
        raise SamplesInputError("file", f"{path}: empty CSV (no header)")
    header = [h.strip() for h in rows[0]]
    index = {h: i for i, h in enumerate(header)}

    def fail(problem: str) -> SamplesInputError:
        return SamplesInputError("file", f"{path}: {problem}")

    def col(name: str) -> str:
        return rename.get(name, name)

    def has(name: str) -> bool:
        return col(name) in index

    def get(name: str) -> F64:
        j = index[col(name)]
        out = np.empty(len(rows) - 1)
        for r, row in enumerate(rows[1:]):
            cell = row[j].strip() if j < len(row) else ""
            try:
                out[r] = float(cell)
            except ValueError:
                raise fail(
                    f"column {col(name)!r}, data row {r + 1}: not a number ({cell!r})"
                ) from None
            if not math.isfinite(out[r]):
                raise fail(f"column {col(name)!r}, data row {r + 1}: NaN/inf value")
        return out

    def group(key: str) -> list[F64] | None:
        names = CSV_COLUMNS[key]
        present = [has(n) for n in names]
        if not any(present):
            return None
        if not all(present):
            missing = [col(n) for n, p in zip(names, present, strict=True) if not p]
            raise fail(
                f"missing column(s) {', '.join(missing)} (needed with "
                f"{', '.join(col(n) for n in names if has(n))})"
            )
        return [get(n) for n in names]

    tname = "t" if has("t") else "time_s"
    if not has(tname):
        raise fail("missing time column 't' (or 'time_s')")
    try:
        t = check_times(f"column {col(tname)}", get(tname))
    except ValueError as exc:
        raise fail(str(exc)) from None
    kw: dict[str, Any] = {}
    geo, ecef = group("geodetic"), group("ecef")
    if geo is not None and ecef is not None:
        raise fail("give lat_deg/lon_deg/alt_m or x_m/y_m/z_m, not both")
    if geo is not None:
        kw.update(lat=np.radians(geo[0]), lon=np.radians(geo[1]), alt=geo[2])
    elif ecef is not None:
        kw["r_ecef"] = np.stack(ecef, axis=-1)
    else:
        raise fail("missing position columns lat_deg, lon_deg, alt_m (or x_m, y_m, z_m)")
    vn, vx = group("v_ned"), group("v_ecef")
    if vn is not None and vx is not None:
        raise fail("give vn_mps/ve_mps/vd_mps or vx_mps/vy_mps/vz_mps, not both")
    if vn is not None:
        kw["v_ned"] = np.stack(vn, axis=-1)
    elif vx is not None:
        kw["v_ecef"] = np.stack(vx, axis=-1)
    eul, quat = group("euler"), group("quaternion")
    if eul is not None and quat is not None:
        raise fail("give roll_deg/pitch_deg/heading_deg or qw/qx/qy/qz, not both")
    if eul is not None:
        kw.update(roll=np.radians(eul[0]), pitch=np.radians(eul[1]), heading=np.radians(eul[2]))
    elif quat is not None:
        kw["q_b_n"] = np.stack(quat, axis=-1)
    rate = group("rate")
    if rate is not None:
        kw["omega_ib_b" if rate_frame == "inertial" else "omega_eb_b"] = np.stack(rate, -1)
    try:
        return samples_from_arrays(t, **kw)
    except ValueError as exc:
        raise fail(str(exc)) from None


def odometry_samples(path: str | Path, topic: str = "/reference/odom") -> Samples:
    """Samples from a bag's ``nav_msgs/Odometry`` topic (docs/interface.md §4 conventions).

    The messages give ECEF position, body FLU attitude relative to ECEF, and Earth-relative
    velocity and angular rate in body axes; they are converted to FRD and all four are
    returned (position, velocity, attitude ``C_B^E``, rate ``ω_eb^B``). Time is seconds since
    the first stamp.

    Raises
    ------
    SamplesInputError
        ``key`` ``bag`` (unreadable bag, unusable samples) or ``topic`` (absent or not
        Odometry).
    """
    from strapdown_ros.bag.reader import BagReadError, read_bag
    from strapdown_ros.messages import odometry_state

    path = Path(path)
    try:
        contents = read_bag(path, [topic])
    except BagReadError as exc:
        raise SamplesInputError("topic" if "no topic" in str(exc) else "bag", str(exc)) from None
    if topic not in contents.topics:
        raise SamplesInputError("topic", f"{topic!r} is not in {path}")
    if contents.topics[topic].msgtype != "nav_msgs/msg/Odometry":
        raise SamplesInputError(
            "topic", f"{topic!r} is {contents.topics[topic].msgtype}, not Odometry"
        )
    state = odometry_state(contents[topic])  # FRD body axes
    t = (state.stamps_ns - state.stamps_ns[0]) * 1e-9
    try:
        return samples_from_arrays(
            t, r_ecef=state.r_e, v_ecef=state.v_e, c_b_e=state.c_b_e, omega_eb_b=state.omega_eb_b
        )
    except ValueError as exc:
        raise SamplesInputError("bag", f"{path} {topic}: {exc}") from None
