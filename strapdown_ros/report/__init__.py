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
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from strapdown_ros.report.data import (
    BagData,
    Comparison,
    ReportError,
    StreamData,
    compare_streams,
    load_bag,
)

__all__ = ["PLOT_FILES", "ReportError", "ReportResult", "method_of", "write_report"]

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
)


@dataclass
class ReportResult:
    """What :func:`write_report` wrote."""

    out_dir: Path
    markdown: Path
    plots: dict[str, Path] = field(default_factory=dict)  #: name -> PNG path
    omitted: dict[str, str] = field(default_factory=dict)  #: plot -> reason
    elapsed_s: float = 0.0


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

    Raises
    ------
    BagReadError
        The bag (or a compare bag) cannot be read; the message names the path and the problem.
    ReportError
        The bag has no topic the report understands.
    """
    from strapdown_ros.report import plots, summary

    start = time.perf_counter()
    data = load_bag(bag, exactness=exactness, gravity_model=gravity_model)
    others = [load_bag(p, exactness=False, allan=False, odometry_only=True) for p in compare]
    out_dir = Path(out) if out is not None else Path(bag) / "report"
    out_dir.mkdir(parents=True, exist_ok=True)
    _clear_old(out_dir)
    result = ReportResult(out_dir, out_dir / "report.md")
    md = summary.header(data)
    md += ["", "## Topics", ""] + summary.topic_table(data)
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
    if data.errors:
        for owner, es in data.errors.items():
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
    candidates = [(data, s, _label(data, s, bool(others))) for s in data.variation_streams()]
    for o in others:
        candidates += [(o, s, _label(o, s, True)) for s in o.variation_streams()]
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

    result.elapsed_s = time.perf_counter() - start
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
