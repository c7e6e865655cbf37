"""The shipped viewer configurations (config/viz/, docs/viewing.md) parse, and every topic and
frame they name exists in a bag that ``generate`` writes for the default scenario.

Neither Foxglove nor RViz runs here; this is what can be checked without them.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.config import load_scenario
from strapdown_ros.generate import generate_dataset

REPO = Path(__file__).resolve().parent.parent
VIZ = REPO / "config" / "viz"
FOXGLOVE = VIZ / "strapdown.foxglove.json"
RVIZ = VIZ / "strapdown.rviz"
TS = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[set[str], set[str]]:
    """Topics and TF frames of a short default-scenario bag."""
    out = tmp_path_factory.mktemp("viz") / "bag"
    generate_dataset(load_scenario(REPO / "config/scenarios/default.yaml", duration_s=2.0), out)
    frames: set[str] = set()
    with Reader(out) as reader:
        topics = {c.topic for c in reader.connections}
        conns = [c for c in reader.connections if c.topic in ("/tf", "/tf_static")]
        for conn, _, raw in reader.messages(connections=conns):
            for tr in TS.deserialize_cdr(raw, conn.msgtype).transforms:
                frames |= {tr.header.frame_id, tr.child_frame_id}
    return topics, frames


def _foxglove() -> tuple[set[str], set[str]]:
    layout = json.loads(FOXGLOVE.read_text())
    assert {"configById", "layout"} <= set(layout)
    topics: set[str] = set()
    frames: set[str] = set()

    def panels(node: Any) -> Iterator[str]:
        if isinstance(node, str):
            yield node
        else:
            yield from panels(node["first"])
            yield from panels(node["second"])

    placed = set(panels(layout["layout"]))
    assert placed == set(layout["configById"]), "every panel is placed, every placed one exists"
    for panel_id, cfg in layout["configById"].items():
        kind = panel_id.split("!")[0]
        if kind == "3D":
            topics |= set(cfg.get("topics", {}))
            frames.add(cfg["followTf"])
            shown = cfg.get("transforms", {})
            frames |= {k.split(":", 1)[1] for k in shown if k.startswith("frame:")}
            layers = cfg.get("layers", {}).values()
            frames |= {layer["frameId"] for layer in layers if "frameId" in layer}
        elif kind == "Plot":
            assert cfg["paths"]
            for path in cfg["paths"]:
                topic, field = path["value"].split(".", 1)
                assert field.startswith("vector."), path
                topics.add(topic)
        elif kind == "Map":
            topics.add(cfg["followTopic"])
        else:
            pytest.fail(f"unexpected panel {panel_id}")
    return topics, frames


def _rviz() -> tuple[set[str], set[str]]:
    cfg = yaml.safe_load(RVIZ.read_text())
    manager = cfg["Visualization Manager"]
    topics: set[str] = set()
    frames = {manager["Global Options"]["Fixed Frame"]}
    frames.add(manager["Views"]["Current"]["Target Frame"])

    def tree(node: dict) -> Iterator[str]:
        for name, child in node.items():
            yield name
            yield from tree(child or {})

    for display in manager["Displays"]:
        cls = display["Class"]
        assert cls.startswith("rviz_default_plugins/"), cls
        if "Topic" in display:
            topics.add(display["Topic"]["Value"])
        if "Reference Frame" in display:
            frames.add(display["Reference Frame"])
        if cls.endswith("/TF"):
            frames |= set(tree(display["Tree"]))
    return topics, frames


@pytest.mark.parametrize("reader", [_foxglove, _rviz], ids=["foxglove", "rviz"])
def test_viewer_config_names_only_what_the_bag_has(reader, bag) -> None:
    bag_topics, bag_frames = bag
    topics, frames = reader()
    assert topics, "the configuration names no topic"
    assert topics <= bag_topics, sorted(topics - bag_topics)
    assert frames <= bag_frames, sorted(frames - bag_frames)
    # what the issue asks to see: map, the vehicle, the variation IMU and the navigator
    assert {"map", "base_link", "variation_imu", "navigator"} <= frames


def test_foxglove_plots_the_error_topics() -> None:
    topics, _ = _foxglove()
    assert {
        "/navigator/error/position",
        "/navigator/error/velocity",
        "/navigator/error/attitude",
    } <= topics
