"""The aided filter's σ against an ensemble of its errors (strapdown_ros.analysis.aided_check).

* (fast) :func:`aided_prediction` is the RMS over the runs of their σ with zero mean and the
  runs' spread about it; runs on other epochs are refused; :func:`plot_checks` draws a PNG of
  :func:`compare_ensemble`'s series (synthetic runs, their errors drawn with the σ they carry).
* (slow) The command line end to end on 2 short runs of the flight (bags written, read back):
  every σ finite and positive, the attitude σ about down (θ1, a variance: no sign flip) the one
  :func:`bag_result` gives, the horizontal σ its ``sigma_h``; ``--plot`` writes the figure;
  ``--also`` pools the runs of more directories.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.analysis import covariance_check as cc
from strapdown_ros.analysis.aided_check import (
    AidedRun,
    aided_prediction,
    main,
    plot_checks,
    read_aided_run,
)

DATA = Path(__file__).resolve().parent / "data"


def _runs(n: int, k: int = 200) -> list[AidedRun]:
    rng = np.random.default_rng(1)
    stamps = np.arange(k, dtype=np.int64) * 100_000_000
    base = np.geomspace(1.0, 0.1, k)[:, None] * np.array([1, 1, 2, 0.1, 0.1, 0.1, 1e-3, 1e-4,
                                                            1e-4])  # fmt: skip
    runs = []
    for _ in range(n):
        sigma = base * (1.0 + 0.01 * rng.standard_normal())
        runs.append(AidedRun(stamps, sigma * rng.standard_normal(sigma.shape), sigma))
    return runs


def test_prediction_is_the_rms_of_the_runs_sigma():
    runs = _runs(4)
    prediction, spread = aided_prediction(runs, None)
    sig = np.stack([r.sigma for r in runs])
    np.testing.assert_allclose(prediction.sigma, np.sqrt(np.mean(sig**2, axis=0)), rtol=1e-15)
    assert np.all(prediction.mean == 0.0)
    np.testing.assert_allclose(spread, sig.max(axis=0) / sig.min(axis=0) - 1.0)
    shifted = AidedRun(runs[0].stamps + 1, runs[0].errors, runs[0].sigma)
    with pytest.raises(ValueError, match="different output epochs"):
        aided_prediction([runs[1], shifted], None)


def test_plot_draws_a_png(tmp_path):
    runs = _runs(30)
    prediction, _ = aided_prediction(runs, None)
    ensemble = cc.Ensemble(prediction.stamps_ns, np.stack([r.errors for r in runs]))
    checks, series = cc.compare_ensemble(prediction, ensemble, skip_s=5.0)
    assert all(c.ratio_min > 0.3 and c.ratio_max < 2.0 for c in checks)
    path = plot_checks(series, 30, tmp_path / "check.png", 5.0, "synthetic")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


@pytest.mark.slow
def test_command_line_on_two_short_runs(tmp_path, capsys):
    from strapdown_ros.config.scenario import apply_overrides, parse_scenario
    from strapdown_ros.stages.aided_montecarlo import bag_result, campaign_document

    scenario_path = DATA / "aided_default_noisy.yaml"
    png = tmp_path / "check.png"
    assert main([str(scenario_path), "--runs", "2", "--duration", "20", "--modelled-only",
                 "--skip", "5", "--dir", str(tmp_path / "runs"), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "| att_1_rad |" in out and "nan" not in out, out
    assert png.read_bytes()[:4] == b"\x89PNG"
    doc, overrides = campaign_document(scenario_path, True, [], 20.0)
    scenario = parse_scenario(apply_overrides(doc, overrides))
    run = read_aided_run(tmp_path / "runs" / "run_001", scenario)
    assert np.all(np.isfinite(run.sigma)) and np.all(run.sigma > 0)
    ref = bag_result(tmp_path / "runs" / "run_001", scenario)
    np.testing.assert_allclose(run.sigma[:, 6], ref.sigma_heading, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(run.sigma[:, 0], run.sigma[:, 1]), ref.sigma_h,
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(run.errors[:, 6], -ref.error_attitude[:, 2], rtol=0, atol=0)
    assert main([str(scenario_path), "--runs", "2", "--duration", "20", "--modelled-only",
                 "--skip", "5", "--dir", str(tmp_path / "runs"), "--also",
                 str(tmp_path / "runs")]) == 0  # read only, pooled: 4 runs
    assert "N = 4 runs" in capsys.readouterr().out
