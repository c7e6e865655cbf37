"""Command line entry point ``strapdown-sim`` (see SPEC section 6).

The subcommands are placeholders for now: each prints "not implemented yet" to stderr and
exits with status 2.
"""

from __future__ import annotations

import argparse
import sys


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``strapdown-sim``."""
    parser = argparse.ArgumentParser(
        prog="strapdown-sim",
        description="Exact synthetic strapdown IMU data, variation trajectories and navigation.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    gen = sub.add_parser(
        "generate", help="compute every stream of a scenario offline and write a rosbag2 directory"
    )
    gen.add_argument("scenario", help="scenario YAML file")
    gen.add_argument("--out", required=True, help="output bag directory")
    gen.add_argument(
        "--storage", choices=("mcap", "sqlite3"), default="mcap", help="rosbag2 storage format"
    )
    gen.add_argument("--force", action="store_true", help="overwrite an existing output directory")

    run = sub.add_parser(
        "run", help="run the live ROS 2 pipeline (nodes as separate processes) and record a bag"
    )
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--out", required=True, help="output bag directory")
    run.add_argument(
        "--storage", choices=("mcap", "sqlite3"), default="mcap", help="rosbag2 storage format"
    )
    run.add_argument("--force", action="store_true", help="overwrite an existing output directory")

    rep = sub.add_parser("report", help="summary table and plots of a recorded bag")
    rep.add_argument("bag", help="bag directory")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``strapdown-sim``; return the process exit status."""
    args = build_parser().parse_args(argv)
    print(f"strapdown-sim {args.command}: not implemented yet", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
