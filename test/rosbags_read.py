"""Test helpers independent of the package's decoder: a bag's messages read with rosbags, and
a shipped scenario edited in memory and generated."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

SCENARIOS = Path(__file__).resolve().parent.parent / "config" / "scenarios"


def messages_by_stamp(bag: Path, topic: str) -> dict[int, Any]:
    """``header.stamp`` (ns) → message of ``topic``, decoded by rosbags' Jazzy typestore."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    out = {}
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        for conn, _, raw in reader.messages(connections=conns):
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            out[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = msg
    return out


def generate_edited(tmp: Path, name: str, edit: Callable[[dict], None]) -> Path:
    """The bag of shipped scenario ``name`` with ``edit`` applied to its document."""
    from strapdown_ros.config import load_scenario
    from strapdown_ros.generate import generate_dataset

    doc = yaml.safe_load((SCENARIOS / f"{name}.yaml").read_text())
    edit(doc)
    path = tmp / f"{name}_edited.yaml"
    path.write_text(yaml.safe_dump(doc))
    generate_dataset(load_scenario(path), tmp / "bag")
    return tmp / "bag"
