"""A user's estimate read from a bag into ECEF rows, and the frames it needs (static TF).

Accepted message types (their ROS conventions, REP-103 / REP-105 / REP-145):

* ``nav_msgs/Odometry``: ``pose`` (position, orientation of ``child_frame_id`` relative to
  ``header.frame_id``) with its 6×6 covariance in the ``header.frame_id`` axes (x, y, z, then
  rotations about those axes); ``twist`` in the ``child_frame_id`` axes (FLU body), its
  covariance in the same axes;
* ``geometry_msgs/PoseWithCovarianceStamped``: a pose and its covariance as above, no velocity;
* ``sensor_msgs/NavSatFix``: geodetic WGS-84 latitude/longitude (deg), ellipsoidal altitude (m),
  ``position_covariance`` in ENU (m², row-major), used unless its type is ``UNKNOWN`` (0).

``header.frame_id`` may be the Earth frame (ECEF) or any frame with a static transform to it on
``/tf_static`` (e.g. ``map``, ENU at the datum). Covariance rows that are all zeros ("unknown")
or have element 0 = -1 ("not provided") are not used. Everything comes out in ECEF, body FRD.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag.reader import BagContents, TopicData
from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.earth import _geodetic_to_ecef, dcm_ned_to_ecef
from strapdown_ros.core.rotations import C_FRD_TO_FLU, C_NED_TO_ENU
from strapdown_ros.messages import EARTH_FRAME, TFMessageFields, dcm_from_quat_ros
from strapdown_ros.score.estimate_types import ESTIMATE_TYPES

__all__ = [
    "ESTIMATE_TYPES",
    "EstimateRows",
    "ScoreError",
    "StaticFrames",
    "read_estimate",
]


ODOMETRY, POSE_COV, NAVSATFIX = ESTIMATE_TYPES

#: ``D = diag(1, -1, -1)``: FRD ↔ FLU (its own inverse).
D = C_FRD_TO_FLU


class ScoreError(ValueError):
    """Bad input to the scorer (missing topic, unknown frame, unusable estimate)."""


@dataclass(frozen=True)
class EstimateRows:
    """An estimate in ECEF.

    ``r_e`` (K, 3) m; ``v_e`` (K, 3) m/s relative to the Earth, ECEF axes, or None;
    ``c_b_e`` (K, 3, 3) the estimate's frame (FRD) to ECEF, or None; ``pose_cov_e`` (K, 6, 6)
    position and rotation covariance in ECEF axes (NaN rows: none); ``vel_cov_e`` (K, 3, 3)
    (NaN rows: none); ``frame_id``/``child_frame_id`` as in the messages.
    """

    stamps_ns: I64
    r_e: F64
    v_e: F64 | None
    c_b_e: F64 | None
    pose_cov_e: F64 | None
    vel_cov_e: F64 | None
    msgtype: str
    frame_id: str
    child_frame_id: str | None

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    def select(self, keep: NDArray[np.bool_]) -> EstimateRows:
        def cut(a: F64 | None) -> F64 | None:
            return None if a is None else a[keep]

        return EstimateRows(self.stamps_ns[keep], self.r_e[keep], cut(self.v_e), cut(self.c_b_e),
                            cut(self.pose_cov_e), cut(self.vel_cov_e), self.msgtype,
                            self.frame_id, self.child_frame_id)  # fmt: skip

    def shifted(self, shift_ns: int) -> EstimateRows:
        """The same rows with stamps ``+ shift_ns`` (tests, time-offset studies)."""
        return EstimateRows(self.stamps_ns + int(shift_ns), self.r_e, self.v_e, self.c_b_e,
                            self.pose_cov_e, self.vel_cov_e, self.msgtype, self.frame_id,
                            self.child_frame_id)  # fmt: skip


class StaticFrames:
    """The static transforms of a bag's ``/tf_static``: ``parent → child`` translations (m,
    parent axes) and rotations ``C_child^parent``."""

    def __init__(self, tf: TFMessageFields | None, earth_frame: str = EARTH_FRAME) -> None:
        self.earth = earth_frame
        self.edges: dict[str, tuple[str, F64, F64]] = {}
        if tf is not None:
            self.add(tf)

    def add(self, tf: TFMessageFields) -> None:
        """Add the transforms of a ``/tf_static`` topic (a later one for a child replaces)."""
        pairs = list(enumerate(zip(tf.frame_ids, tf.child_frame_ids, strict=True)))
        for i in range(len(tf)):
            for j, (parent, child) in pairs:
                c = dcm_from_quat_ros(np.asarray(tf.rotation[i, j]))
                self.edges[child] = (parent, np.asarray(tf.translation[i, j], float), c)

    def transform(self, frame: str, to: str) -> tuple[F64, F64]:
        """``(p, C)`` of ``frame`` in ``to``: origin ``p`` (m, ``to`` axes), ``C_frame^to``.

        Raises ScoreError if ``frame`` does not hang below ``to`` on ``/tf_static``.
        """
        p, c = np.zeros(3), np.eye(3)
        node = frame
        seen = []
        while node != to:
            seen.append(node)
            if node not in self.edges:
                known = sorted({*self.edges, *(e[0] for e in self.edges.values())})
                raise ScoreError(
                    f"frame {frame!r} has no static transform to {to!r} on /tf_static "
                    f"(chain {' <- '.join(seen)}; frames: {', '.join(known) or 'none'})"
                )
            parent, t, c_cp = self.edges[node]
            p, c = t + c_cp @ p, c_cp @ c
            node = parent
        return p, c

    def root(self, frame: str) -> tuple[str, F64, F64]:
        """``(root, p, C_frame^root)``: the top of ``frame``'s chain on ``/tf_static``."""
        node = frame
        while node in self.edges:
            node = self.edges[node][0]
        p, c = self.transform(frame, node)
        return node, p, c

    def relative(self, frame: str, to: str) -> tuple[F64, F64]:
        """``(p, C)`` of ``frame`` in ``to`` through their common root (e.g. ``variation_imu``
        in ``reference_imu``, both below ``base_link``)."""
        root_f, p_f, c_f = self.root(frame)
        root_t, p_t, c_t = self.root(to)
        if root_f != root_t:
            raise ScoreError(f"frames {frame!r} and {to!r} are not connected on /tf_static "
                             f"(roots {root_f!r}, {root_t!r})")  # fmt: skip
        return c_t.T @ (p_f - p_t), c_t.T @ c_f

    def to_earth(self, frame: str) -> tuple[F64, F64]:
        """``(origin in ECEF, C_frame^E)`` of ``frame`` (identity for the Earth frame)."""
        if frame == self.earth:
            return np.zeros(3), np.eye(3)
        return self.transform(frame, self.earth)


def _cov_rows(cov: F64, n: int) -> F64:
    """Covariances (K, n*n) → (K, n, n) with NaN for rows unknown (zeros) or not provided
    (element 0 = -1) or not finite."""
    c = np.asarray(cov, dtype=np.float64).reshape(-1, n, n).copy()
    bad = (~np.isfinite(c).all(axis=(1, 2))) | (c[:, 0, 0] < 0) | ~np.any(c != 0, axis=(1, 2))
    c[bad] = np.nan
    return c


def _rotate_cov(c_ab: F64, cov: F64) -> F64:
    """``C P Cᵀ`` row by row (C (K, 3, 3) or (3, 3))."""
    return c_ab @ cov @ np.swapaxes(c_ab, -1, -2)


def _pose_in_earth(frames: StaticFrames, frame_id: str, position: F64, orientation: F64,
                   cov36: F64) -> tuple[F64, F64, F64]:  # fmt: skip
    """ECEF position, ``C_child(FRD)^E`` and the pose covariance in ECEF axes."""
    origin, c_f_e = frames.to_earth(frame_id)
    r_e = origin + position @ c_f_e.T
    c_flu_e = c_f_e @ dcm_from_quat_ros(orientation)
    cov = _cov_rows(cov36, 6)
    big = np.zeros((6, 6))
    big[:3, :3] = big[3:, 3:] = c_f_e
    return r_e, c_flu_e @ D, big @ cov @ big.T


def _pose_messages(data: TopicData) -> tuple[I64, str, F64, F64, F64]:
    """Stamps, frame id, positions, orientations, covariances of PoseWithCovarianceStamped."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    assert data.payloads is not None
    stamps, pos, quat, cov, frames = [], [], [], [], set()
    for raw in data.payloads:
        msg = store.deserialize_cdr(bytes(raw), data.msgtype)
        h, p = msg.header, msg.pose.pose
        stamps.append(int(h.stamp.sec) * 1_000_000_000 + int(h.stamp.nanosec))
        frames.add(h.frame_id)
        pos.append([p.position.x, p.position.y, p.position.z])
        quat.append([p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w])
        cov.append(np.asarray(msg.pose.covariance, dtype=np.float64))
    if len(frames) > 1:
        raise ScoreError(f"{data.topic}: several header.frame_id values {sorted(frames)}")
    return (np.asarray(stamps, dtype=np.int64), frames.pop(), np.asarray(pos, float),
            np.asarray(quat, float), np.asarray(cov, float))  # fmt: skip


def ecef_from_degrees(lat_deg: F64, lon_deg: F64, alt: F64) -> F64:
    """ECEF position of NavSatFix degrees, the degree → radian step in ``np.longdouble`` (a
    float64 ``radians`` adds up to 1 ulp of latitude, 7e-10 m, to the 0.5 ulp the degrees
    carry; measured on the navigator's fix: 1.3e-9 m → 1.0e-9 m worst norm)."""
    ld = np.longdouble
    to_rad = np.arctan2(ld(1), ld(0)) / ld(90)
    lat = np.asarray(lat_deg, dtype=np.float64).astype(ld) * to_rad
    lon = np.asarray(lon_deg, dtype=np.float64).astype(ld) * to_rad
    # the longdouble evaluation of geodetic_to_ecef, fed longdouble angles (not cast to float64)
    return _geodetic_to_ecef(lat, lon, np.asarray(alt, dtype=np.float64).astype(ld))


def read_estimate(bag: BagContents, topic: str, frames: StaticFrames) -> EstimateRows:
    """The estimate on ``topic`` of ``bag``, in ECEF (see the module docstring)."""
    if topic not in bag.topics:
        raise ScoreError(f"estimate topic {topic!r} not in bag {bag.path} (topics: "
                         f"{', '.join(sorted(bag.topics))})")  # fmt: skip
    data = bag.topics[topic]
    if data.msgtype not in ESTIMATE_TYPES:
        raise ScoreError(f"{topic}: type {data.msgtype} is not an estimate type (one of "
                         f"{', '.join(ESTIMATE_TYPES)})")  # fmt: skip
    if not len(data):
        raise ScoreError(f"{topic}: no messages")
    if data.msgtype == ODOMETRY:
        f = data.fields
        r_e, c_b_e, pose_cov = _pose_in_earth(frames, f.frame_id, np.asarray(f.position),
                                              np.asarray(f.orientation), f.pose_covariance)
        v_e = np.einsum("nij,nj->ni", c_b_e @ D, np.asarray(f.twist_linear, float))
        tw = _cov_rows(f.twist_covariance, 6)[:, :3, :3]
        vel_cov = _rotate_cov(c_b_e @ D, tw)
        return EstimateRows(np.asarray(f.stamps_ns, np.int64), r_e, v_e, c_b_e, pose_cov,
                            vel_cov, data.msgtype, f.frame_id, f.child_frame_id)  # fmt: skip
    if data.msgtype == POSE_COV:
        stamps, frame_id, pos, quat, cov = _pose_messages(data)
        r_e, c_b_e, pose_cov = _pose_in_earth(frames, frame_id, pos, quat, cov)
        return EstimateRows(stamps, r_e, None, c_b_e, pose_cov, None, data.msgtype, frame_id,
                            None)  # fmt: skip
    f = data.fields
    r_e = ecef_from_degrees(f.latitude, f.longitude, f.altitude)
    lat = np.radians(np.asarray(f.latitude, dtype=np.float64))
    lon = np.radians(np.asarray(f.longitude, dtype=np.float64))
    enu = _cov_rows(f.position_covariance, 3)
    enu[np.asarray(f.position_covariance_type) == 0] = np.nan
    c_enu_e = dcm_ned_to_ecef(lat, lon) @ C_NED_TO_ENU.T  # C_ENU^E = C_N^E C_ENU^N
    pose_cov = np.full((len(r_e), 6, 6), np.nan)
    pose_cov[:, :3, :3] = _rotate_cov(c_enu_e, enu)
    return EstimateRows(np.asarray(f.stamps_ns, np.int64), r_e, None, None, pose_cov, None,
                        data.msgtype, f.frame_id, None)  # fmt: skip
