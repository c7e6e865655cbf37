"""Command line entry point ``strapdown-sim`` (docs/interface.md §6).

Subcommands:

* ``generate SCENARIO --out DIR`` — every stream of the scenario, offline, into a rosbag2 dir;
* ``validate SCENARIO`` — check a scenario file (and its overrides) without computing anything;
* ``check DIR`` — re-verify the docs/interface.md §3 exactness rule on a bag read back from disk;
* ``run SCENARIO --out DIR`` — the live pipeline (nodes as processes) recorded into a bag;
* ``replay DIR --into navigator --out OUT`` — a bag's IMU/truth into a live navigator_node;
* ``bag repair DIR`` / ``bag info DIR`` — repair an interrupted recording; summarize a bag;
* ``score DIR --topic TOPIC`` — score a navigation estimate against the bag's truth;
* ``sweep-orientation SCENARIO --azimuth-deg ... --tilt-deg ... --out DIR`` — initial attitude
  errors against Young 1980's nonlinear error equations (docs/error_analysis.md);

Every command that takes a scenario takes ``--set dotted.key=value`` (value parsed as YAML,
repeatable) and ``--duration S``. Exit status: 0 success, 1 failure while running, 2 invalid
input (scenario, arguments, existing output).
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
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


def _add_recording_args(parser: argparse.ArgumentParser) -> None:
    """What the bag gets (generate, run): MCAP chunk compression and the topic selection, as
    ``ros2 bag record`` takes them; each sets its ``recording`` key (docs/recording.md)."""
    parser.add_argument(
        "--compression", choices=("none", "zstd", "lz4"), default=None,
        help="MCAP chunk compression (sets recording.compression; default: the scenario's, "
        "else none)",
    )  # fmt: skip
    parser.add_argument(
        "--topics", nargs="+", default=[], metavar="TOPIC",
        help="write only these topics (with --regex: these and the matching ones; sets "
        "recording.include)",
    )  # fmt: skip
    _add_repeatable(
        parser, "--regex", "RE", "write only the topics whose whole name matches RE "
        "(repeatable; sets recording.include)", dest="regex",
    )  # fmt: skip
    parser.add_argument(
        "--exclude-topics", nargs="+", default=[], metavar="TOPIC",
        help="do not write these topics (sets recording.exclude)",
    )  # fmt: skip
    _add_repeatable(
        parser, "--exclude-regex", "RE", "do not write the topics whose whole name matches RE "
        "(repeatable; sets recording.exclude)", dest="exclude_regex",
    )  # fmt: skip


def _recording_overrides(args: argparse.Namespace) -> list[str]:
    """``--set`` overrides of ``recording`` from :func:`_add_recording_args`' options (after
    the user's own ``--set``: the options win)."""
    import json

    from strapdown_ros.bag.selection import name_pattern

    out = []
    if args.compression is not None:
        out.append(f"recording.compression={args.compression}")
    include = [name_pattern(t) for t in args.topics] + list(args.regex)
    exclude = [name_pattern(t) for t in args.exclude_topics] + list(args.exclude_regex)
    if include:
        out.append(f"recording.include={json.dumps(include)}")
    if exclude:
        out.append(f"recording.exclude={json.dumps(exclude)}")
    return out


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
    _add_recording_args(gen)
    gen.add_argument("--force", action="store_true", help="overwrite an existing output directory")
    gen.add_argument("--quiet", action="store_true", help="no progress bar and no summary")

    val = sub.add_parser("validate", help="validate a scenario file without computing anything")
    _add_scenario_args(val)

    chk = sub.add_parser(
        "check", help="verify the docs/interface.md §3 exactness rule on a bag from disk"
    )
    chk.add_argument("bag", help="bag directory written by generate or run")
    chk.add_argument(
        "--gravity-model", choices=("j2", "spherical"), default=None,
        help="gravitation model to verify with (default: the one in the bag's metadata, "
        "else j2)",
    )  # fmt: skip

    run = sub.add_parser(
        "run", help="run the live ROS 2 pipeline as separate processes and record a bag"
    )
    _add_scenario_args(run)
    run.add_argument("--out", required=True, help="output bag directory")
    run.add_argument("--storage", choices=("mcap", "sqlite3"), default=None)
    _add_recording_args(run)
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
        "--publish-period", type=float, default=0.0, metavar="S",
        help="the trajectory node publishes in groups of S s of data (never early, at most S "
        "late; fewer wake-ups per message); default 0: every message at its own time",
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
    rep.add_argument(
        "--gravity-model", choices=("j2", "spherical"), default=None,
        help="gravitation model of the re-check (default: the one in the bag's metadata, "
        "else j2)",
    )  # fmt: skip
    rep.add_argument(
        "--no-free-inertial",
        action="store_true",
        help="skip the free-inertial navigator the report runs on each measured IMU",
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
    cmp_.add_argument(
        "--dashboard", default="127.0.0.1:0", metavar="HOST:PORT",
        help="the local cluster's Dask dashboard (with bokeh installed; default 127.0.0.1:0, "
        "loopback only; e.g. 0.0.0.0:8787 to expose it)",
    )  # fmt: skip
    cmp_.add_argument(
        "--tls-ca-file", default=None, metavar="PEM",
        help="with a tls:// --scheduler: the CA certificate of the cluster (Dask TLS security; "
        "default: distributed.comm.tls in Dask's configuration)",
    )  # fmt: skip
    cmp_.add_argument("--tls-cert", default=None, metavar="PEM",
                      help="with --tls-ca-file: this client's certificate")  # fmt: skip
    cmp_.add_argument("--tls-key", default=None, metavar="PEM",
                      help="with --tls-cert: its key (default: inside --tls-cert)")  # fmt: skip
    bag_info.add_argument("bag", help="bag directory")
    from strapdown_ros.score.cli import add_parser as add_score_parser

    add_score_parser(sub)
    swp = sub.add_parser(
        "sweep-orientation",
        help="initial attitude errors: navigator vs Young 1980 eq. (51) vs the linear model",
    )
    _add_scenario_args(swp)
    swp.add_argument("--azimuth-deg", type=float, nargs="+", required=True, metavar="DEG")
    swp.add_argument("--tilt-deg", type=float, nargs="+", default=[0.0], metavar="DEG",
                     help="roll and pitch offsets (deg), default 0")  # fmt: skip
    swp.add_argument("--navigator", choices=("damped", "exact", "scenario"), default="damped",
                     help="damped: paper mode + vertical damping (default); exact: undamped "
                     "exact mode; scenario: the scenario's navigator section")  # fmt: skip
    swp.add_argument("--out", required=True, help="output directory (sweep.json, plots)")
    swp.add_argument("--keep-bags", action="store_true", help="keep each case's bag")
    swp.add_argument("--no-plots", action="store_true", help="only sweep.json and the series")
    return parser


def _sweep_orientation(args: argparse.Namespace) -> int:
    from strapdown_ros.analysis.orientation_sweep import format_table, sweep_orientation
    from strapdown_ros.analysis.sweep_plots import plot_sweep

    table = sweep_orientation(
        args.scenario, args.azimuth_deg, args.tilt_deg, args.out, duration_s=args.duration,
        overrides=args.overrides, setup=args.navigator, keep_bags=args.keep_bags,
        progress=lambda line: print(line, file=sys.stderr, flush=True),
        command="strapdown-sim " + " ".join(sys.argv[1:]),
    )  # fmt: skip
    print(format_table(table))
    if not args.no_plots:
        for path in plot_sweep(args.out):
            print(f"wrote {path}")
    return 0


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

    overrides = [*args.overrides, *_recording_overrides(args)]
    scenario = load_scenario(args.scenario, overrides, args.duration)
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
    """Verify docs/interface.md §3 on every Imu/Odometry pair of a bag, with the gravity model
    the bag was generated with. Exit 0: every verifiable pair within the tolerances; 1: a
    pair out of them (DEFECT); 2: nothing in the bag can be verified (another tool's bag)."""
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.checks import check_settings, check_streams
    from strapdown_ros.checks.foreign import capability_lines
    from strapdown_ros.checks.settings import SettingsError

    contents = read_bag(args.bag)
    try:
        settings = check_settings(contents.custom_data, args.gravity_model)
    except SettingsError as exc:
        print(f"strapdown-sim check: {exc}", file=sys.stderr)
        return 2
    print(f"{args.bag}: {settings.describe()}")
    verdicts = check_streams(contents, settings.gravity_model)
    for v in verdicts:
        if not v.checked:
            print(f"{v.pair}: not checked: {v.reason}")
            continue
        res = v.residuals
        assert res is not None
        hint = "" if settings.from_strapdown else (
            "; the bag has no strapdown_ros metadata: check the gravity model "
            "(--gravity-model) and where the bag comes from"
        )  # fmt: skip
        print(
            f"{v.pair}: {v.cycles} cycles, max residual attitude "
            f"{res.max_attitude:.2e} rad, velocity {res.max_velocity:.2e} m/s, position "
            f"{res.max_position:.2e} m: "
            + ("ok" if v.ok else f"DEFECT (docs/interface.md §3{hint})")
        )
    checked = [v for v in verdicts if v.checked]
    if not checked:
        types = {t: d.msgtype for t, d in contents.topics.items()}
        for line in capability_lines(contents.custom_data, types):
            print(f"  {line}")
        print(
            f"strapdown-sim check: nothing to verify in {args.bag}: "
            + ("no Imu/Odometry pair with the stream layout" if verdicts
               else "no `P/imu` + `P/odom` topic pair"),
            file=sys.stderr,
        )  # fmt: skip
        return 2
    return 0 if all(v.ok for v in checked) else 1


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
        args.scenario, args.out, overrides=[*args.overrides, *_recording_overrides(args)],
        duration_s=args.duration, storage=args.storage, force=args.force,
        rate_factor=0.0 if args.unpaced else args.rate_factor,
        domain_id=args.domain_id, timeout_s=args.timeout,
        flow_control={"auto": None, "on": True, "off": False}[args.flow_control],
        publish_period_s=args.publish_period,
    ))  # fmt: skip


def _replay_problem(bag: str, imu_topic: str, truth_topic: str) -> list[str]:
    """Why ``bag`` cannot feed a navigator on ``imu_topic`` (+ ``truth_topic``), with what the
    bag has; empty when it can. Reads only those topics."""
    from strapdown_ros.bag.reader import check_bag, read_bag
    from strapdown_ros.checks import is_ecef
    from strapdown_ros.checks.foreign import capability_lines
    from strapdown_ros.messages import odometry_state

    info, _ = check_bag(bag)  # BagReadError: reported by the dispatcher
    entries = info.get("topics_with_message_count") or []
    types = {e["topic_metadata"]["name"]: e["topic_metadata"]["type"] for e in entries}
    custom = {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}
    wanted = {imu_topic: "sensor_msgs/msg/Imu"}
    if truth_topic:
        wanted[truth_topic] = "nav_msgs/msg/Odometry"
    problems = []
    for topic, ty in wanted.items():
        if topic not in types:
            problems.append(f"the bag has no topic {topic} ({ty})")
        elif types[topic] != ty:
            problems.append(f"{topic} is a {types[topic]}, not a {ty}")
    if not problems and truth_topic:
        truth = read_bag(bag, [truth_topic]).topics[truth_topic].fields
        if truth is None or not is_ecef(odometry_state(truth).r_e):  # type: ignore[arg-type]
            frame = getattr(truth, "frame_id", "?")
            problems.append(
                f"{truth_topic} (frame {frame!r}) has no ECEF positions: the navigator "
                "initializes from and compares with an ECEF truth (frame `earth`)"
            )
    if not problems:
        return []
    return problems + capability_lines(custom, types)


def _replay(args: argparse.Namespace) -> int:
    """Replay a bag into a live navigator; exit 2 (nothing started) when the bag lacks the
    navigator's input streams."""
    from strapdown_ros.pipeline import replay_into_navigator
    from strapdown_ros.pipeline.replay import _navigator_settings

    _, _, nav = _navigator_settings(args.scenario, args.overrides)
    problems = _replay_problem(args.bag, str(nav.imu_topic), str(nav.truth_topic or ""))
    if problems:
        print(
            f"strapdown-sim replay: {args.bag} cannot feed navigator_node (imu_topic "
            f"{nav.imu_topic}, truth_topic {nav.truth_topic or 'none'}; choose them with "
            "--scenario and its navigator section):\n"
            + "\n".join(f"  {p}" for p in problems),
            file=sys.stderr,
        )
        return 2
    return _live("replay", lambda: replay_into_navigator(
        args.bag, args.out, scenario_path=args.scenario, overrides=args.overrides,
        rate_factor=args.rate_factor, force=args.force, domain_id=args.domain_id,
    ))  # fmt: skip


def _report(args: argparse.Namespace) -> int:
    from strapdown_ros.report import ReportError, write_report

    try:
        result = write_report(
            args.bag, args.out, compare=args.compare, exactness=not args.no_exactness,
            gravity_model=args.gravity_model, free_inertial=not args.no_free_inertial,
        )  # fmt: skip
    except ReportError as exc:
        print(f"strapdown-sim report: {exc}", file=sys.stderr)
        return 1
    print(f"{result.markdown} ({len(result.plots)} plots, {result.elapsed_s:.1f} s)")
    for name, path in result.plots.items():
        print(f"  {name:<20} {path}")
    for name, why in result.omitted.items():
        print(f"  {name:<20} omitted: {why}")
    return 0


def _score(args: argparse.Namespace) -> int:
    from strapdown_ros.score.cli import run

    return run(args)


def _bag(args: argparse.Namespace) -> int:
    from strapdown_ros.bag.reader import bag_info
    from strapdown_ros.bag.repair import BagRepairError, repair_bag

    try:
        if args.bag_command == "repair":
            print(repair_bag(args.bag, force=args.force).format())
        else:
            print(bag_info(args.bag))
            for line in _bag_capabilities(args.bag):
                print(f"  {line}")
    except BagRepairError as exc:
        print(f"strapdown-sim bag {args.bag_command}: {exc}", file=sys.stderr)
        return 1
    return 0


def _bag_capabilities(path: str) -> list[str]:
    """``bag info``'s statement of what check, report and replay do with a bag that reads
    (from its metadata; nothing for a bag that does not read: bag info says why)."""
    from strapdown_ros.bag.reader import BagReadError, check_bag
    from strapdown_ros.checks.foreign import capability_lines, is_foreign

    try:
        info, _ = check_bag(path)
        entries = info.get("topics_with_message_count") or []
        types = {e["topic_metadata"]["name"]: e["topic_metadata"]["type"] for e in entries}
        custom = {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}
    except (BagReadError, KeyError, TypeError, AttributeError):
        return []
    if not is_foreign(custom):
        model = custom.get("gravity_model", "not recorded")
        return [f"strapdown_ros: written by strapdown_ros (scenario {custom.get('scenario', '?')}"
                f", gravity model {model}): check, report and replay apply"]  # fmt: skip
    return ["strapdown_ros:"] + [f"  {line}" for line in capability_lines(custom, types)]


def _campaign(args: argparse.Namespace) -> int:
    from strapdown_ros.campaign import run_campaign

    if args.runs < 1:
        print("strapdown-sim campaign: --runs must be >= 1", file=sys.stderr)
        return 2
    if args.workers is not None and args.workers < 1:
        print("strapdown-sim campaign: --workers must be >= 1", file=sys.stderr)
        return 2
    tls = None
    if args.tls_ca_file or args.tls_cert or args.tls_key:
        if not (args.tls_ca_file and args.tls_cert and args.scheduler):
            print("strapdown-sim campaign: TLS needs --scheduler tls://..., --tls-ca-file and "
                  "--tls-cert (and --tls-key unless the key is inside --tls-cert)",
                  file=sys.stderr)  # fmt: skip
            return 2
        from strapdown_ros.campaign.engine import TlsFiles

        tls = TlsFiles(args.tls_ca_file, args.tls_cert, args.tls_key)
    try:
        result = run_campaign(
            args.scenario, args.out, args.runs, overrides=args.overrides,
            duration_s=args.duration, vary=args.vary, seed=args.seed, bags=args.bags,
            scheduler=args.scheduler, workers=args.workers, dashboard=args.dashboard, tls=tls,
            log=lambda m: print(m, file=sys.stderr),
        )  # fmt: skip
    except (FileExistsError, ValueError) as exc:
        print(f"strapdown-sim campaign: {exc}", file=sys.stderr)
        return 2
    print(result.format())
    return 1 if result.failed else 0


#: Exit status of an interrupted command (128 + SIGINT), as a shell reports Ctrl-C.
EXIT_INTERRUPTED = 130
#: Signals that stop a command like Ctrl-C (``kill``, systemd, docker, launch; a closed
#: terminal). Exit status 128 + the signal's number, as a shell reports it.
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


class Stopped(KeyboardInterrupt):
    """A stop signal (:data:`STOP_SIGNALS`) taken as Ctrl-C: the same clean-up runs (children
    stopped, temporary bags and spools removed)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _stop_on_signals() -> None:
    """SIGTERM and SIGHUP raise :class:`Stopped` in the main thread, once: a second one is
    ignored while the command cleans up (SIGKILL still ends it)."""

    def stop(signum: int, frame: object) -> None:
        for s in STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        raise Stopped(signum)

    for s in STOP_SIGNALS:
        signal.signal(s, stop)


def _describe_output(out: str | None, command: str = "") -> str:
    """What an interrupted command left at ``out``: the bag's message counts, a hint to repair
    it, or that nothing was written (a campaign: its finished runs and how to resume)."""
    if not out:
        return ""
    path = Path(out)
    if command == "campaign":
        return _describe_campaign(path)
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


def _describe_campaign(path: Path) -> str:
    """What an interrupted campaign left in its directory, and how to resume it."""
    if not path.is_dir():
        return f"nothing written at {path}"
    from strapdown_ros.campaign.results import finished_runs

    n = len(finished_runs(path))
    return (
        f"the campaign directory {path} keeps its {n} finished run(s); run the same command "
        "again (same scenario, --set, --vary, --seed and --out) to compute only the missing runs"
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
    exit status 130 (what was written is summarized), SIGTERM and SIGHUP likewise with 143 and
    129. Only an internal bug shows a traceback,
    behind a one-line summary.
    """
    args = build_parser().parse_args(argv)
    from strapdown_ros.requirements_check import MissingDependencyError, exit_if_unsupported

    exit_if_unsupported("strapdown-sim")  # a library older than supported: say so, exit 1
    _stop_on_signals()
    try:
        return _dispatch(args)
    except MissingDependencyError as exc:  # an optional feature's library (campaign, magnetometer)
        print(f"strapdown-sim {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        described = _describe_output(getattr(args, "out", None), args.command)
        how = f"stopped by {exc}" if isinstance(exc, Stopped) else "interrupted"
        print(
            f"strapdown-sim {args.command}: {how}" + (f"; {described}" if described else ""),
            file=sys.stderr,
        )
        return 128 + exc.signum if isinstance(exc, Stopped) else EXIT_INTERRUPTED
    except OSError as exc:
        message = _environment_fault(args.command, exc)
        if args.command == "generate":  # the bag is written atomically (bag/writer.py)
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
        "score": _score,
        "sweep-orientation": _sweep_orientation,
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
