"""The navigator's output fields: the solution as ``/navigator/odom`` and ``/navigator/fix``
and, with truth, its errors (position and velocity NED, attitude Young's ``young_uen``).
Definitions: docs/navigator.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.config.navigator import OUTPUT_TOPICS
from strapdown_ros.core.array_types import F64, I64
from strapdown_ros.core.earth import (
    dcm_ned_to_ecef,
    geodetic_to_ecef,
)
from strapdown_ros.core.navigation import NavSolution
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.messages import (
    SERVICE_UNKNOWN,
    STATUS_NO_FIX,
    NavSatFixFields,
    OdometryFields,
    Vector3StampedFields,
    navsatfix_fields_from_geodetic,
    odometry_fields_from_ecef,
    vector3_stamped_fields,
)
from strapdown_ros.stages.navigator_truth import TruthRows


@dataclass
class NavigatorOutputs:
    """Fields of the navigator topics for consecutive output stamps (errors: None without
    truth)."""

    odom: OdometryFields
    fix: NavSatFixFields
    error_position: Vector3StampedFields | None = None
    error_velocity: Vector3StampedFields | None = None
    error_attitude: Vector3StampedFields | None = None

    def __len__(self) -> int:
        return len(self.odom)

    def items(self) -> list[tuple[str, object]]:
        """``(output key, fields)`` of the topics present (keys of :data:`OUTPUT_TOPICS`)."""
        return [(k, getattr(self, k)) for k in OUTPUT_TOPICS if getattr(self, k) is not None]


def output_fields(
    stamps: I64,
    sol: NavSolution,
    omega_eb_b: F64,
    truth: TruthRows | None,
    frame_id: str,
    earth_frame: str,
) -> NavigatorOutputs:
    r_e = geodetic_to_ecef(sol.lat, sol.lon, sol.alt)
    c_n_e = dcm_ned_to_ecef(sol.lat, sol.lon)
    v_e = np.einsum("nij,nj->ni", c_n_e, sol.v_ned)
    c_b_n = dcm_from_quat(sol.q_b_n)
    out = NavigatorOutputs(
        odometry_fields_from_ecef(
            stamps, r_e, v_e, c_n_e @ c_b_n, omega_eb_b, frame_id, earth_frame
        ),  # fmt: skip
        # an inertial-only position: no GNSS fix claimed (docs/interface.md §4)
        navsatfix_fields_from_geodetic(
            stamps,
            sol.lat,
            sol.lon,
            sol.alt,
            frame_id,
            status=STATUS_NO_FIX,
            service=SERVICE_UNKNOWN,
        ),  # fmt: skip
    )
    if truth is not None:
        dr = position_error_ned(r_e, truth.r_e, truth.lat, truth.lon)
        out.error_position = vector3_stamped_fields(stamps, dr, "ned")
        out.error_velocity = vector3_stamped_fields(
            stamps, velocity_error_ned(sol.v_ned, truth.v_ned), "ned"
        )
        out.error_attitude = vector3_stamped_fields(
            stamps, attitude_error_young(c_b_n, truth.c_b_n), "young_uen"
        )
    return out
