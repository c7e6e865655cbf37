"""``strapdown-sim run`` with a topic selection and chunk compression equals ``generate`` with
the same options: the recorder subscribes to the selected topics only, expects their counts
(``zero loss``) and writes zstd chunks; the other nodes still run (the navigator's output needs
the variation streams, which are not recorded)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader
from node_testing import assert_recorded_as_generated, generate, run_live

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
OPTIONS = ["--duration", "2", "--compression", "zstd", "--topics", "/tf", "/tf_static",
           "/navigator/odom", "--regex", "/reference/.*", "--exclude-regex", ".*_map"]  # fmt: skip
SELECTED = {"/tf", "/tf_static", "/navigator/odom", "/reference/imu", "/reference/odom",
            "/reference/fix", "/reference/imu_measured"}  # fmt: skip


@pytest.mark.slow
def test_run_records_the_selection_as_generate_writes_it(tmp_path, ros_env) -> None:
    scenario = tmp_path / "scenario.yaml"
    shutil.copy(SCENARIO, scenario)
    gen, live = tmp_path / "generate", tmp_path / "run"
    generate(scenario, gen, *OPTIONS, timeout=180)
    proc = run_live(scenario, live, dict(ros_env), *OPTIONS, timeout=240)
    assert set(read_bag(gen).topics) == SELECTED
    assert_recorded_as_generated(live, gen)
    (data,) = live.glob("*.mcap")
    with data.open("rb") as f:
        assert {c.compression for c in make_reader(f).get_summary().chunk_indexes} == {"zstd"}
    assert "/variation/imu" not in proc.stdout  # not expected, not reported missing
