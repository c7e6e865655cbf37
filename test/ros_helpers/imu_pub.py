"""Publish N deterministic sensor_msgs/Imu messages (DDS smoke test, run as a subprocess).

Protocol with the test: once the publisher has matched a subscription it prints ``MATCHED``;
it then waits for a line ``go`` on stdin (sent when the subscriber reports that it matched
this publisher, so both ends are matched), publishes, waits until every message is
acknowledged (RELIABLE) and prints ``PUBLISHED <n> acked``.  Exit 0 on success, 3 on timeout.
"""

from __future__ import annotations

import argparse
import select
import sys
import time

from imu_pattern import make_imu
from ros_child import exit_with, reliable_qos, ros_node, wait_acked, wait_matched


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--topic", required=True)
    parser.add_argument("--count", type=int, required=True)
    parser.add_argument("--timeout", type=float, default=30.0)
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    from sensor_msgs.msg import Imu

    with ros_node("smoke_imu_publisher") as node:
        pub = node.create_publisher(Imu, args.topic, reliable_qos(max(args.count, 1)))
        if not wait_matched(node, deadline, [pub], what="a subscription", step_s=0.05):
            return 3
        print("MATCHED", flush=True)

        ready, _, _ = select.select([sys.stdin], [], [], max(deadline - time.monotonic(), 0.0))
        if not ready or sys.stdin.readline().strip() != "go":
            print("TIMEOUT waiting for go", flush=True)
            return 3

        for i in range(args.count):
            pub.publish(make_imu(i))
        if not wait_acked([pub], deadline):
            return 3
        print(f"PUBLISHED {args.count} acked", flush=True)
        return 0


if __name__ == "__main__":
    exit_with(main)
