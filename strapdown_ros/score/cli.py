"""``strapdown-sim score BAG --topic TOPIC``: the arguments and the command (docs/score.md)."""

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
    try:
        score = score_bag(args.bag, args.topic, estimate_bag=args.estimate_bag,
                          scenario=scenario, truth_topic=args.truth_topic, frame=args.frame,
                          lever_arm=args.lever_arm, mounting_rph_deg=args.mounting_rph)
    except ScoreError as exc:
        print(f"strapdown-sim score: {exc}", file=sys.stderr)
        return 1
    out = Path(args.out) if args.out else Path(args.bag) / "score"
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
