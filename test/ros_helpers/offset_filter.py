"""A dead-simple "filter" of the tests' own (test subprocess): the truth moved by a fixed offset.

Subscribes to ``--input`` (nav_msgs/Odometry, RELIABLE) and republishes every message on
``--output`` as nav_msgs/Odometry with ``--offset DX DY DZ`` (m) added to the position in the
message's own frame (``earth``: ECEF); everything else is copied. Faults for the scorer's live
mode (``--mode``):

* ``ok`` (default): as above, until SIGINT/SIGTERM;
* ``exit-early``: exits with status 3 after its first ``--after`` messages;
* ``silent``: creates the publisher but never publishes;
* ``no-publisher``: subscribes only;
* ``wrong-type``: publishes std_msgs/String on ``--output``.

Prints ``READY`` when its publisher and subscription exist, ``FIRST`` at its first message.
"""

from __future__ import annotations

import argparse
import sys

from ros_child import reliable_qos


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--input", default="/reference/odom")
    parser.add_argument("--output", default="/offset_filter/odom")
    parser.add_argument("--offset", type=float, nargs=3, default=(0.0, 0.0, 0.0))
    parser.add_argument(
        "--mode", default="ok", choices=("ok", "exit-early", "silent", "no-publisher", "wrong-type")
    )
    parser.add_argument("--after", type=int, default=5)
    args = parser.parse_args()

    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.executors import ExternalShutdownException
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node("offset_filter")
    qos = reliable_qos(1000)
    pub = None
    if args.mode == "wrong-type":
        pub = node.create_publisher(String, args.output, qos)
    elif args.mode != "no-publisher":
        pub = node.create_publisher(Odometry, args.output, qos)
    seen = [0]

    def on_odom(msg: Odometry) -> None:
        seen[0] += 1
        if seen[0] == 1:
            print("FIRST", flush=True)
        if args.mode == "exit-early" and seen[0] > args.after:
            raise SystemExit(3)
        if args.mode in ("silent", "no-publisher"):
            return
        if args.mode == "wrong-type":
            pub.publish(String(data="not an estimate"))
            return
        p = msg.pose.pose.position
        p.x, p.y, p.z = p.x + args.offset[0], p.y + args.offset[1], p.z + args.offset[2]
        pub.publish(msg)

    node.create_subscription(Odometry, args.input, on_odom, qos)
    print("READY", flush=True)
    status = 0
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SystemExit as exc:
        status = int(exc.code or 0)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == "__main__":
    sys.exit(main())
