"""Stand-in for rclpy in the child processes of the ROS-free test tier (test/tiers.py).

``test/tiers.py`` puts ``test/ros_free`` first on ``PYTHONPATH`` when a pytest session selected
no ``dds`` test; importing rclpy in a child process then records the attempt (the test that
started the child fails) and raises ImportError.
"""

import os
import sys
import time

_log = os.environ.get("STRAPDOWN_TEST_RCLPY_LOG")
if _log and os.path.isdir(_log):
    with open(os.path.join(_log, f"{time.time_ns()}-{os.getpid()}"), "w") as _f:
        _f.write(" ".join([sys.executable, *sys.argv]))

raise ImportError(
    "rclpy is blocked in the ROS-free test tier (no dds test selected): the test that started "
    "this process must be marked dds (give it the ros_env fixture)"
)
