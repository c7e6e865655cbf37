"""Replay a bag's Imu/Odometry pair raw with injected faults, optionally recording a node's
output (test subprocess).

Publishes the payloads of ``--imu-topic`` and ``--odom-topic`` of the bag ``--bag`` cycle by
cycle (at one stamp: Odometry, then Imu, as ``merge_order`` puts them), RELIABLE, after both
publishers have ``--wait-subscribers`` matched subscriptions (``--no-wait-odom``: the Imu's
only; ``--no-wait-imu``: the Odometry's only) and every ``--record`` topic a matched
publisher. Faults, each repeatable, by cycle index m (position in the Odometry stamps):

* ``--drop M``: cycle M is not published (a gap); ``--drop-imu M`` / ``--drop-odom M``: only
  its Imu / Odometry message;
* ``--swap M``: cycles M and M+1 are published in the order M+1, M (out-of-order stamps);
* ``--duplicate M``: cycle M is published twice (identical content);
* ``--nan-imu M`` / ``--nan-odom M``: a NaN in the message's angular velocity / position;
* ``--zero-quat-odom M``: the Odometry's orientation quaternion (0, 0, 0, 0) (finite, degenerate);
* ``--jump-back AT:TO``: after cycle AT, continue from cycle TO (a restarted source).

``--interval`` s between cycles (0: a burst). Prints ``MATCHED``, then ``PUBLISHED <n>``.
Without ``--record`` it exits 0 once every message is acknowledged. ``--record NAME=pkg/msg/Type``
(repeatable) subscribes raw; when no output arrived for ``--quiet`` s after the last input (or
at ``--timeout``), the payloads per topic are pickled to ``--out`` as ``{name: [bytes, ...]}``.
Exit 3 on a timeout waiting for the subscriptions or the acknowledgements.
"""

from __future__ import annotations

import argparse
import pickle
import time

from ros_child import exit_with, message_type, reliable_qos, ros_node, wait_acked, wait_matched


def _with_nan(msgtype: str, payload: bytes, field: str) -> bytes:
    from strapdown_ros.bag import cdr

    fields = cdr.deserialize(msgtype, [payload])
    array = getattr(fields, field).copy()
    array[0, 0] = float("nan")
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values[field] = array
    return bytes(cdr.serialize(type(fields)(**values))[0])


def _with_zero_quaternion(payload: bytes) -> bytes:
    import numpy as np

    from strapdown_ros.bag import cdr

    fields = cdr.deserialize(cdr.ODOMETRY, [payload])
    values = {f: getattr(fields, f) for f in fields.__dataclass_fields__}
    values["orientation"] = np.zeros((1, 4))
    return bytes(cdr.serialize(type(fields)(**values))[0])


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    parser.add_argument("--bag", required=True)
    parser.add_argument("--imu-topic", default="/reference/imu")
    parser.add_argument("--odom-topic", default="/reference/odom")
    for fault in ("drop", "drop-imu", "drop-odom", "swap", "duplicate", "nan-imu", "nan-odom",
                  "zero-quat-odom"):  # fmt: skip
        parser.add_argument(f"--{fault}", type=int, action="append", default=[], metavar="M")
    parser.add_argument("--jump-back", default=None, metavar="AT:TO")
    parser.add_argument("--interval", type=float, default=0.0)
    parser.add_argument("--wait-subscribers", type=int, default=1)
    parser.add_argument("--no-wait-odom", action="store_true")
    parser.add_argument("--no-wait-imu", action="store_true")
    parser.add_argument("--record", action="append", default=[], metavar="NAME=TYPE")
    parser.add_argument("--out", default=None, help="with --record: the pickle to write")
    parser.add_argument("--quiet", type=float, default=4.0)
    parser.add_argument("--timeout", type=float, default=60.0)
    return parser.parse_args()


def _cycles(args: argparse.Namespace) -> list[list[tuple[str, bytes]]]:
    """One entry per cycle: ``[(kind, payload), ...]`` in the order of merge_order, faults
    applied to the messages (NaN, dropped Imu or Odometry)."""
    from strapdown_ros.bag import cdr
    from strapdown_ros.bag.reader import read_bag

    bag = read_bag(args.bag, [args.imu_topic, args.odom_topic], raw=True)
    imu, odom = bag.topics[args.imu_topic], bag.topics[args.odom_topic]
    imu_by_stamp = dict(zip(imu.fields.stamps_ns.tolist(), imu.payloads, strict=True))
    cycles = []
    stamped = zip(odom.fields.stamps_ns.tolist(), odom.payloads, strict=True)
    for m, (stamp, payload) in enumerate(stamped):
        items = []
        if m not in args.drop_odom:
            data = bytes(payload)
            if m in args.nan_odom:
                data = _with_nan(cdr.ODOMETRY, data, "position")
            if m in args.zero_quat_odom:
                data = _with_zero_quaternion(data)
            items.append(("odom", data))
        if stamp in imu_by_stamp and m not in args.drop_imu:
            data = bytes(imu_by_stamp[stamp])
            if m in args.nan_imu:
                data = _with_nan(cdr.IMU, data, "angular_velocity")
            items.append(("imu", data))
        cycles.append(items)
    return cycles


def _order(args: argparse.Namespace, n: int) -> list[int]:
    """The cycles in publishing order: drops, swaps, duplicates and the jump back applied."""
    order = list(range(n))
    if args.jump_back:
        at, to = map(int, args.jump_back.split(":"))
        order = list(range(at + 1)) + list(range(to, n))
    order = [m for m in order if m not in args.drop]
    for m in args.swap:
        i = order.index(m)
        order[i], order[i + 1] = order[i + 1], order[i]
    for m in args.duplicate:
        order.insert(order.index(m) + 1, m)
    return order


def main() -> int:
    args = _arguments()
    deadline = time.monotonic() + args.timeout

    import rclpy
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu

    cycles = _cycles(args)
    order = _order(args, len(cycles))
    qos = reliable_qos(10000)
    received: dict[str, list[bytes]] = {}
    last_rx = [time.monotonic()]
    with ros_node("reference_replay") as node:
        pubs = {
            "imu": node.create_publisher(Imu, args.imu_topic, qos),
            "odom": node.create_publisher(Odometry, args.odom_topic, qos),
        }
        subs = []
        for item in args.record:
            name, msgtype = item.split("=")
            received[name] = []

            def on_message(data: bytes, name: str = name) -> None:
                received[name].append(bytes(data))
                last_rx[0] = time.monotonic()

            subs.append(
                node.create_subscription(message_type(msgtype), name, on_message, qos, raw=True)
            )
        skip = {"odom": args.no_wait_odom, "imu": args.no_wait_imu}
        wait = [p for k, p in pubs.items() if not skip[k]]
        if not wait_matched(node, deadline, wait, subs, args.wait_subscribers):
            return 3
        print("MATCHED", flush=True)
        count = 0
        for m in order:
            for kind, payload in cycles[m]:
                pubs[kind].publish(payload)
                count += 1
            if subs:  # take the node's output as it comes
                rclpy.spin_once(node, timeout_sec=0.0)
            if args.interval > 0:
                time.sleep(args.interval)
        if not subs:
            if not wait_acked(list(pubs.values()), deadline):
                return 3
            print(f"PUBLISHED {count}", flush=True)
            return 0
        print(f"PUBLISHED {count}", flush=True)
        last_rx[0] = max(last_rx[0], time.monotonic())
        while time.monotonic() < deadline and time.monotonic() - last_rx[0] < args.quiet:
            rclpy.spin_once(node, timeout_sec=0.05)
        with open(args.out, "wb") as f:
            pickle.dump(received, f)
        return 0


if __name__ == "__main__":
    exit_with(main)
