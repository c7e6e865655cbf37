"""The trajectory model is built once per process: by ``generate``, by ``trajectory_node`` (the
only node that samples it) and by nobody else; the other nodes and ``run``'s expected counts
read the plan's counts and stamps, which need no fit.

Counted with :func:`strapdown_ros.plan.trajectory_builds` (incremented in ``build_trajectory``).
The ``samples`` scenarios (``waldmann_*``, whose splines are fitted at build) are the case where
a second build costs most.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.plan import resolve_plan, trajectory_builds

SCENARIOS = Path(__file__).resolve().parent.parent / "config" / "scenarios"


@pytest.mark.parametrize("name", ["default", "waldmann_moving", "car"])
def test_generate_builds_the_trajectory_once(name, tmp_path, monkeypatch):
    """Every stage of the chain (reference, variation, IMU errors, navigator, aiding, TF) runs
    on one built trajectory. The producer runs as a thread here so that builds in it count."""
    from strapdown_ros import producer
    from strapdown_ros.generate import generate_dataset

    monkeypatch.setattr(producer.mp, "get_all_start_methods", lambda: ["spawn"])
    scenario = load_scenario(SCENARIOS / f"{name}.yaml", duration_s=2.0)
    before = trajectory_builds()
    summary = generate_dataset(scenario, tmp_path / "bag")
    assert sum(summary.topics.values()) > 0
    assert trajectory_builds() - before == 1


def test_expected_counts_build_no_trajectory():
    """``run``'s expected counts (the recorder's and the pipeline's) come from the plan alone."""
    before = trajectory_builds()
    for path in sorted(SCENARIOS.glob("*.yaml")):
        counts = resolve_plan(load_scenario(path)).counts()
        assert counts and all(n > 0 for n in counts.values()), path.name
    assert trajectory_builds() == before


_NODE_SCRIPT = r"""
import json, sys
import rclpy
from strapdown_ros.plan import trajectory_builds
from strapdown_ros.nodes.{module} import {cls} as Node
rclpy.init(args=["--ros-args", "-p", "scenario:=" + sys.argv[1]])
node = Node()
print(json.dumps({{"builds": trajectory_builds()}}))
node.destroy_node()
rclpy.shutdown()
"""

NODES = {
    "trajectory_node": ("trajectory_node", "TrajectoryNode", 1),
    "variation_node": ("variation_node", "VariationNode", 0),
    "imu_model_node": ("imu_model_node", "ImuModelNode", 0),
    "navigator_node": ("navigator_node", "NavigatorNode", 0),
    "aiding_node": ("aiding_node", "AidingNode", 0),
    "aided_node": ("aided_node", "AidedNode", 0),
    "transfer_node": ("transfer_node", "TransferNode", 0),
    "bag_recorder": ("bag_recorder", "BagRecorder", 0),
}


@pytest.mark.parametrize("node", list(NODES))
def test_node_start_up_builds(node, ros_env, tmp_path):
    """A node's start-up (parameters, plan, stage, publishers) builds the trajectory only if it
    samples it: ``trajectory_node`` once, the others never (on the samples scenario, where a
    build fits splines; ``default.yaml`` for the aiding and IMU-error nodes, which need
    their sections; test/data/aided_default_noisy.yaml for the aided node)."""
    module, cls, want = NODES[node]
    name = "default" if node in ("aiding_node", "imu_model_node") else "waldmann_moving"
    path = SCENARIOS / f"{name}.yaml"
    if node == "aided_node":  # no shipped scenario has an aided section
        path = SCENARIOS.parents[1] / "test" / "data" / "aided_default_noisy.yaml"
    if node == "transfer_node":
        path = SCENARIOS / "transfer_alignment.yaml"
    script = _NODE_SCRIPT.format(module=module, cls=cls)
    env = dict(ros_env)
    if node == "bag_recorder":
        # the recorder writes to its out parameter at start-up
        script = script.replace(
            '"scenario:=" + sys.argv[1]]',
            f'"scenario:=" + sys.argv[1], "-p", "output:={tmp_path / "bag"}"]',
        )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(path)],
        capture_output=True, text=True, timeout=120, env=env,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    line = [x for x in proc.stdout.splitlines() if x.startswith("{")][-1]
    assert json.loads(line)["builds"] == want, proc.stderr
