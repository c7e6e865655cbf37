"""``strapdown-sim score BAG --topic TOPIC``: the arguments and the command (docs/score.md).

With ``--node CMD`` (live mode, :mod:`strapdown_ros.score.live`) the ``--input`` topics of BAG
are first played into the user's node and what it publishes on TOPIC is recorded, then scored.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["add_parser", "run"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """The ``score`` subcommand's parser."""
    p = sub.add_parser(
        "score", help="score a navigation estimate in a bag against the bag's exact truth"
    )
    p.add_argument("bag", help="bag with the truth (written by generate or run)")
    p.add_argument("--topic", required=True,
                   help="estimate topic: nav_msgs/Odometry, sensor_msgs/NavSatFix or "
                   "geometry_msgs/PoseWithCovarianceStamped")  # fmt: skip
    p.add_argument("--estimate-bag", default=None,
                   help="bag holding the estimate topic (default: BAG)")  # fmt: skip
    p.add_argument("--scenario", default=None,
                   help="the scenario BAG was generated from: exact truth between samples "
                   "(without it: cubic Hermite)")  # fmt: skip
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="scenario override used for BAG (repeatable)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="duration_s override used for BAG")
    p.add_argument("--truth-topic", default="/reference/odom", help="truth Odometry topic")
    p.add_argument("--frame", default=None,
                   help="the estimate's frame on /tf_static (default: its child_frame_id)")
    p.add_argument("--lever-arm", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="the estimate's point relative to the reference IMU, FRD m")
    p.add_argument("--mounting-rph", type=float, nargs=3, default=None,
                   metavar=("ROLL", "PITCH", "YAW"),
                   help="the estimate's axes relative to the reference IMU's, deg")
    p.add_argument("--out", default=None, help="output directory (default: BAG/score)")
    live = p.add_argument_group(
        "live (hardware in the loop)",
        "play BAG into your node, record what it publishes on --topic, then score it",
    )
    live.add_argument("--node", default=None, metavar="COMMAND",
                      help="the command that runs your node (split like a shell command line; "
                      "it must create its --topic publisher at start-up)")  # fmt: skip
    live.add_argument("--input", action="append", default=[], metavar="TOPIC", dest="inputs",
                      help="topic of BAG your node subscribes to: played (repeatable)")
    live.add_argument("--rate-factor", type=float, default=1.0,
                      help="play speed over real time (default 1)")  # fmt: skip
    live.add_argument("--record-to", default=None, metavar="DIR",
                      help="bag the node's output is recorded into (default: OUT/estimate)")
    live.add_argument("--force", action="store_true", help="replace an existing --record-to bag")
    live.add_argument("--domain-id", type=int, default=None,
                      help="ROS_DOMAIN_ID of the processes (default: a private one from the pid)")
    live.add_argument("--startup-timeout", type=float, default=60.0, metavar="S",
                      help="seconds the node may take to publish and subscribe (default 60)")
    live.add_argument("--linger", type=float, default=2.0, metavar="S",
                      help="seconds the node keeps running after the play (default 2)")


def run(args: argparse.Namespace) -> int:
    """Score, write the page, print where; 1 on bad input (the message names it)."""
    from pathlib import Path

    from strapdown_ros.config import load_scenario
    from strapdown_ros.score.estimate import ScoreError
    from strapdown_ros.score.page import write_page
    from strapdown_ros.score.scorer import score_bag

    scenario = None
    if args.scenario is not None:
        scenario = load_scenario(args.scenario, args.overrides, args.duration)
    out = Path(args.out) if args.out else Path(args.bag) / "score"
    if args.node is not None:
        status = _record_live(args, out)
        if status:
            return status
    elif args.inputs:
        print("strapdown-sim score: --input needs --node (live mode)", file=sys.stderr)
        return 2
    try:
        score = score_bag(args.bag, args.topic, estimate_bag=args.estimate_bag,
                          scenario=scenario, truth_topic=args.truth_topic, frame=args.frame,
                          lever_arm=args.lever_arm, mounting_rph_deg=args.mounting_rph)
    except ScoreError as exc:
        print(f"strapdown-sim score: {exc}", file=sys.stderr)
        return 1
    files = write_page(score, out)
    s = score.summary
    pos = s["position_error_m"]["horizontal"]
    print(f"{args.topic}: {s['samples']} estimates, horizontal error RMS {pos['rms']:.3e} m, "
          f"max {pos['max_abs']:.3e} m")  # fmt: skip
    off = s["time_offset"]
    if off["offset_s"] is not None:
        print(f"time offset {off['offset_s'] * 1e3:.6f} ms ± {off['sigma_s'] * 1e3:.1e} ms")
    for name, path in files.items():
        print(f"  {name:<10} {path}")
    return 0


def _record_live(args: argparse.Namespace, out) -> int:
    """Play BAG into ``--node`` and record its ``--topic`` (sets ``args.estimate_bag``); 0 when
    recorded, else the exit status after the one-line reason and the end of the log."""
    from pathlib import Path

    from strapdown_ros.score.live import LiveInputError, LiveScoreError, record_live_estimate

    if args.estimate_bag is not None:
        print("strapdown-sim score: --estimate-bag and --node exclude each other (live mode "
              "records the estimate into --record-to)", file=sys.stderr)  # fmt: skip
        return 2
    record_to = Path(args.record_to) if args.record_to else out / "estimate"
    try:
        recording = record_live_estimate(
            args.bag, args.node, args.topic, record_to, inputs=args.inputs,
            rate_factor=args.rate_factor, force=args.force, domain_id=args.domain_id,
            startup_timeout_s=args.startup_timeout, linger_s=args.linger,
        )  # fmt: skip
    except FileExistsError as exc:
        print(f"strapdown-sim score: {exc}", file=sys.stderr)
        return 2
    except LiveScoreError as exc:
        tail = "\n".join(exc.log.splitlines()[-30:])
        print(f"strapdown-sim score: {exc}" + (f"\n--- log (end) ---\n{tail}" if tail else ""),
              file=sys.stderr)  # fmt: skip
        return 2 if isinstance(exc, LiveInputError) else 1
    except KeyboardInterrupt:
        args.out = str(record_to)  # what main() describes: the recording, closed by the recorder
        raise
    print(
        f"{args.topic}: {recording.count} messages ({recording.msgtype}) recorded live into "
        f"{recording.out} in {recording.elapsed_s:.1f} s; logs in {recording.log_dir}"
    )
    args.estimate_bag = str(recording.out)
    return 0
