"""``strapdown-sim campaign``: deterministic runs, equal to ``generate``, resumable, on Dask.

The campaign tests run real Dask clusters: an embedded ``LocalCluster`` and, for
``--scheduler``, a ``dask scheduler`` and ``dask worker`` processes started here on loopback.
A run's navigator errors are compared bit for bit with those of ``strapdown-sim generate`` with
the run's overrides, read back from the bag on disk.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.campaign import run_campaign
from strapdown_ros.campaign.results import finished_runs, read_run_errors, run_dir
from strapdown_ros.campaign.runs import Campaign
from strapdown_ros.campaign.vary import parse_vary
from strapdown_ros.config import ScenarioError
from strapdown_ros.logs import quiet

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"
BIN = Path(sys.executable).parent
ERROR_TOPICS = ("/navigator/error/position", "/navigator/error/velocity",
                "/navigator/error/attitude")  # fmt: skip


# -- the plan (no cluster) ---------------------------------------------------------------------


def test_runs_are_deterministic_and_independent_of_the_campaign_size():
    plan = Campaign(DEFAULT, duration_s=5.0, seed=7)
    again = Campaign(DEFAULT, duration_s=5.0, seed=7)
    assert plan.run(37) == again.run(37)
    # default.yaml lists two IMU error models: each its own seed
    assert {"imu_errors.0.seed", "imu_errors.1.seed", "variation.bending.random.seed"} <= set(
        plan.seed_keys
    )
    assert all(k.endswith(".seed") for k in plan.seed_keys)  # and the aiding sensors' seeds
    seeds = [tuple(plan.run(k).seeds.values()) for k in range(50)]
    assert len(set(seeds)) == 50  # every run its own seeds
    other = Campaign(DEFAULT, duration_s=5.0, seed=8)
    assert other.run(37).seeds != plan.run(37).seeds
    assert "navigator.imu_topic=/variation/imu_measured" in plan.run(0).overrides
    assert plan.shared_level == "reference"  # the bending seed varies: the variation is per run


def test_vary_draws_and_validates_through_the_scenario_model():
    v = parse_vary("navigator.initial_errors.attitude_rph_deg=normal([0, 0, 0], [0.1, 0.1, 1])")
    plan = Campaign(DEFAULT, duration_s=5.0, varies=[v])
    draws = [plan.run(k).draws[v.key] for k in range(200)]
    heading = np.array([d[2] for d in draws])
    assert abs(heading.mean()) < 4 * 1 / np.sqrt(200) and 0.8 < heading.std() < 1.2
    scenario = plan.scenario(plan.run(3))
    assert list(scenario.navigator.initial_errors.attitude_rph_deg) == draws[3]
    u = parse_vary("imu_errors.0.gyro_bias_dph=uniform(-2, 2)")
    values = [Campaign(DEFAULT, varies=[u]).run(k).draws[u.key] for k in range(20)]
    assert all(-2 <= x <= 2 for x in values)
    with pytest.raises(ScenarioError) as info:
        Campaign(DEFAULT, varies=[parse_vary("imu_errors.0.gyro_arw=normal(0, 1)")])
    assert info.value.key == "imu_errors[0].gyro_arw"
    for bad in ("x=normal(1)", "x=gauss(0, 1)", "x=normal(0, -1)", "x=uniform(2, 1)",
                "x=normal([0, 0], [1])", "normal(0, 1)", "x=normal(a, 1)"):  # fmt: skip
        with pytest.raises(ScenarioError):
            parse_vary(bad)


def test_a_campaign_needs_something_to_vary(tmp_path):
    scenario = tmp_path / "s.yaml"
    text = DEFAULT.read_text().split("# IMU error model")[0]
    scenario.write_text(text)
    with pytest.raises(ScenarioError) as info:
        Campaign(scenario)
    assert info.value.key == "imu_errors"


# -- campaigns on a local cluster --------------------------------------------------------------


def _generate_errors(tmp_path: Path, overrides: tuple[str, ...]) -> np.ndarray:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    out = tmp_path / "generated"
    args = [str(BIN / "strapdown-sim"), "generate", str(DEFAULT), "--out", str(out), "--quiet"]
    for o in overrides:
        args += ["--set", o]
    subprocess.run(args, check=True, timeout=300)
    store = get_typestore(Stores.ROS2_JAZZY)
    columns = []
    with Reader(out) as reader:
        for topic in ERROR_TOPICS:
            conns = [c for c in reader.connections if c.topic == topic]
            rows = []
            for c, _, raw in reader.messages(connections=conns):
                v = store.deserialize_cdr(raw, c.msgtype).vector
                rows.append((v.x, v.y, v.z))
            columns.append(np.array(rows))
    return np.hstack(columns)


@pytest.mark.slow
def test_run_k_equals_generate_and_an_interrupted_campaign_resumes(tmp_path):
    out = tmp_path / "campaign"
    result = run_campaign(DEFAULT, out, 3, duration_s=10.0, workers=2, log=quiet)
    assert result.ran == [0, 1, 2] and not result.failed and result.workers == 2
    summary = json.loads((run_dir(out, 2) / "summary.json").read_text())
    _, errors = read_run_errors(out, 2)
    expected = _generate_errors(tmp_path, tuple(summary["overrides"]))
    assert errors.shape == expected.shape == (200, 9)
    assert errors.tobytes() == expected.tobytes()  # bit for bit
    # the report and the ensemble tables
    md = (out / "report" / "campaign.md").read_text()
    assert "3 of 3 runs finished" in md and "final horizontal position error" in md
    assert (out / "report" / "ensemble_errors.png").stat().st_size > 10_000
    import pyarrow.parquet as pq

    assert pq.read_table(out / "runs.parquet").num_rows == 3
    assert pq.read_table(out / "errors.parquet").num_rows == 600
    # a run lost (as by an interruption) is the only one run again, with the same bits
    (run_dir(out, 1) / "summary.json").unlink()
    before = read_run_errors(out, 0)[1]
    again = run_campaign(DEFAULT, out, 3, duration_s=10.0, workers=1, log=quiet)
    assert again.ran == [1] and again.skipped == [0, 2]
    assert read_run_errors(out, 0)[1].tobytes() == before.tobytes()
    # a different campaign in the same directory is refused
    with pytest.raises(FileExistsError):
        run_campaign(DEFAULT, out, 3, duration_s=10.0, seed=1, workers=1)


@pytest.mark.slow
def test_a_failing_run_is_reported_and_the_others_finish(tmp_path):
    out = tmp_path / "campaign"
    # a normal draw of a standard deviation goes negative in some runs: those runs fail
    vary = ["imu_errors.0.gyro_arw_dpsh=normal(0.05, 0.1)"]
    plan = Campaign(DEFAULT, duration_s=3.0, varies=[parse_vary(vary[0])])
    draws = [plan.run(k).draws[vary[0].split("=")[0]] for k in range(4)]
    bad = {k for k, d in enumerate(draws) if d < 0}
    assert bad and len(bad) < 4
    messages: list[str] = []
    result = run_campaign(DEFAULT, out, 4, duration_s=3.0, vary=vary, workers=2,
                          log=messages.append)  # fmt: skip
    assert set(result.failed) == bad
    assert all("imu_errors[0].gyro_arw_dpsh" in why for why in result.failed.values())
    assert finished_runs(out) == set(range(4)) - bad
    assert any(f"run {min(bad):04d} failed" in m for m in messages)
    assert "Failed runs" in (out / "report" / "campaign.md").read_text()


# -- an existing Dask cluster on loopback ------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(args: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen(args, stdout=log.open("w"), stderr=subprocess.STDOUT,
                            cwd=log.parent, start_new_session=True)  # fmt: skip


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
        p.wait(timeout=30)


@pytest.mark.slow
def test_scheduler_address_and_a_killed_worker(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(BIN / "dask")
    procs = [_start([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                     "--no-dashboard"], tmp_path / "scheduler.log")]  # fmt: skip
    try:
        for i in range(2):
            procs.append(_start([dask, "worker", address, "--nworkers", "1", "--nthreads", "1",
                                 "--no-dashboard"], tmp_path / f"worker{i}.log"))  # fmt: skip
        out = tmp_path / "campaign"
        cmd = [str(BIN / "strapdown-sim"), "campaign", str(DEFAULT), "--runs", "8",
               "--duration", "20", "--out", str(out), "--scheduler", address]  # fmt: skip
        campaign = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    text=True)  # fmt: skip
        deadline = time.monotonic() + 240
        while not finished_runs(out) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert finished_runs(out), "no run finished"
        os.killpg(procs[2].pid, signal.SIGKILL)  # a worker dies mid-campaign
        stdout, _ = campaign.communicate(timeout=300)
        # the scheduler reruns the dead worker's runs on the other; rerunning completes anyway
        if campaign.returncode != 0 or finished_runs(out) != set(range(8)):
            rerun = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
            assert rerun.returncode == 0, rerun.stdout + rerun.stderr
        assert finished_runs(out) == set(range(8)), stdout
        import pyarrow.parquet as pq

        runs = pq.read_table(out / "runs.parquet").column("run").to_pylist()
        assert sorted(runs) == list(range(8))  # every run present once
        # and the same bits as a local run of the same index
        local = tmp_path / "local"
        run_campaign(DEFAULT, local, 1, duration_s=20.0, workers=1, log=quiet)
        assert read_run_errors(local, 0)[1].tobytes() == read_run_errors(out, 0)[1].tobytes()
    finally:
        _stop(procs)
