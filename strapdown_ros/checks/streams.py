"""The docs/interface.md §3 verdict of the Imu/Odometry pairs of a bag read back from disk.

A pair is a prefix ``P`` with ``P/imu`` (sensor_msgs/Imu) and ``P/odom`` (nav_msgs/Odometry).
It is verifiable when it has the layout of docs/interface.md §2 and §4: Odometry in ECEF (the
``earth`` frame), Imu message m stamped like Odometry message m (m = 1..M), a uniform period.
A pair of another tool's bag (a robot's ``/imu`` at 100 Hz and ``/odom`` at 50 Hz in an
``odom`` frame) is reported with the reason it cannot be verified, never as a defect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.core.exactness import stream_residuals

__all__ = [
    "ECEF_RADIUS_RANGE_M",
    "IMU",
    "ODOMETRY",
    "PairVerdict",
    "check_pair",
    "check_streams",
    "imu_odometry_pairs",
    "is_ecef",
]

IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"

#: Distances from the Earth's centre (m) an ECEF position of a vehicle can have: 6.2e6 m
#: (150 km below the polar radius) to 7.0e6 m (about 620 km above the equator). A local frame
#: (``odom``, ``map``) has positions within metres or kilometres of its origin instead.
ECEF_RADIUS_RANGE_M = (6.2e6, 7.0e6)


@dataclass
class PairVerdict:
    """The verdict on one Imu/Odometry pair.

    ``residuals`` when the pair was verified, else ``reason`` says why it could not be.
    """

    imu_topic: str
    odom_topic: str
    cycles: int = 0
    residuals: Residuals | None = None
    reason: str | None = None

    @property
    def checked(self) -> bool:
        return self.residuals is not None

    @property
    def ok(self) -> bool:
        """Verified and within the docs/interface.md §3 tolerances."""
        return self.residuals is not None and bool(self.residuals.within_spec())

    @property
    def pair(self) -> str:
        return f"{self.imu_topic} + {self.odom_topic}"


def is_ecef(r: np.ndarray) -> bool:
    """Whether every position (N, 3), m, lies in :data:`ECEF_RADIUS_RANGE_M` of the centre."""
    r = np.asarray(r, dtype=np.float64)
    if r.ndim != 2 or r.shape[0] == 0:
        return False
    norm = np.linalg.norm(r, axis=1)
    lo, hi = ECEF_RADIUS_RANGE_M
    return bool(np.all(np.isfinite(norm)) and np.all((norm >= lo) & (norm <= hi)))


def imu_odometry_pairs(contents: BagContents) -> list[tuple[str, str]]:
    """``(P/imu, P/odom)`` topic pairs of the bag, typed Imu and Odometry, in the bag's order."""
    out = []
    for topic, data in contents.topics.items():
        if not topic.endswith("/imu") or data.msgtype != IMU:
            continue
        odom = topic[: -len("imu")] + "odom"
        if odom in contents.topics and contents.topics[odom].msgtype == ODOMETRY:
            out.append((topic, odom))
    return out


def _rate(stamps_ns: np.ndarray) -> str:
    d = np.diff(np.asarray(stamps_ns, dtype=np.int64))
    return f"{1e9 / float(np.median(d)):.4g} Hz" if d.size and np.median(d) > 0 else "one message"


def _layout_problem(imu: object, odom: object) -> str | None:
    """Why the pair does not have the stream layout (None: it has)."""
    from strapdown_ros.messages import odometry_state

    t_imu = np.asarray(imu.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
    t_odom = np.asarray(odom.stamps_ns, dtype=np.int64)  # type: ignore[attr-defined]
    if not t_imu.size or not t_odom.size:
        return "a topic has no messages"
    r_e = odometry_state(odom).r_e  # type: ignore[arg-type]
    if not is_ecef(r_e):
        norm = np.linalg.norm(r_e, axis=1)
        frame = getattr(odom, "frame_id", "?")
        return (
            f"the Odometry positions (frame {frame!r}, {np.nanmin(norm):.3g} to "
            f"{np.nanmax(norm):.3g} m from the origin) are not ECEF: §3 is stated for the truth "
            "of docs/interface.md §4 (frame `earth`)"
        )
    if t_odom.shape[0] != t_imu.shape[0] + 1 or not np.array_equal(t_odom[1:], t_imu):
        return (
            f"Imu at {_rate(t_imu)} ({t_imu.size} messages), Odometry at {_rate(t_odom)} "
            f"({t_odom.size}); §3 needs Imu message m stamped like Odometry message m "
            "(m = 1..M, docs/interface.md §2)"
        )
    return None


def check_pair(contents: BagContents, imu_topic: str, odom_topic: str, gravity_model: str
               ) -> PairVerdict:  # fmt: skip
    """Verify one pair with ``gravity_model``, or say why it cannot be verified."""
    from strapdown_ros.messages import stream_from_messages

    verdict = PairVerdict(imu_topic, odom_topic)
    imu, odom = contents.topics[imu_topic].fields, contents.topics[odom_topic].fields
    if imu is None or odom is None:
        verdict.reason = "a topic could not be decoded"
        return verdict
    problem = _layout_problem(imu, odom)
    if problem is not None:
        verdict.reason = problem
        return verdict
    try:
        stream = stream_from_messages(imu, odom, gravity_model)  # type: ignore[arg-type]
    except ValueError as exc:  # e.g. a non-uniform period
        verdict.reason = str(exc)
        return verdict
    verdict.cycles = stream.cycles
    verdict.residuals = stream_residuals(stream)
    return verdict


def check_streams(
    contents: BagContents, gravity_model: str, *, skip: tuple[str, ...] = ("navigator",)
) -> list[PairVerdict]:
    """Verdicts on every Imu/Odometry pair (prefixes containing a ``skip`` word excluded:
    a navigator's solution is not an exact stream)."""
    return [
        check_pair(contents, imu, odom, gravity_model)
        for imu, odom in imu_odometry_pairs(contents)
        if not any(word in imu for word in skip)
    ]
