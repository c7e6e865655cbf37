"""Receive N sensor_msgs/Imu messages and check them bit for bit (DDS smoke test subprocess).

Prints ``READY`` once it has matched a publisher, then ``RECEIVED <n>`` and ``OK`` when all N
messages arrived in order with exactly the expected field values (and no extra message came
within a short grace period).  Exit 0 on success, 1 on a wrong message, 3 on timeout.
"""

from __future__ import annotations

import argparse
import time

from imu_pattern import differences, expected_fields, fields_of
from ros_child import exit_with, reliable_qos, ros_node, wait_matched


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--topic", required=True)
    parser.add_argument("--count", type=int, required=True)
    parser.add_argument("--timeout", type=float, default=30.0)
    parser.add_argument("--grace", type=float, default=0.3, help="seconds to watch for extras")
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    import rclpy
    from sensor_msgs.msg import Imu

    received: list[dict] = []
    with ros_node("smoke_imu_subscriber") as node:
        sub = node.create_subscription(
            Imu, args.topic, lambda msg: received.append(fields_of(msg)),
            reliable_qos(max(args.count, 1)),
        )  # fmt: skip
        if not wait_matched(node, deadline, subs=[sub], what="a publisher", step_s=0.05):
            return 3
        print("READY", flush=True)

        while len(received) < args.count:
            if time.monotonic() > deadline:
                print(f"TIMEOUT after {len(received)} of {args.count} messages", flush=True)
                return 3
            rclpy.spin_once(node, timeout_sec=0.05)
        grace_end = time.monotonic() + args.grace
        while time.monotonic() < grace_end:
            rclpy.spin_once(node, timeout_sec=0.05)

        print(f"RECEIVED {len(received)}", flush=True)
        if len(received) != args.count:
            print(f"WRONG COUNT {len(received)} != {args.count}", flush=True)
            return 1
        bad = 0
        for i, got in enumerate(received):
            for diff in differences(got, expected_fields(i)):
                bad += 1
                if bad <= 20:
                    print(f"MISMATCH message {i}: {diff}", flush=True)
        if bad:
            return 1
        print("OK", flush=True)
        return 0


if __name__ == "__main__":
    exit_with(main)
