"""Replay a bag's reference Imu/Odometry raw, with injected faults (test subprocess).

Publishes the payloads of ``--imu-topic`` and ``--odom-topic`` of the bag ``--bag`` cycle by
cycle (at one stamp: Odometry, then Imu, as ``merge_order`` puts them), RELIABLE, depth 5000,
after both publishers have at least ``--wait-subscribers`` matched subscriptions. Faults, each
repeatable, by cycle index m (position in the Odometry stamps):

* ``--drop M``: cycle M is not published (a gap);
* ``--swap M``: cycles M and M+1 are published in the order M+1, M (out-of-order stamps);
* ``--duplicate M``: cycle M is published twice (identical content).

``--interval`` s between cycles (0: a burst). Prints ``PUBLISHED <n>`` and exits 0 once every
message is acknowledged; exit 3 on timeout.
"""

from __future__ import annotations

import argparse
import sys
import time


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--bag", required=True)
    parser.add_argument("--imu-topic", default="/reference/imu")
    parser.add_argument("--odom-topic", default="/reference/odom")
    parser.add_argument("--drop", type=int, action="append", default=[])
    parser.add_argument("--swap", type=int, action="append", default=[])
    parser.add_argument("--duplicate", type=int, action="append", default=[])
    parser.add_argument("--interval", type=float, default=0.0)
    parser.add_argument("--wait-subscribers", type=int, default=1)
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from strapdown_ros.bag.reader import read_bag

    bag = read_bag(args.bag, [args.imu_topic, args.odom_topic], raw=True)
    imu, odom = bag.topics[args.imu_topic], bag.topics[args.odom_topic]
    imu_by_stamp = dict(zip(imu.fields.stamps_ns.tolist(), imu.payloads, strict=True))
    # One entry per cycle: [(kind, payload), ...] in the order of merge_order.
    cycles = []
    for stamp, payload in zip(odom.fields.stamps_ns.tolist(), odom.payloads, strict=True):
        items = [("odom", payload)]
        if stamp in imu_by_stamp:
            items.append(("imu", imu_by_stamp[stamp]))
        cycles.append(items)
    order = [m for m in range(len(cycles)) if m not in args.drop]
    for m in args.swap:
        i = order.index(m)
        order[i], order[i + 1] = order[i + 1], order[i]
    for m in args.duplicate:
        order.insert(order.index(m) + 1, m)

    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=5000,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    rclpy.init()
    node = rclpy.create_node("reference_replay")
    try:
        pubs = {
            "imu": node.create_publisher(Imu, args.imu_topic, qos),
            "odom": node.create_publisher(Odometry, args.odom_topic, qos),
        }
        while any(p.get_subscription_count() < args.wait_subscribers for p in pubs.values()):
            if time.monotonic() > deadline:
                print("TIMEOUT waiting for subscriptions", flush=True)
                return 3
            rclpy.spin_once(node, timeout_sec=0.02)
        print("MATCHED", flush=True)
        count = 0
        for m in order:
            for kind, payload in cycles[m]:
                pubs[kind].publish(bytes(payload))
                count += 1
            if args.interval > 0:
                time.sleep(args.interval)
        for pub in pubs.values():
            remaining = max(deadline - time.monotonic(), 0.1)
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9))):
                print("TIMEOUT waiting for acknowledgements", flush=True)
                return 3
        print(f"PUBLISHED {count}", flush=True)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
