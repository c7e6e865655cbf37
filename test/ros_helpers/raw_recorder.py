"""Record raw (serialized) messages of several topics (test subprocess).

``--topic NAME=pkg/msg/Type=COUNT`` (repeatable): subscribe NAME raw, RELIABLE, depth 5000,
and expect COUNT messages (0: expect none). Prints ``READY`` once every topic with COUNT > 0 has
matched a publisher, then records each topic's payloads (bytes) and arrival times
(``time.monotonic``) in arrival order until every count is reached, watches ``--grace`` s more
for extra messages, and writes ``{"topics": {name: [bytes, ...]}, "arrival": {name: [t, ...]}}``
to ``--out`` (pickle). The file is written on timeout too (partial result). Exit 0 when every
topic got exactly its count, 1 on a wrong count, 3 on timeout.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import threading
import time

from ros_child import message_type, reliable_qos


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--topic", action="append", required=True, metavar="NAME=TYPE=COUNT")
    parser.add_argument("--out", required=True)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--grace", type=float, default=0.5)
    parser.add_argument("--depth", type=int, default=5000)
    args = parser.parse_args()
    deadline = time.monotonic() + args.timeout

    import rclpy

    qos = reliable_qos(args.depth)
    expected: dict[str, int] = {}
    types: dict[str, type] = {}
    for spec in args.topic:
        name, msgtype, count = spec.rsplit("=", 2)
        types[name] = message_type(msgtype)
        expected[name] = int(count)
    payloads: dict[str, list[bytes]] = {name: [] for name in expected}
    arrival: dict[str, list[float]] = {name: [] for name in expected}

    def callback(name: str):
        def record(data: bytes) -> None:
            arrival[name].append(time.monotonic())
            payloads[name].append(bytes(data))

        return record

    def write() -> None:
        with open(args.out, "wb") as f:
            pickle.dump({"topics": payloads, "arrival": arrival}, f)

    rclpy.init()
    node = rclpy.create_node("raw_recorder")
    try:
        subs = {
            name: node.create_subscription(types[name], name, callback(name), qos, raw=True)
            for name in expected
        }
        while any(subs[n].get_publisher_count() < 1 for n in expected if expected[n] > 0):
            if time.monotonic() > deadline:
                print("TIMEOUT waiting for publishers", flush=True)
                write()
                return 3
            rclpy.spin_once(node, timeout_sec=0.05)
        print("READY", flush=True)

        while any(len(payloads[n]) < expected[n] for n in expected):
            if time.monotonic() > deadline:
                got = {n: len(p) for n, p in payloads.items()}
                print(f"TIMEOUT with {got} of {expected}", flush=True)
                write()
                return 3
            rclpy.spin_once(node, timeout_sec=0.05)
        grace_end = time.monotonic() + args.grace
        while time.monotonic() < grace_end:
            rclpy.spin_once(node, timeout_sec=0.05)

        write()
        got = {n: len(p) for n, p in payloads.items()}
        print(f"RECEIVED {got}", flush=True)
        if got != expected:
            print(f"WRONG COUNT {got} != {expected}", flush=True)
            return 1
        print("OK", flush=True)
        return 0
    finally:
        # The result is written and printed; a DDS teardown that hangs (seen once in CI on a
        # loaded machine, with the publisher still draining) must not fail the test: give it
        # a few seconds in a daemon thread, then exit anyway.
        def teardown() -> None:
            node.destroy_node()
            rclpy.try_shutdown()

        done = threading.Thread(target=teardown, daemon=True)
        done.start()
        done.join(timeout=5.0)


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)
