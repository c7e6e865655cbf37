"""Command line entry point ``strapdown-sim`` (SPEC §6).

Subcommands:

* ``generate SCENARIO --out DIR`` — every stream of the scenario, offline, into a rosbag2 dir;
* ``validate SCENARIO`` — check a scenario file (and its overrides) without computing anything;
* ``check DIR`` — re-verify the SPEC §3 exactness rule on a bag read back from disk;
* ``run`` and ``report`` — planned (live pipeline, report of a bag).

Every command that takes a scenario takes ``--set dotted.key=value`` (value parsed as YAML,
repeatable) and ``--duration S``. Exit status: 0 success, 1 failure while running, 2 invalid
input (scenario, arguments, existing output).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from strapdown_ros.scenario import ScenarioError, load_scenario


def _add_scenario_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file (SPEC §5, docs/scenarios.md)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, value parsed as YAML (repeatable), "
        "e.g. --set variation.lever_arm_m=[1,0,0]",
    )
    parser.add_argument(
        "--duration", type=float, default=None, metavar="S", help="override duration_s"
    )


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
    _add_scenario_args(gen)
    gen.add_argument("--out", required=True, help="output bag directory")
    gen.add_argument(
        "--storage",
        choices=("mcap", "sqlite3"),
        default=None,
        help="rosbag2 storage format (default: the scenario's recording.storage, else mcap)",
    )
    gen.add_argument("--force", action="store_true", help="overwrite an existing output directory")
    gen.add_argument("--quiet", action="store_true", help="no progress bar and no summary")

    val = sub.add_parser("validate", help="validate a scenario file without computing anything")
    _add_scenario_args(val)

    chk = sub.add_parser("check", help="verify the SPEC §3 exactness rule on a bag from disk")
    chk.add_argument("bag", help="bag directory written by generate or run")
    chk.add_argument("--gravity-model", default="j2", help="gravitation model of the streams")

    run = sub.add_parser(
        "run", help="(planned) run the live ROS 2 pipeline as separate processes and record a bag"
    )
    _add_scenario_args(run)
    run.add_argument("--out", required=True, help="output bag directory")

    rep = sub.add_parser("report", help="(planned) summary table and plots of a recorded bag")
    rep.add_argument("bag", help="bag directory")
    return parser


class _ProgressBar:
    """A one-line progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.last = 0.0

    def __call__(self, stage: str, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if done < total and now - self.last < 0.1:
            return
        self.last = now
        frac = done / total if total else 1.0
        bar = "#" * int(30 * frac)
        end = "\n" if done >= total and stage == "writing" else ""
        sys.stderr.write(f"\r{stage:<10} [{bar:<30}] {100 * frac:5.1f}%{end}")
        sys.stderr.flush()


def _generate(args: argparse.Namespace) -> int:
    from strapdown_ros.dataset import generate_dataset

    scenario = load_scenario(args.scenario, args.overrides, args.duration)
    try:
        summary = generate_dataset(
            scenario,
            args.out,
            storage=args.storage,
            force=args.force,
            progress=_ProgressBar(not args.quiet),
        )
    except FileExistsError as exc:
        print(f"strapdown-sim generate: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        print(summary.format())
    return 0 if all(r.within_spec() for r in summary.residuals.values()) else 1


def _validate(args: argparse.Namespace) -> int:
    from strapdown_ros.reference import build_trajectory, natural_duration

    scenario = load_scenario(args.scenario, args.overrides, args.duration)
    trajectory = build_trajectory(scenario)
    natural = natural_duration(scenario, trajectory)
    duration = scenario.duration_s if scenario.duration_s is not None else natural
    print(
        f"{scenario.path}: valid; {scenario.trajectory['kind']} trajectory of {natural:g} s, "
        f"{duration:g} s at {scenario.rate_hz:g} Hz (oversample {scenario.oversample}), "
        f"gravity {scenario.gravity_model}"
    )
    return 0


def _check(args: argparse.Namespace) -> int:
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.core.exactness import stream_residuals
    from strapdown_ros.messages import stream_from_messages

    contents = read_bag(args.bag)
    status = 0
    checked = 0
    for topic, data in contents.topics.items():
        if not topic.endswith("/imu") or data.msgtype != "sensor_msgs/msg/Imu":
            continue
        odom_topic = topic[: -len("imu")] + "odom"
        if odom_topic not in contents.topics:
            continue
        stream = stream_from_messages(
            data.fields, contents.topics[odom_topic].fields, args.gravity_model
        )
        res = stream_residuals(stream)
        ok = res.within_spec()
        status |= 0 if ok else 1
        checked += 1
        print(
            f"{topic} + {odom_topic}: {stream.cycles} cycles, max residual attitude "
            f"{res.max_attitude:.2e} rad, velocity {res.max_velocity:.2e} m/s, position "
            f"{res.max_position:.2e} m: {'ok' if ok else 'DEFECT (SPEC §3)'}"
        )
    if not checked:
        print(f"{args.bag}: no Imu/Odometry topic pair to check", file=sys.stderr)
        return 1
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``strapdown-sim``; return the process exit status."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == "generate":
            return _generate(args)
        if args.command == "validate":
            return _validate(args)
        if args.command == "check":
            return _check(args)
    except ScenarioError as exc:
        print(f"strapdown-sim {args.command}: invalid scenario: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # the bag reader and writer raise with the path and the problem
        name = type(exc).__name__
        if name in {"BagReadError", "BagWriteError"}:
            print(f"strapdown-sim {args.command}: {exc}", file=sys.stderr)
            return 1
        raise
    print(f"strapdown-sim {args.command}: not implemented yet", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
