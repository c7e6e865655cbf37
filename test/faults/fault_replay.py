"""Replay a bag's Imu/Odometry pair with injected faults and record a node's output (test
subprocess).

Publishes the payloads of ``--imu-topic`` and ``--odom-topic`` of ``--bag`` cycle by cycle (at
one stamp: Odometry, then Imu), RELIABLE, after every publisher has a matched subscription and
every ``--record`` topic a matched publisher. Faults, by cycle index m (position in the
Odometry stamps), each repeatable:

* ``--nan-imu M`` / ``--nan-odom M``: a NaN in the message's angular velocity / position;
* ``--drop-odom M`` / ``--drop-imu M``: the message is not published;
* ``--jump-back AT:TO``: after cycle AT, continue from cycle TO (a restarted source).

``--no-wait-odom``: do not wait for a subscription to the Odometry topic (a node without one).

``--record NAME=pkg/msg/Type`` (repeatable) subscribes raw; when no output arrived for
``--quiet`` s after the last input (or at ``--timeout``), the payloads per topic are pickled to
``--out`` as ``{name: [bytes, ...]}``. Prints ``MATCHED`` and ``PUBLISHED n``; exit 0, 3 on a
timeout waiting for the subscriptions.
"""

from __future__ import annotations

import argparse
import importlib
import pickle
import sys
import time


def _with_nan(msgtype: str, payload: bytes, field: str) -> bytes:
    from strapdown_ros.bag import cdr

    fields = cdr.deserialize(msgtype, [payload])
    array = getattr(fields, field).copy()
    array[0, 0] = float("nan")
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values[field] = array
    return bytes(cdr.serialize(type(fields)(**values))[0])


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--bag", required=True)
    parser.add_argument("--imu-topic", required=True)
    parser.add_argument("--odom-topic", required=True)
    parser.add_argument("--nan-imu", type=int, action="append", default=[])
    parser.add_argument("--nan-odom", type=int, action="append", default=[])
    parser.add_argument("--drop-imu", type=int, action="append", default=[])
    parser.add_argument("--drop-odom", type=int, action="append", default=[])
    parser.add_argument("--jump-back", default=None, metavar="AT:TO")
    parser.add_argument("--no-wait-odom", action="store_true")
    parser.add_argument("--record", action="append", default=[], metavar="NAME=TYPE")
    parser.add_argument("--out", required=True)
    parser.add_argument("--quiet", type=float, default=4.0)
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from strapdown_ros.bag import cdr
    from strapdown_ros.bag.reader import read_bag

    bag = read_bag(args.bag, [args.imu_topic, args.odom_topic], raw=True)
    imu, odom = bag.topics[args.imu_topic], bag.topics[args.odom_topic]
    imu_by_stamp = dict(zip(imu.fields.stamps_ns.tolist(), imu.payloads, strict=True))
    cycles = []
    for m, (stamp, payload) in enumerate(
        zip(odom.fields.stamps_ns.tolist(), odom.payloads, strict=True)
    ):
        items = []
        if m not in args.drop_odom:
            data = bytes(payload)
            if m in args.nan_odom:
                data = _with_nan(cdr.ODOMETRY, data, "position")
            items.append(("odom", data))
        if stamp in imu_by_stamp and m not in args.drop_imu:
            data = bytes(imu_by_stamp[stamp])
            if m in args.nan_imu:
                data = _with_nan(cdr.IMU, data, "angular_velocity")
            items.append(("imu", data))
        cycles.append(items)
    order = list(range(len(cycles)))
    if args.jump_back:
        at, to = map(int, args.jump_back.split(":"))
        order = list(range(at + 1)) + list(range(to, len(cycles)))

    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10000,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    rclpy.init()
    node = rclpy.create_node("fault_replay")
    received: dict[str, list[bytes]] = {}
    last_rx = [time.monotonic()]
    try:
        pubs = {
            "imu": node.create_publisher(Imu, args.imu_topic, qos),
            "odom": node.create_publisher(Odometry, args.odom_topic, qos),
        }
        subs = []
        for item in args.record:
            name, msgtype = item.split("=")
            pkg, _, cls = msgtype.split("/")
            msg_class = getattr(importlib.import_module(f"{pkg}.msg"), cls)
            received[name] = []

            def on_message(data: bytes, name: str = name) -> None:
                received[name].append(bytes(data))
                last_rx[0] = time.monotonic()

            subs.append(node.create_subscription(msg_class, name, on_message, qos, raw=True))
        wait = [p for k, p in pubs.items() if not (k == "odom" and args.no_wait_odom)]
        while any(p.get_subscription_count() < 1 for p in wait) or any(
            s.get_publisher_count() < 1 for s in subs
        ):
            if time.monotonic() > deadline:
                print("TIMEOUT waiting for subscriptions", flush=True)
                return 3
            rclpy.spin_once(node, timeout_sec=0.02)
        print("MATCHED", flush=True)
        count = 0
        for m in order:
            for kind, payload in cycles[m]:
                pubs[kind].publish(payload)
                count += 1
            rclpy.spin_once(node, timeout_sec=0.0)
            time.sleep(0.0005)
        print(f"PUBLISHED {count}", flush=True)
        last_rx[0] = max(last_rx[0], time.monotonic())
        while time.monotonic() < deadline and time.monotonic() - last_rx[0] < args.quiet:
            rclpy.spin_once(node, timeout_sec=0.05)
        with open(args.out, "wb") as f:
            pickle.dump(received, f)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
