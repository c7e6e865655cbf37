"""The ROS/message boundary: streams (FRD, NED, E0) to message fields (FLU, ENU, ECEF) and back.

Everything here is pure numpy (no rclpy, no rosbags). A message *type* is represented by a field
container holding one array per field for N messages (a struct of arrays); the bulk CDR codec in
:mod:`strapdown_ros.bag.cdr` turns those into payloads and back. The frame conversions of
docs/interface.md §1 happen here and only here, exactly (sign flips and 90° rotations):

* body: ``v^FLU = diag(1, -1, -1) v^FRD`` (:func:`~strapdown_ros.core.rotations.frd_to_flu`);
* local level: ``C_FLU^ENU = C_NED_TO_ENU C_FRD^NED C_FRD_TO_FLU``;
* inertial E0 to ECEF at ``t = t_m - t0`` (:func:`~strapdown_ros.core.earth.e0_state_to_ecef`).

One module per job (message semantics in each; see also ``docs/messages.md``):

* :mod:`~strapdown_ros.messages.fields`: the field containers, their validation, Clock and
  Vector3Stamped;
* :mod:`~strapdown_ros.messages.frames`: frame ids, ROS quaternion order ``(x, y, z, w)``
  (the core uses ``[w, x, y, z]``);
* :mod:`~strapdown_ros.messages.imu`, :mod:`~strapdown_ros.messages.odometry`,
  :mod:`~strapdown_ros.messages.navsatfix`: a stream (or its arrays) to each message type;
  :mod:`~strapdown_ros.messages.truth` the Earth-referenced truth they share and
  :mod:`~strapdown_ros.messages.stream` all three at once;
* :mod:`~strapdown_ros.messages.tf`: TFMessage, map-frame Odometry, Δv / Δq increments;
* :mod:`~strapdown_ros.messages.decode`: messages back to core arrays and streams.

Covariances follow REP-145: zeros mean "unknown" (ideal streams), element 0 = -1 means "not
provided" (:data:`COVARIANCE_NOT_PROVIDED`). Every public name is importable from this package.
"""

from __future__ import annotations

from strapdown_ros.messages.decode import (
    EarthState,
    ImuIncrements,
    imu_increments,
    navsatfix_geodetic,
    odometry_state,
    stream_from_messages,
)
from strapdown_ros.messages.fields import (
    COVARIANCE_NOT_PROVIDED,
    ClockFields,
    FluidPressureFields,
    ImuFields,
    MagneticFieldFields,
    NavSatFixFields,
    OdometryFields,
    QuaternionStampedFields,
    TFMessageFields,
    TwistWithCovarianceStampedFields,
    Vector3StampedFields,
    clock_fields,
    stamps_to_sec_nanosec,
    vector3_stamped_fields,
)
from strapdown_ros.messages.frames import (
    BASE_LINK_FRAME,
    DEFAULT_BODY_FRAME,
    EARTH_FRAME,
    MAP_FRAME,
    dcm_from_quat_ros,
    quat_ros_from_dcm,
)
from strapdown_ros.messages.imu import imu_fields, imu_fields_from_increments
from strapdown_ros.messages.navsatfix import (
    COVARIANCE_TYPE_APPROXIMATED,
    COVARIANCE_TYPE_DIAGONAL_KNOWN,
    COVARIANCE_TYPE_KNOWN,
    COVARIANCE_TYPE_UNKNOWN,
    SERVICE_GPS,
    SERVICE_UNKNOWN,
    STATUS_FIX,
    STATUS_NO_FIX,
    navsatfix_fields,
    navsatfix_fields_from_geodetic,
)
from strapdown_ros.messages.odometry import (
    odometry_fields,
    odometry_fields_from_ecef,
    twist_covariance_flu,
)
from strapdown_ros.messages.stream import StreamFields, stream_fields
from strapdown_ros.messages.tf import (
    increment_fields,
    map_odometry_fields,
    quaternion_stamped_fields,
    tf_message_fields,
)
from strapdown_ros.messages.truth import StreamTruth

__all__ = [
    "BASE_LINK_FRAME",
    "COVARIANCE_NOT_PROVIDED",
    "COVARIANCE_TYPE_APPROXIMATED",
    "COVARIANCE_TYPE_DIAGONAL_KNOWN",
    "COVARIANCE_TYPE_KNOWN",
    "COVARIANCE_TYPE_UNKNOWN",
    "DEFAULT_BODY_FRAME",
    "EARTH_FRAME",
    "MAP_FRAME",
    "SERVICE_GPS",
    "SERVICE_UNKNOWN",
    "STATUS_FIX",
    "STATUS_NO_FIX",
    "ClockFields",
    "EarthState",
    "FluidPressureFields",
    "ImuFields",
    "ImuIncrements",
    "MagneticFieldFields",
    "NavSatFixFields",
    "OdometryFields",
    "QuaternionStampedFields",
    "StreamFields",
    "StreamTruth",
    "TFMessageFields",
    "TwistWithCovarianceStampedFields",
    "Vector3StampedFields",
    "clock_fields",
    "dcm_from_quat_ros",
    "imu_fields",
    "imu_fields_from_increments",
    "imu_increments",
    "increment_fields",
    "map_odometry_fields",
    "navsatfix_fields",
    "navsatfix_fields_from_geodetic",
    "navsatfix_geodetic",
    "odometry_fields",
    "odometry_fields_from_ecef",
    "odometry_state",
    "quat_ros_from_dcm",
    "quaternion_stamped_fields",
    "stamps_to_sec_nanosec",
    "stream_fields",
    "stream_from_messages",
    "tf_message_fields",
    "twist_covariance_flu",
    "vector3_stamped_fields",
]
