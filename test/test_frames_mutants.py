"""core/frames.py edges found by mutation testing (docs/development.md, "Mutation testing").

Expected values: a sensor pose ``p^B = l^B + C_S^B s^S`` with ``C_S^B`` from
scipy.spatial.transform, FRD -> FLU as ``D = diag(1, -1, -1)``, and the datum's stored fields.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strapdown_ros.core.frames import Datum, lever_arm_in_base_link, sensor_in_body

D = np.diag([1.0, -1.0, -1.0])


def test_sensor_pose_from_lever_arm_displacement_and_attitude():
    """Savage 2020 eqs. (6)-(7): the sensor at ``l + C s`` with attitude ``C``, in FLU axes."""
    c = Rotation.from_euler("ZYX", [[0.4, -0.3, 0.2], [-1.0, 0.5, 2.0]]).as_matrix()
    lever = np.array([[1.0, -2.0, 0.5], [0.1, 0.2, 0.3]])
    disp = np.array([[0.3, 0.7, -1.1], [-0.4, 0.9, 0.25]])
    p, rot = sensor_in_body(lever, disp, c)
    expected_p = (lever + np.einsum("nij,nj->ni", c, disp)) @ D
    np.testing.assert_allclose(p, expected_p, rtol=0, atol=1e-15)  # measured 2.2e-16
    np.testing.assert_allclose(rot, D @ c @ D, rtol=0, atol=0)  # sign flips only: exact


def test_base_link_lever_arm_is_flu():
    np.testing.assert_array_equal(lever_arm_in_base_link([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])


def test_datum_keeps_its_geodetic_position_and_is_read_only():
    lat, lon, alt = 0.7, -1.2, 350.0
    d = Datum.at(lat, lon, alt)
    assert (d.latitude_rad, d.longitude_rad, d.altitude_m) == (lat, lon, alt)
    for a in (d.r0_e, d.c_map_e):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[0] = 0.0
    # C_ENU^E: columns east, north, up (closed form on the sphere of directions)
    east = [-np.sin(lon), np.cos(lon), 0.0]
    north = [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)]
    up = [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)]
    # measured: equal to the bit; bound a few ulp
    np.testing.assert_allclose(d.c_map_e, np.column_stack([east, north, up]), rtol=0, atol=1e-15)
