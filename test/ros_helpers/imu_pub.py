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


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--topic", required=True)
    parser.add_argument("--count", type=int, required=True)
    parser.add_argument("--timeout", type=float, default=30.0)
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(args.count, 1),
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    rclpy.init()
    node = rclpy.create_node("smoke_imu_publisher")
    try:
        pub = node.create_publisher(Imu, args.topic, qos)
        while pub.get_subscription_count() < 1:
            if time.monotonic() > deadline:
                print("TIMEOUT waiting for a subscription", flush=True)
                return 3
            rclpy.spin_once(node, timeout_sec=0.05)
        print("MATCHED", flush=True)

        ready, _, _ = select.select([sys.stdin], [], [], max(deadline - time.monotonic(), 0.0))
        if not ready or sys.stdin.readline().strip() != "go":
            print("TIMEOUT waiting for go", flush=True)
            return 3

        for i in range(args.count):
            pub.publish(make_imu(i))
        remaining = max(deadline - time.monotonic(), 0.1)
        if not pub.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9))):
            print("TIMEOUT waiting for acknowledgements", flush=True)
            return 3
        print(f"PUBLISHED {args.count} acked", flush=True)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
