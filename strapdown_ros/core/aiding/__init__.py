"""Aiding-sensor models (ROS-free, numpy/scipy only): GNSS, barometer, magnetometer, wheel odometer.

Each module has the exact truth of its sensor point (computed from a truth state) and a seeded,
chunk-invariant error model. Theory, parameters and presets: ``docs/aiding.md``.
"""

from strapdown_ros.core.aiding.baro import BaroErrorModel, BaroErrors, icao_pressure
from strapdown_ros.core.aiding.common import GaussMarkov, epoch_mask, sensor_rng
from strapdown_ros.core.aiding.gnss import (
    GnssErrorModel,
    GnssErrors,
    antenna_state,
    gnss_measurement,
)
from strapdown_ros.core.aiding.magnetometer import (
    MagnetometerErrorModel,
    MagnetometerErrors,
    field_body,
    igrf_field_ned,
)
from strapdown_ros.core.aiding.odometer import (
    OdometerErrorModel,
    OdometerErrors,
    contact_point_speed,
)

__all__ = [
    "BaroErrorModel",
    "BaroErrors",
    "GaussMarkov",
    "GnssErrorModel",
    "GnssErrors",
    "MagnetometerErrorModel",
    "MagnetometerErrors",
    "OdometerErrorModel",
    "OdometerErrors",
    "antenna_state",
    "contact_point_speed",
    "epoch_mask",
    "field_body",
    "gnss_measurement",
    "icao_pressure",
    "igrf_field_ned",
    "sensor_rng",
]
