"""`report` on a transfer-alignment bag: the slave against its own truth, the mounting against
the truths' relative attitude, recomputed from the bag read back from disk.

The expected values come from the scenario file, not from the code under test: the true
mounting is `variation.mounting_rph_deg`, the initial mounting error is
`transfer_alignment.mounting_error_deg` (the nominal mounting `exp([μ0×]) M`, so rotvec(M̂ Mᵀ)
= μ0 at cycle 0, reference body FRD, published FLU).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from strapdown_ros.config import load_scenario

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "transfer_alignment.yaml"
#: No model error (as test_transfer_alignment.py): no bending, the ideal variation IMU, an
#: exact master, no added measurement noise.
EXACT = ["variation.bending=null", "imu_errors=null", "transfer_alignment.imu_topic=/variation/imu",
         "transfer_alignment.master={}", "transfer_alignment.tuning={}"]  # fmt: skip
DURATION = 30.0

pytestmark = pytest.mark.slow  # generates a 30 s bag and compiles the filter's kernels


def _scenario_doc() -> dict:
    return yaml.safe_load(SCENARIO.read_text())


@pytest.fixture(scope="module")
def exact_report(tmp_path_factory):
    from strapdown_ros.generate import generate_dataset
    from strapdown_ros.report import write_report

    root = tmp_path_factory.mktemp("transfer_report")
    generate_dataset(load_scenario(SCENARIO, EXACT, duration_s=DURATION), root / "bag")
    res = write_report(root / "bag", exactness=False, free_inertial=False)
    return root, res


def test_the_true_mounting_is_the_scenarios(exact_report):
    _, res = exact_report
    r = res.transfer["/transfer"]
    from strapdown_ros.core.rotations import euler_from_dcm

    want = np.radians(_scenario_doc()["variation"]["mounting_rph_deg"])
    got = np.array([float(x) for x in euler_from_dcm(r.mounting_true)])
    # measured: 2e-16 rad; the relative attitude of two Odometry quaternions
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    assert r.mounting_spread < 1e-14  # measured 3e-16: a fixed mount


def test_the_mounting_error_starts_at_the_configured_error_and_converges(exact_report):
    _, res = exact_report
    r = res.transfer["/transfer"]
    mu0 = np.radians(_scenario_doc()["transfer_alignment"]["mounting_error_deg"])
    flu = np.array([1.0, -1.0, -1.0])
    np.testing.assert_allclose(r.error[0], mu0 * flu, rtol=0, atol=1e-12)
    late = r.t >= 20.0
    # measured after 20 s: 6.4e-12 rad (docs/transfer_alignment.md §6); the bar 1 µrad
    assert np.abs(r.error[late]).max() < 1e-10
    # the recomputed error is the filter's own, to round-off (measured 1e-16 rad)
    np.testing.assert_allclose(r.error, r.published_error, rtol=0, atol=1e-14)
    times = r.alignment_times()
    assert times["1 mrad"]["mounting yaw"] <= times["0.1 mrad"]["mounting yaw"] < 20.0


def test_the_slave_is_compared_with_its_own_truth(exact_report):
    """Against `/variation/odom` the slave's errors are round-off after convergence; against
    the reference truth they would be the lever arm (4 m) and the mounting (3 deg)."""
    _, res = exact_report
    slave = res.transfer["/transfer"].slave
    assert slave.truth_topic == "/variation/odom"
    late = slave.t >= 20.0
    assert np.linalg.norm(slave.errors["position"], axis=1).max() < 5e-5
    assert np.linalg.norm(slave.errors["velocity"][late], axis=1).max() < 2e-9
    assert np.linalg.norm(slave.errors["attitude"][late], axis=1).max() < 5e-11
    # the filter's own error topics, from its state before the Odometry conversion (measured:
    # 7e-10 m, 1.1e-13 m/s, 2e-14 rad: ulps of 6.4e6 m and 250 m/s)
    for q, atol in (("position", 5e-9), ("velocity", 1e-12), ("attitude", 2e-13)):
        diff = np.abs(slave.errors[q] - slave.published_errors[q]).max()
        assert diff < atol, (q, diff)
    assert [n.sensor for n in slave.nis] == ["velocity", "attitude"]
    assert "/transfer" not in res.aided  # not reported as an aided filter against the reference


def test_the_report_names_the_transfer_section_and_plots(exact_report):
    _, res = exact_report
    md = res.markdown.read_text()
    assert "## Transfer alignment `/transfer`" in md
    row = ("| `/transfer` | transfer alignment (slave) | `/variation/imu` | ideal "
           "| `/variation/odom`")
    assert row in md
    for name in ("transfer_errors", "transfer_consistency", "transfer_mounting"):
        assert res.plots[name].is_file()
    assert "aided_errors_transfer" not in res.plots


def test_a_bag_without_the_slave_truth_says_why(tmp_path):
    from strapdown_ros.generate import generate_dataset
    from strapdown_ros.report import write_report

    sc = load_scenario(SCENARIO, [*EXACT, "recording.exclude=[/variation/odom]"], duration_s=2.0)
    generate_dataset(sc, tmp_path / "bag")
    res = write_report(tmp_path / "bag", exactness=False, free_inertial=False)
    assert "/variation/odom" in res.omitted["transfer"]
    assert not res.transfer
