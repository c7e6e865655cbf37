"""What the report shows, computed from a bag read back from disk (numpy only, no plotting).

The report knows topics by their role, found from the names and types of docs/interface.md §4 (every
name is
a parameter, so roles come from the last name component under a common prefix):

* a **stream** is a prefix ``P`` with ``P/odom`` (nav_msgs/Odometry) and/or ``P/fix``
  (sensor_msgs/NavSatFix), optionally ``P/imu``: ``/reference``, ``/variation``,
  ``/variation/reference`` (the regenerated reference), ``/navigator``;
* an **error set** is a prefix ``P`` with ``P/error/position``, ``P/error/velocity``,
  ``P/error/attitude`` (geometry_msgs/Vector3Stamped; any subset);
* a **measured IMU** is ``P/imu_measured`` (sensor_msgs/Imu), paired with the ideal ``P/imu``
  when present.

Times are seconds since the bag's first header stamp.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import yaml
from numpy.typing import NDArray

from strapdown_ros.bag.reader import BagContents, read_bag
from strapdown_ros.checks import CheckSettings, check_pair, check_settings, is_ecef
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import dcm_ecef_to_ned, ecef_to_geodetic, ned_velocity_from_ecef
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.rotations import euler_from_dcm, rotation_angle
from strapdown_ros.messages import (
    ImuFields,
    NavSatFixFields,
    OdometryFields,
    Vector3StampedFields,
    navsatfix_geodetic,
    odometry_state,
)

__all__ = [
    "AllanResult",
    "BagData",
    "ErrorSet",
    "ImuData",
    "MeasuredImu",
    "ReportError",
    "StreamData",
    "load_bag",
]


ODOMETRY = "nav_msgs/msg/Odometry"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
IMU = "sensor_msgs/msg/Imu"
VECTOR3 = "geometry_msgs/msg/Vector3Stamped"

#: Leaf names of the navigator error topics and what they carry.
ERROR_LEAVES = ("position", "velocity", "attitude")


class ReportError(RuntimeError):
    """The report cannot be made (e.g. the bag has no topic the report understands)."""


@dataclass
class _Prefixed:
    """Data under a topic prefix ``P`` (``P/...`` topics); :attr:`label` names them in tables and
    legends."""

    #: The label of the root prefix (``/``).
    ROOT_LABEL: ClassVar[str] = "root"

    prefix: str

    @property
    def label(self) -> str:
        """The prefix without its slashes (``variation/reference``), or :attr:`ROOT_LABEL`."""
        return self.prefix.strip("/") or self.ROOT_LABEL


@dataclass
class StreamData(_Prefixed):
    """Truth or navigation solution of one prefix (from Odometry, else NavSatFix)."""

    source: str  #: the topic the data come from
    t: F64  #: (N,) s since the bag start
    lat: F64  #: (N,) rad
    lon: F64  #: (N,) rad
    alt: F64  #: (N,) m, ellipsoidal
    stamps_ns: NDArray[np.int64]
    r_e: F64 | None = None  #: (N, 3) ECEF position, m (Odometry only)
    v_ned: F64 | None = None  #: (N, 3) m/s (Odometry only)
    rph: F64 | None = None  #: (N, 3) roll, pitch, heading of FRD w.r.t. NED, rad (Odometry only)


@dataclass
class ImuData:
    """One Imu topic: rates and specific force as published (FLU)."""

    topic: str
    t: F64
    stamps_ns: NDArray[np.int64]
    gyro: F64  #: (N, 3) rad/s FLU (Δα/T)
    accel: F64  #: (N, 3) m/s² FLU (Δv/T)
    gyro_var: F64 | None  #: (3,) mean diagonal of angular_velocity_covariance, (rad/s)²
    accel_var: F64 | None  #: (3,) mean diagonal of linear_acceleration_covariance, (m/s²)²
    frame_id: str = ""
    measured: bool = False  #: an IMU error model's output (``P/imu_measured``)
    #: The IMU's FLU axes named by the vehicle direction each points to as mounted
    #: (:func:`mount_axis_labels`); plain axis names when the mount is unknown.
    axis_labels: tuple[str, str, str] = ("x", "y", "z")

    @property
    def period_s(self) -> float:
        d = np.diff(self.stamps_ns)
        return float(np.median(d)) * 1e-9 if d.size else float("nan")


@dataclass
class AllanResult:
    """Overlapping Allan deviation per axis (columns x, y, z FLU)."""

    taus: F64
    adev: F64  #: (K, 3)


@dataclass
class MeasuredImu:
    """A measured IMU topic, its ideal twin (if any) and their Allan deviations."""

    measured: ImuData
    ideal: ImuData | None
    #: Allan deviation of measured minus ideal (the sensor error), gyro and accel; None without
    #: the ideal twin.
    error_gyro: AllanResult | None = None
    error_accel: AllanResult | None = None
    #: Allan deviation of the measured data themselves (motion included).
    total_gyro: AllanResult | None = None
    total_accel: AllanResult | None = None


@dataclass
class ErrorSet(_Prefixed):
    """Navigator errors under one prefix (each (t, (N, 3)) or None)."""

    ROOT_LABEL = "errors"

    position: tuple[F64, F64] | None = None  #: NED, m
    velocity: tuple[F64, F64] | None = None  #: NED, m/s
    attitude: tuple[F64, F64] | None = None  #: Young θ1, θ2, θ3 (up, east, north), rad


@dataclass
class BagData:
    """Everything the report needs from one bag."""

    path: Path
    contents: BagContents
    start_ns: int
    end_ns: int
    streams: dict[str, StreamData] = field(default_factory=dict)
    imus: dict[str, ImuData] = field(default_factory=dict)
    residuals: dict[str, tuple[str, Residuals | str]] = field(default_factory=dict)
    errors: dict[str, ErrorSet] = field(default_factory=dict)
    measured: dict[str, MeasuredImu] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: Imu topics outside the ``P/imu`` / ``P/imu_measured`` names (e.g. a robot's
    #: ``/imu/data``), by topic: plotted, not checked.
    other_imus: dict[str, ImuData] = field(default_factory=dict)
    settings: CheckSettings | None = None  #: how the streams were verified

    @property
    def name(self) -> str:
        return self.path.resolve().name

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) * 1e-9

    @property
    def start_utc(self) -> str:
        """Start time as ISO 8601 UTC."""
        sec, ns = divmod(self.start_ns, 1_000_000_000)
        t = _dt.datetime.fromtimestamp(sec, tz=_dt.UTC)
        return t.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns // 1_000_000:03d}Z"

    def truth_for_summary(self) -> StreamData | None:
        """The stream to show first: the reference, else the first non-navigator stream."""
        if "/reference" in self.streams:
            return self.streams["/reference"]
        for p, s in self.streams.items():
            if not is_navigator(p):
                return s
        return next(iter(self.streams.values()), None)

    def variation_streams(self) -> list[StreamData]:
        """Streams with Odometry that are neither the reference, a regenerated reference nor
        a navigator (the variation IMUs: one per method or lever arm)."""
        return [
            s
            for p, s in self.streams.items()
            if s.r_e is not None and p != "/reference" and not is_regenerated(p)
            and not is_navigator(p)
        ]  # fmt: skip


def is_navigator(prefix: str) -> bool:
    return "navigator" in prefix


def is_regenerated(prefix: str) -> bool:
    """``/variation/reference``-style prefixes: a reference regenerated through Method 2."""
    return prefix.endswith("/reference") and prefix != "/reference"


def _split(topic: str) -> tuple[str, str]:
    prefix, _, leaf = topic.rpartition("/")
    return prefix, leaf


def _seconds(stamps_ns: NDArray[np.int64], start_ns: int) -> F64:
    return (np.asarray(stamps_ns, dtype=np.int64) - start_ns).astype(np.float64) * 1e-9


def _stream_from_odometry(prefix: str, topic: str, odom: OdometryFields, start: int) -> StreamData:
    state = odometry_state(odom)
    lat, lon, alt = ecef_to_geodetic(state.r_e)
    c_b_n = dcm_ecef_to_ned(lat, lon) @ state.c_b_e
    roll, pitch, heading = euler_from_dcm(c_b_n)
    return StreamData(
        prefix=prefix,
        source=topic,
        t=_seconds(state.stamps_ns, start),
        lat=np.asarray(lat, dtype=np.float64),
        lon=np.asarray(lon, dtype=np.float64),
        alt=np.asarray(alt, dtype=np.float64),
        stamps_ns=state.stamps_ns,
        r_e=state.r_e,
        v_ned=ned_velocity_from_ecef(lat, lon, state.v_e),
        rph=np.stack([roll, pitch, heading], axis=-1),
    )


def _stream_from_fix(prefix: str, topic: str, fix: NavSatFixFields, start: int) -> StreamData:
    stamps, lat, lon, alt = navsatfix_geodetic(fix)
    return StreamData(prefix, topic, _seconds(stamps, start), lat, lon, alt, stamps)


def _covariance_diagonal(cov: F64) -> F64 | None:
    """Mean diagonal (3,) of (N, 9) covariances; None when unknown (zeros) or not provided."""
    cov = np.asarray(cov, dtype=np.float64)
    if cov.ndim != 2 or cov.shape[0] == 0 or np.any(cov[:, 0] < 0):
        return None
    diag = cov[:, [0, 4, 8]].mean(axis=0)
    return diag if np.any(diag > 0) else None


def _imu(topic: str, f: ImuFields, start: int, measured: bool = False) -> ImuData:
    return ImuData(
        topic=topic,
        t=_seconds(f.stamps_ns, start),
        stamps_ns=np.asarray(f.stamps_ns, dtype=np.int64),
        gyro=np.asarray(f.angular_velocity, dtype=np.float64),
        accel=np.asarray(f.linear_acceleration, dtype=np.float64),
        gyro_var=_covariance_diagonal(f.angular_velocity_covariance),
        accel_var=_covariance_diagonal(f.linear_acceleration_covariance),
        frame_id=str(getattr(f, "frame_id", "")),
        measured=measured,
    )


def allan_deviation(rate: F64, period_s: float) -> AllanResult | None:
    """Overlapping Allan deviation per column (``strapdown_ros.core.allan``); None if too short."""
    from strapdown_ros.core.allan import overlapping_allan_deviation

    if rate.shape[0] < 4 or not np.isfinite(period_s) or period_s <= 0:
        return None
    taus, adev = overlapping_allan_deviation(rate, period_s)
    taus = np.asarray(taus, dtype=np.float64)
    adev = np.asarray(adev, dtype=np.float64).reshape(taus.shape[0], -1)
    if taus.size == 0:
        return None
    return AllanResult(taus, adev)


def _measured_imu(measured: ImuData, ideal: ImuData | None) -> MeasuredImu:
    out = MeasuredImu(measured, ideal)
    period = measured.period_s
    out.total_gyro = allan_deviation(measured.gyro, period)
    out.total_accel = allan_deviation(measured.accel, period)
    if ideal is not None:
        common, i, j = np.intersect1d(measured.stamps_ns, ideal.stamps_ns, return_indices=True)
        if common.size >= 4:
            out.error_gyro = allan_deviation(measured.gyro[i] - ideal.gyro[j], period)
            out.error_accel = allan_deviation(measured.accel[i] - ideal.accel[j], period)
    return out


def _odometry_topics(path: Path) -> list[str] | None:
    """Odometry topics listed in ``metadata.yaml`` (None if it cannot be read: the reader then
    reports the problem)."""
    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        entries = info["rosbag2_bagfile_information"]["topics_with_message_count"]
        return [
            e["topic_metadata"]["name"] for e in entries if e["topic_metadata"]["type"] == ODOMETRY
        ]
    except (OSError, yaml.YAMLError, TypeError, KeyError):
        return None


def load_bag(
    path: str | Path,
    *,
    exactness: bool = True,
    allan: bool = True,
    odometry_only: bool = False,
    gravity_model: str | None = None,
) -> BagData:
    """Read a bag and derive the report's data (see the module docstring for the roles).

    ``odometry_only`` reads only the Odometry topics (what a comparison needs; faster).
    ``gravity_model``: the model the exactness re-check uses (default: the bag's metadata's,
    :func:`strapdown_ros.checks.check_settings`). Odometry whose positions are not ECEF (a
    robot's ``odom`` frame) is listed in ``notes``, not drawn as a trajectory.
    Raises :class:`~strapdown_ros.bag.reader.BagReadError` for an unreadable bag and
    :class:`ReportError` for a bag without any topic the report understands (or a gravity
    model it cannot use).
    """
    topics = _odometry_topics(Path(path)) if odometry_only else None
    contents = read_bag(path, topics)
    typed = {t: d for t, d in contents.topics.items() if d.fields is not None and len(d)}
    if not typed:
        raise ReportError(
            f"bag {contents.path} has no messages of a type the report reads "
            f"(topics: {sorted(contents.topics) or 'none'})"
        )
    firsts = [int(np.min(d.fields.stamps_ns)) for d in typed.values()]  # type: ignore[attr-defined]
    lasts = [int(np.max(d.fields.stamps_ns)) for d in typed.values()]  # type: ignore[attr-defined]
    start = min(firsts)
    data = BagData(Path(path), contents, start, max(lasts))
    from strapdown_ros.checks.settings import SettingsError

    try:
        data.settings = check_settings(contents.custom_data, gravity_model)
    except SettingsError as exc:
        raise ReportError(str(exc)) from None

    by_prefix: dict[str, dict[str, str]] = {}
    for topic, d in typed.items():
        prefix, leaf = _split(topic)
        by_prefix.setdefault(prefix, {})[leaf] = d.msgtype

    for prefix, leaves in by_prefix.items():
        odom_t, fix_t = f"{prefix}/odom", f"{prefix}/fix"
        ecef = leaves.get("odom") == ODOMETRY and is_ecef(odometry_state(contents[odom_t]).r_e)
        if leaves.get("odom") == ODOMETRY and not ecef:
            frame = getattr(contents[odom_t], "frame_id", "?")
            data.notes.append(
                f"`{odom_t}`: Odometry in frame `{frame}` with positions that are not ECEF "
                "(a local frame): not drawn as a trajectory, not checked"
            )
        if ecef:
            data.streams[prefix] = _stream_from_odometry(prefix, odom_t, contents[odom_t], start)
        elif leaves.get("fix") == NAVSATFIX:
            data.streams[prefix] = _stream_from_fix(prefix, fix_t, contents[fix_t], start)
        if leaves.get("imu") == IMU:
            data.imus[prefix] = _imu(f"{prefix}/imu", contents[f"{prefix}/imu"], start)
        for leaf, ty in leaves.items():
            if ty == IMU and leaf not in ("imu", "imu_measured"):
                topic = f"{prefix}/{leaf}"
                data.other_imus[topic] = _imu(topic, contents[topic], start)

    # Navigator errors: P/error/{position,velocity,attitude}
    for prefix, leaves in by_prefix.items():
        if not prefix.endswith("/error"):
            continue
        owner = prefix[: -len("/error")] or "/"
        es = ErrorSet(owner)
        for leaf in ERROR_LEAVES:
            if leaves.get(leaf) == VECTOR3:
                f: Vector3StampedFields = contents[f"{prefix}/{leaf}"]  # type: ignore[assignment]
                vec = np.asarray(f.vector, dtype=np.float64)
                setattr(es, leaf, (_seconds(f.stamps_ns, start), vec))
        if es.position or es.velocity or es.attitude:
            data.errors[owner] = es

    if exactness:
        model = data.settings.gravity_model
        for prefix, imu in data.imus.items():
            odom_t = f"{prefix}/odom"
            if odom_t not in typed or is_navigator(prefix):
                continue
            v = check_pair(contents, imu.topic, odom_t, model)
            data.residuals[prefix] = (v.pair, v.residuals or f"not checked: {v.reason}")

    for prefix, leaves in by_prefix.items():
        if leaves.get("imu_measured") != IMU:
            continue
        topic = f"{prefix}/imu_measured"
        meas = _imu(topic, contents[topic], start, measured=True)
        if not allan:
            data.measured[prefix] = MeasuredImu(meas, data.imus.get(prefix))
            continue
        data.measured[prefix] = _measured_imu(meas, data.imus.get(prefix))
    _label_axes(data)
    return data


# ------------------------------------------------------------------------------------------
# IMU axes as mounted
# ------------------------------------------------------------------------------------------

#: Names of the vehicle's FLU directions (+ and −), REP-103 body axes.
VEHICLE_DIRECTIONS = (("forward", "aft"), ("left", "right"), ("up", "down"))
#: An IMU axis is named by a vehicle direction when within this angle of it (rad, 1°).
ALIGNED_RAD = np.radians(1.0)
#: The mount is fixed when it turns by less than this over the bag (rad).
FIXED_MOUNT_RAD = 1e-6


def mount_flu(c_ref_e: F64, c_imu_e: F64) -> F64:
    """``C_IMU^Vehicle`` in FLU axes, (N, 3, 3): column j is IMU axis j in vehicle FLU.

    ``c_ref_e``, ``c_imu_e``: ``C_FRD^E`` (N, 3, 3) of the vehicle (reference) and the IMU;
    ``C = D C_ref^T C_imu D`` with ``D = diag(1, −1, −1)`` (FRD ↔ FLU).
    """
    d = np.diag([1.0, -1.0, -1.0])
    return d @ np.swapaxes(c_ref_e, -1, -2) @ c_imu_e @ d


def mount_axis_labels(mount: F64) -> tuple[str, str, str]:
    """Labels of the IMU's FLU axes from a fixed mount (3, 3): ``x (aft)`` for an axis within
    :data:`ALIGNED_RAD` of a vehicle direction, else its direction cosines in vehicle FLU."""
    labels = []
    for j, name in enumerate("xyz"):
        col = mount[:, j]
        k = int(np.argmax(np.abs(col)))
        if np.arccos(min(1.0, abs(float(col[k])))) <= ALIGNED_RAD:
            labels.append(f"{name} ({VEHICLE_DIRECTIONS[k][0 if col[k] > 0 else 1]})")
        else:
            labels.append(f"{name} (vehicle FLU {col[0]:+.2f}, {col[1]:+.2f}, {col[2]:+.2f})")
    return (labels[0], labels[1], labels[2])


def _label_axes(data: BagData) -> None:
    """Name each IMU's axes by the vehicle direction they point to, from its truth attitude
    and the reference's (``P/odom`` and ``/reference/odom`` on common stamps)."""
    ref = data.streams.get("/reference")
    ref_odom = data.contents.topics.get("/reference/odom")
    for prefix, imu in data.imus.items():
        labels = imu.axis_labels
        own = data.streams.get(prefix)
        odom_t = f"{prefix}/odom"
        if prefix == "/reference" or is_regenerated(prefix):
            labels = ("x (forward)", "y (left)", "z (up)")
        elif ref is not None and own is not None and own.r_e is not None and ref_odom:
            c_ref = odometry_state(data.contents[ref_odom.topic]).c_b_e
            c_imu = odometry_state(data.contents[odom_t]).c_b_e
            _, i, j = np.intersect1d(ref.stamps_ns, own.stamps_ns, return_indices=True)
            if i.size:
                m = mount_flu(c_ref[i], c_imu[j])
                turn = float(np.max(rotation_angle(np.swapaxes(m[:1], -1, -2) @ m)))
                if turn <= FIXED_MOUNT_RAD:
                    labels = mount_axis_labels(m[0])
                else:  # a scanning platform: the axes point differently over time
                    labels = ("x (scanning mount)", "y (scanning mount)", "z (scanning mount)")
        imu.axis_labels = labels
        if prefix in data.measured:
            data.measured[prefix].measured.axis_labels = labels


# ------------------------------------------------------------------------------------------
# Comparison of variation streams (Method 1 vs Method 2)
# ------------------------------------------------------------------------------------------


@dataclass
class Comparison:
    """Two variation streams on their common stamps (e.g. Method 1 and Method 2).

    ``a`` is the first (the bag being reported), ``b`` the second. Velocities are NED of the
    respective stream (m/s), positions ECEF (m).
    """

    label_a: str
    label_b: str
    t: F64  #: (K,) common times, s since the start of bag a
    dv: F64  #: (K,) |V_a - V_b|, m/s
    dr: F64  #: (K,) |R_a - R_b|, m
    odd: NDArray[np.bool_]  #: (K,) odd cycle (counted from the first stamp of a)
    t_alt: F64  #: (K-4,) times of the alternation values (cycles 2..K-3)
    alt_a: F64  #: (K-4, 3) signed alternating part of V_a (:func:`alternation`), NED, m/s
    alt_b: F64

    @property
    def even_cycles_dr(self) -> float:
        """max |R_a - R_b| over even cycles (both methods meet constraint (6) there)."""
        return float(self.dr[~self.odd].max(initial=0.0))

    @property
    def odd_cycles_dr(self) -> float:
        return float(self.dr[self.odd].max(initial=0.0))


def alternation(v: F64) -> F64:
    """Signed cycle-to-cycle alternating part of ``v`` (N, 3): ``Δ⁴v_m / 16``, m = 2..N-3.

    The fourth difference ``v_{m-2} - 4 v_{m-1} + 6 v_m - 4 v_{m+1} + v_{m+2}`` gains 16 at the
    Nyquist frequency, so a sign flip ``(-1)^m e`` (Method 1's velocity error) gives
    ``(-1)^m e``; smooth motion of angular frequency ω gives only ``(ωT)^4 / 16`` of its
    amplitude (2e-6 of a 3 Hz bending mode at 200 Hz).
    """
    if v.shape[0] < 5:
        return np.zeros((0,) + v.shape[1:])
    return (v[:-4] - 4 * v[1:-3] + 6 * v[2:-2] - 4 * v[3:-1] + v[4:]) / 16


def compare_streams(a: StreamData, label_a: str, b: StreamData, label_b: str) -> Comparison | str:
    """Compare two variation streams on their common stamps; a string says why not."""
    if a.r_e is None or b.r_e is None or a.v_ned is None or b.v_ned is None:
        return "both streams need Odometry"
    common, i, j = np.intersect1d(a.stamps_ns, b.stamps_ns, return_indices=True)
    if common.size < 5:
        return (
            f"{label_a} and {label_b} share {common.size} time stamps; they are not two runs of "
            "the same reference"
        )
    va, vb = a.v_ned[i], b.v_ned[j]
    period = float(np.median(np.diff(a.stamps_ns)))
    cycle = np.rint((common - a.stamps_ns[0]) / period).astype(np.int64)
    return Comparison(
        label_a=label_a,
        label_b=label_b,
        t=a.t[i],
        dv=np.linalg.norm(va - vb, axis=1),
        dr=np.linalg.norm(a.r_e[i] - b.r_e[j], axis=1),
        odd=cycle % 2 == 1,
        t_alt=a.t[i][2:-2],
        alt_a=alternation(va),
        alt_b=alternation(vb),
    )
