"""Command line entry point ``strapdown-sim`` (docs/interface.md §6).

Subcommands:

* ``generate SCENARIO --out DIR`` — every stream of the scenario, offline, into a rosbag2 dir;
* ``validate SCENARIO`` — check a scenario file (and its overrides) without computing anything;
* ``check DIR`` — re-verify the docs/interface.md §3 exactness rule on a bag read back from disk;
* ``run SCENARIO --out DIR`` — the live pipeline (nodes as processes) recorded into a bag;
* ``replay DIR --into navigator --out OUT`` — a bag's IMU/truth into a live navigator_node;
* ``bag repair DIR`` / ``bag info DIR`` — repair an interrupted recording; summarize a bag;

Every command that takes a scenario takes ``--set dotted.key=value`` (value parsed as YAML,
repeatable) and ``--duration S``. Exit status: 0 success, 1 failure while running, 2 invalid
input (scenario, arguments, existing output).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any


def _add_repeatable(
    parser: argparse.ArgumentParser, flag: str, metavar: str, text: str | None = None, **kw: Any
) -> None:
    """An option that may be given several times (help ``text``); its values collect in a list
    (default [])."""
    parser.add_argument(flag, action="append", default=[], metavar=metavar, help=text, **kw)


def _add_scenario_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario YAML file (interface.md §5, docs/scenarios.md)")
    _add_repeatable(
        parser, "--set", "KEY=VALUE",
        "override a scenario key, value parsed as YAML (repeatable), "
        "e.g. --set variation.lever_arm_m=[1,0,0]",
        dest="overrides",
    )  # fmt: skip
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

    chk = sub.add_parser(
        "check", help="verify the docs/interface.md §3 exactness rule on a bag from disk"
    )
    chk.add_argument("bag", help="bag directory written by generate or run")
    chk.add_argument("--gravity-model", default="j2", help="gravitation model of the streams")

    run = sub.add_parser(
        "run", help="run the live ROS 2 pipeline as separate processes and record a bag"
    )
    _add_scenario_args(run)
    run.add_argument("--out", required=True, help="output bag directory")
    run.add_argument("--storage", choices=("mcap", "sqlite3"), default=None)
    run.add_argument("--force", action="store_true", help="overwrite an existing output")
    run.add_argument(
        "--rate-factor", type=float, default=1.0,
        help="speed over real time (default 1: wall-clock pace, loss reported); above 1 the "
        "run is flow-controlled (lossless, at most this fast)",
    )  # fmt: skip
    run.add_argument(
        "--unpaced", action="store_true",
        help="as fast as the slowest node allows (flow-controlled, lossless); prints the "
        "throughput reached",
    )  # fmt: skip
    run.add_argument(
        "--flow-control", choices=("auto", "on", "off"), default="auto",
        help="auto (default): on with --unpaced or --rate-factor > 1, off in real time",
    )  # fmt: skip
    run.add_argument(
        "--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: private, from pid)"
    )
    run.add_argument("--timeout", type=float, default=None, metavar="S", help="give up after S s")

    rpl = sub.add_parser(
        "replay",
        help="play a bag's navigator input into a live navigator_node and record its output",
    )
    rpl.add_argument("bag", help="bag directory (e.g. written by generate or run)")
    rpl.add_argument(
        "--into", choices=("navigator",), default="navigator", help="node to replay into"
    )
    rpl.add_argument("--out", required=True, help="output bag directory (navigator topics)")
    rpl.add_argument("--scenario", default=None, help="scenario whose navigator section to use")
    _add_repeatable(rpl, "--set", "KEY=VALUE", dest="overrides")
    rpl.add_argument("--rate-factor", type=float, default=1.0, help="speed over real time")
    rpl.add_argument("--force", action="store_true", help="overwrite an existing output")
    rpl.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID")

    rep = sub.add_parser(
        "report", help="write report.md and PNG plots of a recorded bag into DIR/report/"
    )
    rep.add_argument("bag", help="bag directory written by generate or run")
    rep.add_argument("--out", default=None, help="output directory (default: BAG/report)")
    _add_repeatable(
        rep, "--compare", "OTHER_BAG",
        "another bag of the same reference whose variation is compared with this one "
        "(e.g. Method 1 vs Method 2; repeatable)",
    )  # fmt: skip
    rep.add_argument(
        "--no-exactness",
        action="store_true",
        help="skip the docs/interface.md §3 re-check of the streams",
    )

    bag = sub.add_parser("bag", help="bag utilities: repair an interrupted recording, info")
    bag_sub = bag.add_subparsers(dest="bag_command", metavar="BAG_COMMAND", required=True)
    bag_repair = bag_sub.add_parser(
        "repair", help="rebuild metadata.yaml (and the mcap summary) of an interrupted recording"
    )
    bag_repair.add_argument("bag", help="bag directory")
    bag_repair.add_argument(
        "--force", action="store_true", help="rebuild the metadata even if the bag reads fine"
    )
    bag_info = bag_sub.add_parser("info", help="topics, types, message counts and duration")

    cmp_ = sub.add_parser(
        "campaign",
        help="Monte Carlo runs of a scenario (IMU error realizations, drawn values) on Dask",
    )
    _add_scenario_args(cmp_)
    cmp_.add_argument("--runs", type=int, required=True, metavar="N", help="number of runs")
    cmp_.add_argument("--out", required=True, help="campaign directory (reused to resume)")
    _add_repeatable(
        cmp_, "--vary", "KEY=SPEC",
        "draw a scenario value per run: KEY=normal(MEAN,SIGMA) or KEY=uniform(LOW,HIGH) "
        "(lists for vector keys; repeatable; docs/campaigns.md)",
    )  # fmt: skip
    cmp_.add_argument("--seed", type=int, default=0, help="campaign seed (default 0)")
    cmp_.add_argument("--bags", action="store_true", help="also write each run's full bag")
    cmp_.add_argument(
        "--scheduler", default=None, metavar="ADDRESS",
        help="an existing Dask scheduler, e.g. tcp://10.0.0.1:8786 (default: a local cluster)",
    )  # fmt: skip
    cmp_.add_argument(
        "--workers", type=int, default=None, metavar="K",
        help="worker processes of the local cluster (default: one per core)",
    )  # fmt: skip
    bag_info.add_argument("bag", help="bag directory")
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
    from strapdown_ros.config import load_scenario
    from strapdown_ros.generate import generate_dataset

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
    from strapdown_ros.config import load_scenario
    from strapdown_ros.plan import resolve_plan

    scenario = load_scenario(args.scenario, args.overrides, args.duration)
    plan = resolve_plan(scenario, topics=False)  # the topic plans cannot reject a scenario
    plan.trajectory  # noqa: B018 - built: validates the trajectory's parameters
    print(
        f"{scenario.path}: valid; {scenario.trajectory.kind} trajectory of "
        f"{plan.natural_duration_s:g} s, {plan.duration_s:g} s at {scenario.rate_hz:g} Hz "
        f"(oversample {scenario.oversample}), "
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
            f"{res.max_position:.2e} m: {'ok' if ok else 'DEFECT (docs/interface.md §3)'}"
        )
    if not checked:
        print(f"{args.bag}: no Imu/Odometry topic pair to check", file=sys.stderr)
        return 1
    return status


def _live(command: str, call: Callable[[], Any]) -> int:
    """Run a live command (run, replay): ``call()`` and print its result; the exit status is 0
    when the result is ``ok``, 1 when not or when a node process failed (its log is printed), 2
    when the output exists."""
    from strapdown_ros.pipeline import PipelineError

    try:
        result = call()
    except FileExistsError as exc:
        print(f"strapdown-sim {command}: {exc}", file=sys.stderr)
        return 2
    except PipelineError as exc:
        print(f"strapdown-sim {command}: {exc}\n--- log ---\n{exc.log}", file=sys.stderr)
        return 1
    print(result.format())
    return 0 if result.ok else 1


def _run(args: argparse.Namespace) -> int:
    from strapdown_ros.pipeline import run_pipeline

    return _live("run", lambda: run_pipeline(
        args.scenario, args.out, overrides=args.overrides, duration_s=args.duration,
        storage=args.storage, force=args.force,
        rate_factor=0.0 if args.unpaced else args.rate_factor,
        domain_id=args.domain_id, timeout_s=args.timeout,
        flow_control={"auto": None, "on": True, "off": False}[args.flow_control],
    ))  # fmt: skip


def _replay(args: argparse.Namespace) -> int:
    from strapdown_ros.pipeline import replay_into_navigator

    return _live("replay", lambda: replay_into_navigator(
        args.bag, args.out, scenario_path=args.scenario, overrides=args.overrides,
        rate_factor=args.rate_factor, force=args.force, domain_id=args.domain_id,
    ))  # fmt: skip


def _report(args: argparse.Namespace) -> int:
    from strapdown_ros.report import ReportError, write_report

    try:
        result = write_report(
            args.bag, args.out, compare=args.compare, exactness=not args.no_exactness
        )
    except ReportError as exc:
        print(f"strapdown-sim report: {exc}", file=sys.stderr)
        return 1
    print(f"{result.markdown} ({len(result.plots)} plots, {result.elapsed_s:.1f} s)")
    for name, path in result.plots.items():
        print(f"  {name:<20} {path}")
    for name, why in result.omitted.items():
        print(f"  {name:<20} omitted: {why}")
    return 0


def _bag(args: argparse.Namespace) -> int:
    from strapdown_ros.bag.reader import bag_info
    from strapdown_ros.bag.repair import BagRepairError, repair_bag

    try:
        if args.bag_command == "repair":
            print(repair_bag(args.bag, force=args.force).format())
        else:
            print(bag_info(args.bag))
    except BagRepairError as exc:
        print(f"strapdown-sim bag {args.bag_command}: {exc}", file=sys.stderr)
        return 1
    return 0


def _campaign(args: argparse.Namespace) -> int:
    from strapdown_ros.campaign import run_campaign

    if args.runs < 1:
        print("strapdown-sim campaign: --runs must be >= 1", file=sys.stderr)
        return 2
    if args.workers is not None and args.workers < 1:
        print("strapdown-sim campaign: --workers must be >= 1", file=sys.stderr)
        return 2
    try:
        result = run_campaign(
            args.scenario, args.out, args.runs, overrides=args.overrides,
            duration_s=args.duration, vary=args.vary, seed=args.seed, bags=args.bags,
            scheduler=args.scheduler, workers=args.workers,
            log=lambda m: print(m, file=sys.stderr),
        )  # fmt: skip
    except FileExistsError as exc:
        print(f"strapdown-sim campaign: {exc}", file=sys.stderr)
        return 2
    print(result.format())
    return 1 if result.failed else 0


#: Exit status of an interrupted command (128 + SIGINT), as a shell reports Ctrl-C.
EXIT_INTERRUPTED = 130


def _describe_output(out: str | None) -> str:
    """What an interrupted command left at ``out``: the bag's message counts, a hint to repair
    it, or that nothing was written."""
    from pathlib import Path

    if not out:
        return ""
    path = Path(out)
    if not path.exists():
        return f"nothing written at {path}"
    try:
        from strapdown_ros.bag.reader import bag_info

        return f"the bag at {path} is closed and readable:\n{bag_info(path)}"
    except Exception as exc:  # any reading problem: name it and the repair command
        return (
            f"{path} is left as it was when interrupted ({exc}); "
            f"run 'strapdown-sim bag repair {path}' to make it readable"
        )


def _environment_fault(command: str, exc: OSError) -> str:
    """One line naming a file-system fault (full disk, read-only, permissions, missing)."""
    import errno

    where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
    hints = {
        errno.ENOSPC: "the disk is full",
        errno.EROFS: "the destination is on a read-only file system",
        errno.EACCES: "permission denied",
        errno.EDQUOT: "disk quota exceeded",
    }
    hint = hints.get(exc.errno or 0, exc.strerror or str(exc))
    return f"strapdown-sim {command}: {hint}{where} ({exc.strerror or exc})"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``strapdown-sim``; return the process exit status.

    User errors and environment faults (invalid scenario, unreadable bag, full or read-only
    disk) are reported in one line, exit status 1 or 2; Ctrl-C stops the command cleanly with
    exit status 130 (what was written is summarized). Only an internal bug shows a traceback,
    behind a one-line summary.
    """
    args = build_parser().parse_args(argv)
    from strapdown_ros.requirements_check import MissingDependencyError, exit_if_unsupported

    exit_if_unsupported("strapdown-sim")  # a library older than supported: say so, exit 1
    try:
        return _dispatch(args)
    except MissingDependencyError as exc:  # an optional feature's library (campaign, magnetometer)
        print(f"strapdown-sim {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        described = _describe_output(getattr(args, "out", None))
        print(
            f"strapdown-sim {args.command}: interrupted"
            + (f"; {described}" if described else ""),
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    except OSError as exc:
        message = _environment_fault(args.command, exc)
        if args.command == "generate":  # the bag is written atomically (bag/writer.py)
            from pathlib import Path

            left = "nothing was written" if not Path(args.out).exists() else "it was not changed"
            message += f"; {left} at {args.out}"
        print(message, file=sys.stderr)
        return 1
    except Exception as exc:
        import traceback

        print(
            f"strapdown-sim {args.command}: internal error ({type(exc).__name__}: {exc}); "
            "this is a bug, please report it with the traceback below",
            file=sys.stderr,
        )
        traceback.print_exc()
        return 1


def _dispatch(args: argparse.Namespace) -> int:
    """Run the subcommand of ``args``; user errors become a message and an exit status."""
    # Imported here, not at module level: a Ctrl-C while the heavy modules load is then
    # handled by main() like any other (no traceback).
    from strapdown_ros.config import ScenarioError

    commands = {
        "generate": _generate, "validate": _validate, "run": _run, "replay": _replay,
        "check": _check, "report": _report, "campaign": _campaign, "bag": _bag,
    }  # fmt: skip
    try:
        if args.command in commands:
            return commands[args.command](args)
    except ScenarioError as exc:
        print(f"strapdown-sim {args.command}: invalid scenario: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # the bag reader and writer raise with the path and the problem
        name = type(exc).__name__
        if name in {"BagReadError", "BagWriteError", "BagRepairError", "ReportError",
                    "StreamError", "PipelineError"}:  # fmt: skip
            print(f"strapdown-sim {args.command}: {exc}", file=sys.stderr)
            return 1
        raise
    print(f"strapdown-sim {args.command}: not implemented yet", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
