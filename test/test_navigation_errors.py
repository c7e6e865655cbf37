"""docs/interface.md §4 navigation error definitions: independent checks on constructed errors."""

import numpy as np
import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.core.earth import dcm_ned_to_ecef, ecef_to_geodetic, geodetic_to_ecef
from strapdown_ros.core.navigation.errors import navigation_errors
from strapdown_ros.core.navigation.multirate import NavSolution, navigate_multirate
from strapdown_ros.core.navigation.state import state_from_stream, truth_navigation
from strapdown_ros.core.rotations import dcm_from_quat, dcm_from_rotvec, quat_from_dcm
from strapdown_ros.core.young import C_NED_TO_UEN, young_angles_from_dcm
from strapdown_ros.stages.trajectory import generate_reference

DEFAULT = "config/scenarios/default.yaml"
# the reference alone
NO_SECTIONS = ("variation=null", "navigator=null", "imu_errors=null", "aided=null")


@pytest.fixture(scope="module")
def truth():
    return generate_reference(
        load_scenario(DEFAULT, [*NO_SECTIONS], duration_s=20.0)
    )


def test_truth_as_solution_has_zero_error(truth):
    idx = np.arange(0, truth.cycles + 1, 10)
    t, lat, lon, alt, v, q = truth_navigation(truth, idx)
    err = navigation_errors(NavSolution(t, lat, lon, alt, v, q, 10), truth)
    assert np.max(np.abs(err.position_ned)) < 1e-8
    assert np.max(np.abs(err.velocity_ned)) < 1e-12
    assert np.max(np.abs(err.attitude_young)) < 1e-14
    np.testing.assert_array_equal(err.index, idx)


def test_constructed_errors_are_recovered(truth):
    idx = np.arange(0, truth.cycles + 1, 50)
    t, lat, lon, alt, v, q = truth_navigation(truth, idx)
    # displace the navigation position by (3, -4, 2) m NED of the true position
    d_ned = np.array([3.0, -4.0, 2.0])
    r = geodetic_to_ecef(lat, lon, alt) + np.einsum("nij,j->ni", dcm_ned_to_ecef(lat, lon), d_ned)
    lat2, lon2, alt2 = ecef_to_geodetic(r)
    # rotate the computed local level by a known rotation (UEN axes), small and large
    psi = np.array([0.3, -0.2, 0.1])
    rot_uen = dcm_from_rotvec(psi).T  # H = C_P^M for a frame rotated by psi
    c_nav = C_NED_TO_UEN.T @ rot_uen @ C_NED_TO_UEN @ dcm_from_quat(q)
    sol = NavSolution(t, lat2, lon2, alt2, v + [0.1, 0.2, -0.3], quat_from_dcm(c_nav), 50)
    err = navigation_errors(sol, truth)
    np.testing.assert_allclose(err.position_ned, np.tile(d_ned, (idx.size, 1)), atol=1e-8)
    np.testing.assert_allclose(err.velocity_ned, np.tile([0.1, 0.2, -0.3], (idx.size, 1)),
                               atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(err.horizontal, 5.0, atol=1e-8)
    # Young angles of a 0.37 rad error: first order equal to psi, exact by eq. (28)
    np.testing.assert_allclose(err.attitude_young, np.tile(young_angles_from_dcm(rot_uen),
                                                           (idx.size, 1)), atol=1e-13)  # fmt: skip
    assert np.allclose(err.attitude_young[0], psi, atol=0.1)


def test_paper_mode_errors_shrink_with_the_rate(truth):
    """End to end: the b-l split's error at T_nav halves when the IMU rate doubles (Table 1 is
    first order), measured with the docs/interface.md §4 error definitions."""
    fast = generate_reference(
        load_scenario(DEFAULT, [*NO_SECTIONS, "rate_hz=400"], 20.0)
    )
    out = []
    for stream in (truth, fast):
        sol = navigate_multirate(state_from_stream(stream), stream.dalpha, stream.dv,
                                 stream.period, n=2, p=1)  # fmt: skip
        err = navigation_errors(sol, stream)
        out.append(np.max(err.horizontal))
    assert 1.7 < out[0] / out[1] < 2.3, out


def test_output_times_must_fall_on_truth_samples(truth):
    t, lat, lon, alt, v, q = truth_navigation(truth, np.array([0, 10]))
    with pytest.raises(ValueError, match="truth samples"):
        navigation_errors(NavSolution(t + 1e-3, lat, lon, alt, v, q, 10), truth)
