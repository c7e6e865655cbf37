"""``--summarize`` pools the runs saved by campaigns of several seeds (the consistency of one
50-run set is nearly one sample per run: the mounting error freezes after the manoeuvres)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.stages.transfer_montecarlo import main


def _save(directory: Path, runs: int, nees: float) -> None:
    directory.mkdir()
    t = np.arange(0.0, 20.0, 0.1)
    k = len(t)
    for r in range(runs):
        np.savez(directory / f"run_{r:03d}.npz", t=t, attitude=np.zeros((k, 3)),
                 velocity=np.zeros((k, 3)), mounting=np.zeros((k, 3)),
                 mounting_sigma=np.ones((k, 3)), nees=np.full((k, 3), nees),
                 mounting_nees=np.full(k, nees), nis=np.full((k - 1, 2), 3.0))  # fmt: skip


def test_runs_of_several_directories_are_pooled(tmp_path, capsys) -> None:
    _save(tmp_path / "a", 2, 2.0)
    _save(tmp_path / "b", 3, 4.5)
    assert main(["scenario.yaml", "--summarize", str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert ": 5 runs" in out
    # the pooled run average: (2 · 2.0 + 3 · 4.5) / 5 = 3.5
    assert "| NEES mounting |" in out and "| 3.500 |" in out.split("NEES mounting")[1]


def test_a_directory_without_runs_is_a_usage_error(tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main(["scenario.yaml", "--summarize", str(tmp_path)])
    assert e.value.code == 2
    assert "no run_*.npz" in capsys.readouterr().err
