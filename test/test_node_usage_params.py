"""The parameters ``--help`` lists (``strapdown_ros/nodes/usage.py``) are exactly those each node
declares: names, order, defaults and descriptions, read from the nodes built in this process
(``test/ros_helpers/node_parameters.py``). A parameter added to a node without updating the
table fails here with the row to add; the table also decides which ``-p NAME:=`` a node
accepts, so a stale table would reject a real parameter.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from ros_helpers.node_parameters import declared_parameters  # noqa: E402

from strapdown_ros.nodes import usage  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def bag(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("usage") / "bag"
    proc = subprocess.run(
        [sys.executable, "-m", "strapdown_ros.cli", "generate",
         str(REPO / "config" / "scenarios" / "default.yaml"), "--out", str(out),
         "--duration", "1", "--quiet"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("name", sorted(usage.PARAMETERS))
def test_help_table_is_what_the_node_declares(name: str, bag: Path) -> None:
    declared = tuple(declared_parameters(name, bag))
    assert usage.PARAMETERS[name] == declared, (
        f"strapdown_ros/nodes/usage.py PARAMETERS[{name!r}] differs from what the node "
        f"declares; it should be:\n" + "\n".join(f"        {row!r}," for row in declared)
    )
