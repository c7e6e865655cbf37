"""The campaign consistency figure: run averages per epoch and the bounds drawn beside them.

The averages are checked against a hand-made pair of runs (NEES 1 and 5 at every epoch average
to 3; runs of unequal length are cut to the shorter), the bounds against scipy's χ² quantiles
(Bar-Shalom et al. 2001 eq. (5.4.2-6)), and the PNG is read back.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread
from scipy.stats import chi2

from strapdown_ros.core.aided.consistency import average_interval
from strapdown_ros.report.consistency_plot import AverageSeries, plot_consistency
from strapdown_ros.stages.aided_montecarlo import RunResult, average_series


def _run(k: int, nees: float, nis: float) -> RunResult:
    z = np.zeros((k, 3))
    stamps = 1_000_000_000 + np.arange(k, dtype=np.int64) * 100_000_000
    return RunResult(
        stamps, np.full((k, 3), nees), z, z, z, *(np.zeros(k),) * 4, z, z, z + 1, z + 1,
        nis={"wheel": (stamps[::2], np.full(len(stamps[::2]), nis), np.ones(len(stamps[::2]),
                                                                      int), np.ones(k))},
    )  # fmt: skip


def test_average_series_is_the_mean_over_runs_at_each_epoch() -> None:
    panels = average_series([_run(10, 1.0, 0.5), _run(12, 5.0, 1.5)])
    nees = panels["NEES"]
    assert list(nees) == ["position", "velocity", "attitude"]
    for s in nees.values():
        np.testing.assert_array_equal(s.mean, np.full(10, 3.0))
        np.testing.assert_allclose(s.t_s, np.arange(10) * 0.1)
        assert (s.dof, s.runs) == (3, 2)
    w = panels["NIS"]["wheel"]
    np.testing.assert_array_equal(w.mean, np.ones(5))
    np.testing.assert_allclose(w.t_s, np.arange(5) * 0.2)
    assert (w.dof, w.runs) == (1, 2)


@pytest.mark.parametrize(("dof", "runs"), [(3, 50), (1, 50), (3, 10)])
def test_bounds_are_the_chi2_quantiles_of_the_run_average(dof, runs) -> None:
    lo, hi = average_interval(dof, runs)
    assert lo == pytest.approx(chi2.ppf(0.025, dof * runs) / runs, rel=1e-12)
    assert hi == pytest.approx(chi2.ppf(0.975, dof * runs) / runs, rel=1e-12)
    if (dof, runs) == (3, 50):  # docs/aided.md's interval
        assert (round(lo, 3), round(hi, 3)) == (2.360, 3.716)


def test_plot_consistency_writes_one_panel_per_group(tmp_path) -> None:
    t = np.linspace(0.0, 100.0, 201)
    s3 = AverageSeries(t, 3.0 + 0.1 * np.sin(t), 3, 50)
    s1 = AverageSeries(t[::2], 1.0 + 0.05 * np.cos(t[::2]), 1, 50)
    one = plot_consistency({"NEES": {"position": s3}}, tmp_path / "one.png", "t", 60.0)
    two = plot_consistency({"NEES": {"position": s3}, "NIS": {"wheel": s1, "gnss": s3}},
                           tmp_path / "sub" / "two.png", "t")  # fmt: skip
    a, b = imread(one), imread(two)
    assert a.shape[1] == b.shape[1] and b.shape[0] > 1.8 * a.shape[0]  # 2.6 in per panel
    assert np.std(b[..., :3]) > 0.05  # drawn, not blank


def test_an_outage_is_not_drawn_across() -> None:
    from strapdown_ros.report.consistency_plot import _broken_at_gaps

    t = np.array([0.0, 1.0, 2.0, 10.0, 11.0])
    tt, vv = _broken_at_gaps(t, np.arange(5.0))
    np.testing.assert_array_equal(np.isnan(tt), [False, False, False, True, False, False])
    np.testing.assert_array_equal(vv[~np.isnan(vv)], np.arange(5.0))


def test_a_missing_bag_directory_is_a_usage_error(tmp_path, capsys) -> None:
    from strapdown_ros.stages.aided_montecarlo import main

    with pytest.raises(SystemExit) as e:
        main(["test/data/aided_car_noisy.yaml", "--runs", "1", "--dir", str(tmp_path / "no")])
    assert e.value.code == 2
    assert "not a directory" in capsys.readouterr().err
