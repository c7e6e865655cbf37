"""A node whose DDS teardown hangs still ends, with the status its run returned.

``run_node`` tears the node down in a daemon thread for at most ``TEARDOWN_TIMEOUT_S``; when
that thread is still running then, the process leaves with ``os._exit(status)`` and says so.
The hang is simulated by a teardown that sleeps (the child below; it borrows variation_node's
name for the command-line front end); the node is a real rclpy node on the test's own domain.
"""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

CHILD = r"""
import sys, time
from strapdown_ros.nodes import lifecycle

hang = sys.argv[1] == "hang"
status = int(sys.argv[2])
lifecycle.TEARDOWN_TIMEOUT_S = 1.0
if hang:
    real = lifecycle._teardown
    def _teardown(node, executor):
        time.sleep(120.0)
        real(node, executor)
    lifecycle._teardown = _teardown

import rclpy.node

class Node(rclpy.node.Node):
    def __init__(self):
        super().__init__("teardown_probe")
    def run(self, executor):
        executor.spin_once(timeout_sec=0.01)
        print("RUN DONE", flush=True)
        return status

sys.exit(lifecycle.run_node(Node, "variation_node", []))
"""


@pytest.mark.parametrize(("mode", "status"), [("hang", 0), ("hang", 1), ("clean", 0), ("clean", 1)])
def test_hung_teardown_leaves_with_the_run_status(ros_env, mode: str, status: int) -> None:
    start = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(status)],
        env=ros_env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    wall = time.monotonic() - start
    assert "RUN DONE" in done.stdout, done.stderr
    assert done.returncode == status, done.stderr
    said = "variation_node: shutdown did not finish within 1 s; exiting with status"
    if mode == "hang":
        assert f"{said} {status}" in done.stderr
        assert wall < 30.0  # not the 120 s of the simulated hang
    else:
        assert said not in done.stderr
