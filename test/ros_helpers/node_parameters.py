"""The parameters each node really declares, read by constructing it in this process.

``declared_parameters(name, bag)`` → ``[(parameter, default, description), ...]`` in declaration
order: every ``declare_*`` helper of ``strapdown_ros.nodes.parameters`` goes through
``parameters._declare``, which is wrapped here to record its arguments while the node class is
built (with the minimal parameters that let it build: the default scenario for 1 s, the aided
node test/data/aided_default_noisy.yaml, a temporary output directory, ``bag`` for the player).
``executor`` (declared by ``run_node`` after construction) is appended. Needs rclpy; used by
test/test_node_usage_params.py and, as a script, to print the table of
``strapdown_ros/nodes/usage.py``:

    python test/ros_helpers/node_parameters.py BAG
"""

from __future__ import annotations

import importlib
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "config" / "scenarios" / "default.yaml"
#: Nodes that need a section default.yaml does not have, and the scenario they are built with.
SCENARIOS = {"aided_node": REPO / "test" / "data" / "aided_default_noisy.yaml",
             "transfer_node": REPO / "config" / "scenarios" / "transfer_alignment.yaml"}
#: Class of each node executable.
CLASSES = {
    "trajectory_node": "TrajectoryNode",
    "variation_node": "VariationNode",
    "navigator_node": "NavigatorNode",
    "imu_model_node": "ImuModelNode",
    "aiding_node": "AidingNode",
    "aided_node": "AidedNode",
    "transfer_node": "TransferNode",
    "bag_recorder": "BagRecorder",
    "bag_player": "BagPlayer",
}


def declared_parameters(name: str, bag: str | Path) -> list[tuple[str, object, str]]:
    import rclpy

    from strapdown_ros.nodes import parameters

    module = importlib.import_module(f"strapdown_ros.nodes.{name}")
    cls = getattr(module, CLASSES[name])
    args = ["--ros-args"]
    with tempfile.TemporaryDirectory() as tmp:
        scenario = SCENARIOS.get(name, SCENARIO)
        for p in (f"scenario:={scenario}", "duration_s:=1.0", f"output:={tmp}/out",
                  f"bag:={bag}"):  # fmt: skip
            args += ["-p", p]
        recorded: list[tuple[str, object, str]] = []
        real = parameters._declare

        def spy(node, pname, default, description, dynamic=False):
            recorded.append((pname, default, description))
            return real(node, pname, default, description, dynamic)

        context = rclpy.Context()
        rclpy.init(args=args, context=context)
        parameters._declare = spy
        node = None
        try:
            node = _construct(cls, context)
        finally:
            parameters._declare = real
            if node is not None:
                node.destroy_node()
            rclpy.shutdown(context=context)
    recorded.append(("executor", "events", "rclpy executor: events | single_threaded"))
    seen: set[str] = set()
    return [r for r in recorded if not (r[0] in seen or seen.add(r[0]))]


def _construct(cls, context):
    """The node classes build on the default context; point rclpy's default at ``context``."""
    from rclpy.node import Node

    real_init = Node.__init__

    def init(self, *a, **kw):
        kw.setdefault("context", context)
        real_init(self, *a, **kw)

    Node.__init__ = init
    try:
        return cls()
    finally:
        Node.__init__ = real_init


if __name__ == "__main__":
    for node_name in CLASSES:
        print(f"    {node_name!r}: (")
        for row in declared_parameters(node_name, sys.argv[1]):
            print(f"        {row!r},")
        print("    ),")
