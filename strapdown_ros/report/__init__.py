"""``strapdown-sim report DIR``: a markdown summary and PNG plots of a recorded bag.

:func:`write_report` reads the bag back from disk (any bag this project writes: reference only,
with a variation, with measured IMU data, with navigator streams), derives what it can
(:mod:`strapdown_ros.report.data`), draws the plots that apply (:mod:`strapdown_ros.report.plots`)
and writes ``report.md`` (:mod:`strapdown_ros.report.summary`) into ``DIR/report/``. Plots whose
topics are missing are omitted, and ``report.md`` says which and why. No ROS runtime needed.
See ``docs/report.md``.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import yaml

from strapdown_ros.bag.reader import BagContents
from strapdown_ros.report.aided import AidedResult
from strapdown_ros.report.data import (
    BagData,
    Comparison,
    ReportError,
    StreamData,
    compare_streams,
    load_bag,
)
from strapdown_ros.report.free_inertial import ErrorGrowth, FreeInertial
from strapdown_ros.report.solutions import Solution
from strapdown_ros.report.transfer import TransferResult

__all__ = ["PLOT_FILES", "ReportError", "ReportResult", "method_of", "write_report"]

T = TypeVar("T")

#: Plot files the report can write (``*`` : a suffix for a second navigator / measured IMU /
#: comparison). Old files matching these names are removed before a report is written.
PLOT_FILES = (
    "trajectory.png",
    "attitude_velocity.png",
    "imu.png",
    "exactness.png",
    "navigation_errors*.png",
    "method_comparison*.png",
    "allan*.png",
    "aiding.png",
    "free_inertial*.png",
    "aided_errors*.png",
    "aided_consistency*.png",
    "transfer_errors*.png",
    "transfer_consistency*.png",
    "transfer_mounting*.png",
)


@dataclass
class ReportResult:
    """What :func:`write_report` wrote."""

    out_dir: Path
    markdown: Path
    plots: dict[str, Path] = field(default_factory=dict)  #: name -> PNG path
    omitted: dict[str, str] = field(default_factory=dict)  #: plot -> reason
    elapsed_s: float = 0.0
    #: Free-inertial solutions the report computed (on each measured IMU, and on an ideal twin
    #: when the bag has no navigator on it).
    free_inertial: list[FreeInertial] = field(default_factory=list)
    free_inertial_s: float = 0.0  #: wall time of those runs (decoding the IMU and truth included)
    aided: dict[str, AidedResult] = field(default_factory=dict)  #: prefix -> recomputed errors
    #: prefix -> a transfer filter's recomputed slave errors and mounting error
    transfer: dict[str, TransferResult] = field(default_factory=dict)


def _slug(prefix: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", prefix).strip("_") or "root"


def method_of(bag: BagData, prefix: str = "/variation") -> int | None:
    """The variation method recorded in the bag's ``custom_data``, if the writer stored it.

    Looks for ``variation.method`` / ``variation_method`` (or ``<prefix>.method``) keys, or a
    scenario stored as YAML text with a ``variation.method`` entry.
    """
    cd = bag.contents.custom_data
    for key in (f"{prefix.strip('/')}.method", "variation.method", "variation_method"):
        if key in cd and cd[key].strip() in {"1", "2"}:
            return int(cd[key])
    for value in cd.values():
        if "method" not in value:
            continue
        try:
            doc = yaml.safe_load(value)
        except yaml.YAMLError:
            continue
        if isinstance(doc, dict) and isinstance(doc.get("variation"), dict):
            m = doc["variation"].get("method")
            if m in (1, 2):
                return int(m)
    return None


def _label(bag: BagData, s: StreamData, with_bag: bool) -> str:
    base = f"{bag.name} {s.label}" if with_bag else s.label
    m = method_of(bag, s.prefix)
    return f"{base} (Method {m})" if m is not None else base


def _clear_old(out: Path) -> None:
    for pattern in PLOT_FILES:
        for p in out.glob(pattern):
            p.unlink()


def write_report(
    bag: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    *,
    compare: Sequence[str | os.PathLike[str]] = (),
    exactness: bool = True,
    gravity_model: str | None = None,
    free_inertial: bool = True,
) -> ReportResult:
    """Write ``report.md`` and the PNG plots of ``bag`` into ``out`` (default ``bag/report``).

    Parameters
    ----------
    bag : path
        rosbag2 directory.
    out : path, optional
        Output directory (created; earlier report files in it are replaced).
    compare : paths
        Other bags of the same reference (e.g. the same scenario with ``variation.method=1``):
        their variation streams are compared with this bag's in ``method_comparison.png``.
        Variation streams under several prefixes of one bag are compared too.
    exactness : bool
        Re-check the docs/interface.md §3 rule on every Imu/Odometry pair (cheap: ~0.2 s per 120 000
        cycles).
    gravity_model : {"j2", "spherical"}, optional
        The model of the re-check; default: the one the bag's metadata records (else j2).
    free_inertial : bool
        Run the package's navigator (multirate, exact mode) on each measured IMU
        ``P/imu_measured`` from its truth ``P/odom`` and plot its error growth beside the exact
        navigator's on the ideal ``P/imu`` (:mod:`strapdown_ros.report.free_inertial`; ~0.1 s
        per minute of 200 Hz data, reading included).

    Raises
    ------
    BagReadError
        The bag (or a compare bag) cannot be read; the message names the path and the problem.
    ReportError
        The bag has no topic the report understands.
    """
    from strapdown_ros.report import plots, summary
    from strapdown_ros.report.aided import aided_prefixes
    from strapdown_ros.report.solutions import bag_solutions, solution_table
    from strapdown_ros.report.transfer import transfer_prefixes

    start = time.perf_counter()
    data = load_bag(bag, exactness=exactness, gravity_model=gravity_model)
    transfer = transfer_prefixes(data.contents)
    aided = [p for p in aided_prefixes(data.contents) if p not in transfer]
    filters = aided + transfer
    others = [load_bag(p, exactness=False, allan=False, odometry_only=True) for p in compare]
    out_dir = Path(out) if out is not None else Path(bag) / "report"
    out_dir.mkdir(parents=True, exist_ok=True)
    _clear_old(out_dir)
    result = ReportResult(out_dir, out_dir / "report.md")
    md = summary.header(data)
    solutions = bag_solutions(data, aided, transfer)
    sections: list[str] = []
    images: list[tuple[str, str, str]] = []  # (name, file, caption)

    def draw(name: str, fname: str, caption: str, fn, *args) -> None:  # noqa: ANN001
        path = fn(*args, out_dir / fname)
        result.plots[name] = path
        images.append((name, fname, caption))

    # --- trajectory, attitude/velocity, IMU
    if data.streams:
        draw("trajectory", "trajectory.png",
             "Ground track (north/east from the start) and ellipsoidal altitude.",
             plots.plot_trajectory, data)  # fmt: skip
    else:
        result.omitted["trajectory"] = "no Odometry or NavSatFix topic (`P/odom`, `P/fix`)"
    if any(s.rph is not None for s in data.streams.values()):
        draw("attitude_velocity", "attitude_velocity.png",
             "Roll, pitch, heading of the body (FRD) w.r.t. NED and the NED velocity relative "
             "to the Earth.", plots.plot_attitude_velocity, data)  # fmt: skip
    else:
        result.omitted["attitude_velocity"] = "no Odometry topic (`P/odom`)"
    if plots.imu_list(data):
        draw("imu", "imu.png",
             "Published angular rate and specific force of every IMU (a measured one beside "
             "its ideal twin), each in its own FLU axes, named by the vehicle direction each "
             "axis points to as mounted.", plots.plot_imu, data)  # fmt: skip
    else:
        result.omitted["imu"] = "no Imu topic"

    # --- exactness
    if data.residuals:
        sections += ["", "## Exactness (docs/interface.md §3)", ""] + summary.exactness_table(data)
        if any(not isinstance(r, str) for _, r in data.residuals.values()):
            draw("exactness", "exactness.png",
                 "One-step residuals of Savage 2020 eqs. (2)-(4) of every Imu/Odometry pair, "
                 "with the docs/interface.md §3 limits.", plots.plot_exactness, data)  # fmt: skip
    elif exactness:
        result.omitted["exactness"] = "no Imu/Odometry pair (`P/imu` + `P/odom`)"
    else:
        result.omitted["exactness"] = "not requested (--no-exactness)"

    # --- navigation errors
    nav_errors = {o: es for o, es in data.errors.items() if o not in filters}
    if nav_errors:
        for owner, es in nav_errors.items():
            suffix = "" if owner == "/navigator" else "_" + _slug(owner)
            sections += ["", f"## Navigation errors of `{owner}`", ""] + summary.error_table(es)
            draw(f"navigation_errors{suffix}", f"navigation_errors{suffix}.png",
                 f"Navigation minus truth of `{owner}`: NED position, NED velocity, Young 1980 "
                 "error angles.", plots.plot_navigation_errors, data, es)  # fmt: skip
    else:
        result.omitted["navigation_errors"] = (
            "no navigator error topics (`/navigator/error/position|velocity|attitude`)"
        )

    # --- Method 1 vs Method 2 (or any two variation streams)
    candidates = [(data, s, _label(data, s, bool(others))) for s in data.variation_streams()
                  if s.prefix not in filters]  # fmt: skip
    for o in others:
        o_aided = aided_prefixes(o.contents) + transfer_prefixes(o.contents)
        candidates += [(o, s, _label(o, s, True)) for s in o.variation_streams()
                       if s.prefix not in o_aided]  # fmt: skip
    if len(candidates) >= 2:
        (_, sa, la) = candidates[0]
        for j, (_, sb, lb) in enumerate(candidates[1:]):
            suffix = "" if j == 0 else f"_{j + 1}"
            cmp = compare_streams(sa, la, sb, lb)
            sections += ["", f"## Variation comparison: {la} vs {lb}", ""]
            if isinstance(cmp, Comparison):
                sections += summary.comparison_table(cmp)
                draw(f"method_comparison{suffix}", f"method_comparison{suffix}.png",
                     f"{la} vs {lb}: velocity and position differences, cycle-to-cycle "
                     "alternation, and a zoom on the largest alternation.",
                     plots.plot_comparison, cmp,
                     f"{la} vs {lb}: variation streams of the same reference")  # fmt: skip
            else:
                sections.append(f"Not compared: {cmp}.")
                result.omitted[f"method_comparison{suffix}"] = cmp
    else:
        n = len(candidates)
        result.omitted["method_comparison"] = (
            f"{n} variation stream{'s' if n != 1 else ''} with Odometry; pass a second bag with "
            "`--compare OTHER_DIR` (e.g. the same scenario with `--set variation.method=1`)"
        )

    # --- Allan deviation of measured increments
    if data.measured:
        for prefix, mi in data.measured.items():
            suffix = "" if prefix == "/variation" else "_" + _slug(prefix)
            sections += ["", f"## Allan deviation of `{mi.measured.topic}`", ""]
            if mi.total_gyro is None and mi.error_gyro is None:
                sections.append("Too few messages for an Allan deviation.")
                result.omitted[f"allan{suffix}"] = "too few messages"
                continue
            sections += summary.allan_table(mi)
            draw(f"allan{suffix}", f"allan{suffix}.png",
                 f"Overlapping Allan deviation of `{mi.measured.topic}` (measured − ideal, "
                 "and measured).", plots.plot_allan, mi, data.name)  # fmt: skip
    else:
        result.omitted["allan"] = "no measured IMU topic (`P/imu_measured`)"

    # --- aiding sensors
    from strapdown_ros.report.aiding import aiding_errors, aiding_table, plot_aiding

    aiding = aiding_errors(data.contents, data.start_ns)
    if aiding:
        sections += ["", "## Aiding sensors", ""] + aiding_table(aiding)
        draw("aiding", "aiding.png",
             "Aiding sensors: measured minus truth per topic with the ±σ band of the message "
             "covariance; outages shaded.", plot_aiding, aiding, f"{data.name}: aiding "
             "sensors")  # fmt: skip
    else:
        result.omitted["aiding"] = "no aiding topic (`/gnss/fix`, `/baro/pressure`, ...)"

    # --- free-inertial solutions on the measured IMUs
    if free_inertial:
        sections += _free_inertial_sections(data, solutions, result, draw)
    else:
        result.omitted["free_inertial"] = "not requested (--no-free-inertial)"
    solutions += [
        Solution(r.label, "free-inertial (report)", r.imu_topic, r.kind, r.truth_topic,
                 "computed by this report")
        for r in result.free_inertial
    ]  # fmt: skip

    # --- aided filter
    sections += _aided_sections(data, aided, result, draw)
    sections += _transfer_sections(data, transfer, result, draw)

    result.elapsed_s = time.perf_counter() - start
    if solutions:
        md += ["", "## Solutions and the IMU each consumes", ""] + solution_table(solutions)
    md += ["", "## Topics", ""] + summary.topic_table(data)
    md += sections
    md += ["", "## Plots", ""]
    for name, fname, caption in images:
        md += [f"### {name}", "", f"![{name}]({fname})", "", caption, ""]
    if result.omitted:
        md += ["## Omitted plots", ""]
        md += [f"- **{name}**: {why}" for name, why in result.omitted.items()]
        md.append("")
    md += [f"_Written by `strapdown-sim report` in {result.elapsed_s:.1f} s._", ""]
    result.markdown.write_text("\n".join(md), encoding="utf-8")
    return result


def _free_inertial_sections(data: BagData, solutions: list[Solution], result: ReportResult,
                            draw) -> list[str]:  # noqa: ANN001  # fmt: skip
    """The report's navigator on each measured IMU ``P/imu_measured`` (truth ``P/odom``), beside
    the exact navigator on the ideal ``P/imu``: the bag's navigator when it consumes it, else the
    report's navigator on it."""
    from strapdown_ros.report.free_inertial import free_inertial, growth_table, plot_free_inertial

    out: list[str] = []
    if not data.measured:
        result.omitted["free_inertial"] = "no measured IMU topic (`P/imu_measured`)"
        return out
    model = data.settings.gravity_model if data.settings is not None else "j2"

    def run_on(imu: str, truth: str, kind: str) -> FreeInertial | str:
        clock = time.perf_counter()
        run = free_inertial(data.contents, imu, truth, data.start_ns, gravity_model=model,
                            kind=kind)  # fmt: skip
        result.free_inertial_s += time.perf_counter() - clock
        return run

    for prefix, mi in data.measured.items():
        suffix = "" if len(data.measured) == 1 else "_" + _slug(prefix)
        truth = f"{prefix}/odom"
        stream = data.streams.get(prefix)
        if stream is None or stream.r_e is None or stream.source != truth:
            result.omitted[f"free_inertial{suffix}"] = (
                f"no truth `{truth}` (ECEF Odometry) for `{mi.measured.topic}`"
            )
            continue
        run = run_on(mi.measured.topic, truth, "measured")
        if isinstance(run, str):
            result.omitted[f"free_inertial{suffix}"] = run
            continue
        result.free_inertial.append(run)
        series = [ErrorGrowth.of(run)]
        ideal_t = f"{prefix}/imu"
        nav = next((s for s in solutions if s.origin == "navigator" and s.imu_topic == ideal_t
                    and s.name in data.errors), None)  # fmt: skip
        es = data.errors.get(nav.name) if nav is not None else None
        if es is not None and es.position and es.velocity and es.attitude:
            series.append(ErrorGrowth(f"{nav.name} (in the bag) on {ideal_t} (ideal)",  # type: ignore[union-attr]
                                      es.position[0], es.position[1], es.velocity[1],
                                      es.attitude[1]))  # fmt: skip
        elif ideal_t in data.contents.topics:
            twin = run_on(ideal_t, truth, "ideal")
            if not isinstance(twin, str):
                result.free_inertial.append(twin)
                series.append(ErrorGrowth.of(twin))
        spec = run.spec
        out += ["", f"## Free-inertial navigation on the measured IMU `{mi.measured.topic}`", "",
                f"The package's navigator ({spec.algorithm}, {spec.mode} mode, N = {spec.n}, "
                f"p = {spec.p}, gravity {model}, no damping) run by the report on the recorded "
                f"increments of `{mi.measured.topic}`, initialized from `{truth}` at "
                f"{run.t[0]:.3f} s without initial errors; errors against `{truth}` at every "
                "navigation cycle (docs/interface.md §4).", ""]  # fmt: skip
        if run.note:
            out += [f"Note: {run.note}.", ""]
        out += growth_table(series)
        draw(f"free_inertial{suffix}", f"free_inertial{suffix}.png",
             f"Error growth of the free-inertial navigator on the measured `{mi.measured.topic}` "
             f"beside the exact navigator on the ideal `{ideal_t}` (log scale).",
             plot_free_inertial, series, f"{data.name}: free-inertial error growth on "
             f"{mi.measured.topic} vs the ideal {ideal_t}")  # fmt: skip
    return out


def _filter_outputs(
    data: BagData,
    prefixes: list[str],
    root: str,
    load: Callable[[BagContents, str, int], T | str],
    result: ReportResult,
    none: str,
) -> Iterator[tuple[str, str, T]]:
    """``(prefix, suffix, loaded)`` of each filter output prefix of a section whose own prefix is
    ``root`` (e.g. ``/aided``): ``loaded`` is what ``load(contents, prefix, start_ns)`` reads,
    ``suffix`` the plot names' (empty for ``root``). Omitted (``result.omitted``): the section
    (``none``, the reason) when there is no prefix, a prefix whose ``load`` returns a reason."""
    key = root.strip("/")
    if not prefixes:
        result.omitted[key] = none
    for prefix in prefixes:
        suffix = "" if prefix == root else "_" + _slug(prefix)
        loaded = load(data.contents, prefix, data.start_ns)
        if isinstance(loaded, str):
            result.omitted[f"{key}{suffix}"] = loaded
            continue
        yield prefix, suffix, loaded


def _aided_sections(data: BagData, aided: list[str], result: ReportResult,
                    draw) -> list[str]:  # noqa: ANN001  # fmt: skip
    """Errors with ±3σ, NEES and NIS of each aided filter, recomputed from the bag."""
    from strapdown_ros.report.aided import (
        aided_data,
        aided_table,
        plot_aided_consistency,
        plot_aided_errors,
    )

    out: list[str] = []
    none = "no aided filter outputs (`P/odom` + `P/nees`, the `aided` section's `/aided/*`)"
    for prefix, suffix, a in _filter_outputs(data, aided, "/aided", aided_data, result, none):
        result.aided[prefix] = a
        out += ["", f"## Aided filter `{prefix}`", ""] + aided_table(a)
        if not a.t.size:
            result.omitted[f"aided{suffix}"] = f"`{prefix}` and its truth share no stamp"
            continue
        draw(f"aided_errors{suffix}", f"aided_errors{suffix}.png",
             f"`{prefix}` minus truth per axis with the filter's ±3σ (from its covariances).",
             plot_aided_errors, a, data.name)  # fmt: skip
        draw(f"aided_consistency{suffix}", f"aided_consistency{suffix}.png",
             f"NEES of `{prefix}` (recomputed) and NIS per measurement with the 95 % χ² "
             "interval.", plot_aided_consistency, a, data.name)  # fmt: skip
    return out


def _transfer_sections(data: BagData, transfer: list[str], result: ReportResult,
                       draw) -> list[str]:  # noqa: ANN001  # fmt: skip
    """The slave's errors, NEES and NIS and the mounting error of each transfer filter,
    recomputed from the bag."""
    from strapdown_ros.report.aided import aided_table, plot_aided_consistency, plot_aided_errors
    from strapdown_ros.report.transfer import plot_transfer_mounting, transfer_data, transfer_table

    out: list[str] = []
    none = ("no transfer-alignment outputs (`P/odom` + `P/mounting/estimate`, the "
            "`transfer_alignment` section's `/transfer/*`)")  # fmt: skip
    for prefix, suffix, r in _filter_outputs(data, transfer, "/transfer", transfer_data, result,
                                             none):  # fmt: skip
        result.transfer[prefix] = r
        out += ["", f"## Transfer alignment `{prefix}`", "", "### The slave INS", ""]
        out += aided_table(r.slave)
        out += ["", "### The mounting", ""] + transfer_table(r)
        draw(f"transfer_errors{suffix}", f"transfer_errors{suffix}.png",
             f"The slave `{prefix}` minus its truth per axis with the filter's ±3σ.",
             plot_aided_errors, r.slave, data.name)  # fmt: skip
        draw(f"transfer_consistency{suffix}", f"transfer_consistency{suffix}.png",
             f"NEES of the slave `{prefix}` (recomputed) and NIS of the velocity and attitude "
             "matching with the 95 % χ² interval.", plot_aided_consistency, r.slave,
             data.name)  # fmt: skip
        draw(f"transfer_mounting{suffix}", f"transfer_mounting{suffix}.png",
             f"The mounting estimate of `{prefix}` minus the truths' relative attitude with the "
             "filter's ±3σ, and |error| against σ.", plot_transfer_mounting, r,
             data.name)  # fmt: skip
    return out
