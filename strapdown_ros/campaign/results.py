"""A campaign's results on disk: one directory per run, then ensemble tables in Parquet.

Layout under ``--out DIR``::

    campaign.json              how the campaign was made (scenario, overrides, varied keys,
                               campaign seed, versions)
    runs/NNNN/errors.parquet   navigator errors of run NNNN at the navigation rate
    runs/NNNN/summary.json     its summary figures, seeds and overrides (written last: the run
                               is complete when this file exists)
    runs/NNNN/bag/             with --bags: the run's full rosbag2 dataset
    runs.parquet               one row per run (summary figures, seeds, overrides)
    errors.parquet             every run's error time series (long format, column ``run``)
    report/                    campaign.md and the ensemble plots

Parquet (Apache Arrow's columnar format, through pyarrow) is read by pandas, polars, DuckDB,
Spark and MATLAB alike, keeps float64 bits exactly and compresses the time series well.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "ERROR_COLUMNS",
    "RunResult",
    "collect",
    "finished_runs",
    "read_run_errors",
    "run_dir",
    "write_run",
]

#: Error time-series columns: NED position (m), NED velocity (m/s), Young angles (rad).
ERROR_COLUMNS = (
    "pos_n_m", "pos_e_m", "pos_d_m",
    "vel_n_mps", "vel_e_mps", "vel_d_mps",
    "att_1_rad", "att_2_rad", "att_3_rad",
)  # fmt: skip


@dataclass
class RunResult:
    """What one run computed: error samples at the output stamps, and its specification."""

    index: int
    stamps_ns: np.ndarray  # (K,)
    errors: np.ndarray  # (K, 9): ERROR_COLUMNS
    seeds: dict[str, int]
    draws: dict[str, Any]
    overrides: tuple[str, ...]
    elapsed_s: float
    bag: str | None = None

    def summary(self) -> dict[str, Any]:
        """Summary figures: final and maximum horizontal, vertical, velocity, attitude errors."""
        e = self.errors
        horizontal = np.hypot(e[:, 0], e[:, 1])
        vertical = np.abs(e[:, 2])
        velocity = np.linalg.norm(e[:, 3:6], axis=1)
        attitude = np.linalg.norm(e[:, 6:9], axis=1)
        return {
            "run": self.index,
            "final_horizontal_m": float(horizontal[-1]),
            "max_horizontal_m": float(horizontal.max()),
            "final_vertical_m": float(vertical[-1]),
            "max_vertical_m": float(vertical.max()),
            "final_velocity_mps": float(velocity[-1]),
            "max_velocity_mps": float(velocity.max()),
            "final_attitude_rad": float(attitude[-1]),
            "max_attitude_rad": float(attitude.max()),
            "samples": int(len(e)),
            "elapsed_s": self.elapsed_s,
            "seeds": self.seeds,
            "draws": self.draws,
            "overrides": list(self.overrides),
            "bag": self.bag,
        }


def run_dir(out: Path, index: int) -> Path:
    """``out/runs/NNNN``."""
    return Path(out) / "runs" / f"{index:04d}"


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def write_run(out: Path, result: RunResult) -> Path:
    """Write a run's errors, then its summary (the completion marker). Returns the directory."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    d = run_dir(out, result.index)
    d.mkdir(parents=True, exist_ok=True)
    table = pa.table(
        {"stamp_ns": pa.array(result.stamps_ns, pa.int64())}
        | {c: pa.array(result.errors[:, i], pa.float64()) for i, c in enumerate(ERROR_COLUMNS)}
    )
    tmp = d / "errors.parquet.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, d / "errors.parquet")
    _atomic_write(d / "summary.json", json.dumps(result.summary(), indent=1).encode())
    return d


def finished_runs(out: Path) -> set[int]:
    """Indices of the runs whose summary exists (complete runs)."""
    runs = Path(out) / "runs"
    if not runs.is_dir():
        return set()
    done = set()
    for d in runs.iterdir():
        if d.name.isdigit() and (d / "summary.json").is_file() and (d / "errors.parquet").is_file():
            done.add(int(d.name))
    return done


def read_run_errors(out: Path, index: int) -> tuple[np.ndarray, np.ndarray]:
    """``(stamps_ns (K,), errors (K, 9))`` of a finished run."""
    import pyarrow.parquet as pq

    table = pq.read_table(run_dir(out, index) / "errors.parquet")
    stamps = table.column("stamp_ns").to_numpy()
    errors = np.column_stack([table.column(c).to_numpy() for c in ERROR_COLUMNS])
    return stamps, errors


def collect(out: Path, runs: int) -> tuple[list[dict[str, Any]], Path, Path]:
    """Write ``runs.parquet`` and ``errors.parquet`` from the finished runs 0..runs-1.

    Returns the summaries (by run index) and the two paths.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = Path(out)
    summaries = []
    columns: dict[str, list[Any]] = {"run": [], "stamp_ns": [], **{c: [] for c in ERROR_COLUMNS}}
    for k in sorted(i for i in finished_runs(out) if i < runs):
        summaries.append(json.loads((run_dir(out, k) / "summary.json").read_text()))
        stamps, errors = read_run_errors(out, k)
        columns["run"].append(np.full(len(stamps), k, dtype=np.int64))
        columns["stamp_ns"].append(stamps)
        for i, c in enumerate(ERROR_COLUMNS):
            columns[c].append(errors[:, i])
    flat = {}
    for s in summaries:
        for key, value in s.items():
            if isinstance(value, dict | list):
                value = json.dumps(value)
            flat.setdefault(key, []).append(value)
    runs_path, errors_path = out / "runs.parquet", out / "errors.parquet"
    pq.write_table(pa.table(flat) if flat else pa.table({"run": pa.array([], pa.int64())}),
                   runs_path)  # fmt: skip
    if columns["run"]:
        pq.write_table(pa.table({k: np.concatenate(v) for k, v in columns.items()}), errors_path)
    else:
        pq.write_table(pa.table({k: pa.array([], pa.float64()) for k in columns}), errors_path)
    return summaries, runs_path, errors_path
