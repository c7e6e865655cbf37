"""Without tf2_msgs (no compiler at ``make setup``), ``strapdown-sim run`` still records the TF
``generate`` writes: the nodes say once that live TF is off and why, and ``bag_recorder``
derives ``/tf`` and ``/tf_static`` from the Odometry it records (docs/recording.md).

tf2_msgs is made unimportable for the pipeline's processes by a package of that name, first
on ``PYTHONPATH``, whose import fails.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml
from node_testing import generate, run_live

from strapdown_ros.bag.reader import read_bag

REPO = Path(__file__).resolve().parent.parent
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"

pytestmark = pytest.mark.slow


def test_run_without_tf2_msgs_records_generates_tf(tmp_path, ros_env) -> None:
    shadow = tmp_path / "shadow" / "tf2_msgs"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text('raise ImportError("tf2_msgs hidden by the test")\n')
    env = dict(ros_env)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(shadow.parent), env.get("PYTHONPATH", "")) if p
    )
    gen, live = tmp_path / "generate", tmp_path / "run"
    generate(SCENARIO, gen, "--duration", "2", timeout=120)
    run_live(SCENARIO, live, env, "--duration", "2")
    logs = "".join(p.read_text() for p in Path(f"{live}.logs").glob("*.log"))
    for node in ("trajectory_node", "variation_node", "navigator_node"):
        assert f"[{node}]: live TF is off: tf2_msgs/msg/TFMessage is not importable" in logs
    assert "[bag_recorder]: tf2_msgs/msg/TFMessage is not importable" in logs
    meta = yaml.safe_load((live / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["custom_data"]["tf"].startswith("derived by bag_recorder")
    a, b = read_bag(live, raw=True), read_bag(gen, raw=True)
    assert set(a.topics) == set(b.topics) and {"/tf", "/tf_static"} <= set(b.topics)
    for topic in ("/tf", "/tf_static"):
        got = sorted(bytes(p) for p in a.topics[topic].payloads)
        assert got == sorted(bytes(p) for p in b.topics[topic].payloads), topic
        assert sorted(a.topics[topic].log_time_ns) == sorted(b.topics[topic].log_time_ns), topic
