"""Markdown tables of the report (``report.md``): topics, exactness, errors, comparison, Allan."""

from __future__ import annotations

import numpy as np

from strapdown_ros.checks.foreign import capability_lines, is_foreign
from strapdown_ros.core.exact_update import Residuals
from strapdown_ros.report.data import (
    AllanResult,
    BagData,
    Comparison,
    ErrorSet,
    MeasuredImu,
)

__all__ = [
    "allan_table",
    "comparison_table",
    "error_table",
    "exactness_table",
    "header",
    "solution_inputs",
    "topic_table",
]


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    """A markdown table; ``|`` inside cells is escaped."""

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    out = [line(head), "|" + "|".join("---" for _ in head) + "|"]
    return out + [line(r) for r in rows]


def _g(x: float, digits: int = 3) -> str:
    return "—" if x is None or not np.isfinite(x) else f"{x:.{digits}g}"


def _e(x: float) -> str:
    return "—" if x is None or not np.isfinite(x) else f"{x:.2e}"


def header(bag: BagData) -> list[str]:
    c = bag.contents
    sec, ns = divmod(bag.start_ns, 1_000_000_000)
    lines = [
        f"# Report of `{bag.name}`",
        "",
        f"- bag: `{bag.path}` ({c.storage}, rosbag2 metadata version {c.version}, "
        f"{c.message_count} messages, {len(c.topics)} topics)",
        f"- start: {bag.start_utc} (header stamp {sec}.{ns:09d} s)",
        f"- duration: {bag.duration_s:.3f} s (first to last header stamp)",
    ]
    if c.custom_data:
        items = ", ".join(
            f"`{k}` = `{v}`" if len(v) <= 80 and "\n" not in v else f"`{k}` ({len(v)} characters)"
            for k, v in sorted(c.custom_data.items())
        )
        lines.append(f"- custom data: {items}")
    if bag.settings is not None and bag.residuals:
        lines.append(f"- exactness re-check: {bag.settings.describe()}")
    lines += [f"- {s}" for s in solution_inputs(bag)]
    if is_foreign(c.custom_data):
        types = {t: d.msgtype for t, d in c.topics.items()}
        lines += ["", "## What this report can show of this bag", ""]
        lines += [f"- {s}" for s in capability_lines(c.custom_data, types)]
    if bag.notes:
        lines += [f"- {n}" for n in bag.notes]
    return lines


def solution_inputs(bag: BagData) -> list[str]:
    """One line per navigation solution of the bag: the IMU topic it consumes, ideal or measured.

    Navigators: from the bag's ``custom_data`` (``navigator.imu_topic``, or
    ``<prefix>.imu_topic`` for a solution under another prefix); a solution whose input is not
    recorded says so. Aided filters: the measured IMU of the reference
    (:func:`strapdown_ros.report.solutions.bag_solutions`).
    """
    from strapdown_ros.report.aided import aided_prefixes
    from strapdown_ros.report.solutions import bag_solutions

    out = []
    for s in bag_solutions(bag, aided_prefixes(bag.contents)):
        key = s.name.strip("/")
        if s.imu_topic:
            kind = "" if s.kind == "unknown" else f"{s.kind} "
            out.append(f"solution `{s.name}` consumes the {kind}IMU `{s.imu_topic}`")
        elif s.origin == "navigator":
            out.append(
                f"solution `{s.name}`: the bag's metadata does not record which IMU it consumes "
                f"(`{key}.imu_topic`)"
            )
        else:
            out.append(f"solution `{s.name}` ({s.origin}): {s.source}")
    return out


def topic_table(bag: BagData) -> list[str]:
    rows = []
    for topic, d in bag.contents.topics.items():  # the bag's order (generate: by stream)
        n = len(d)
        stamps = getattr(d.fields, "stamps_ns", None) if d.fields is not None else None
        t = np.asarray(stamps if stamps is not None else d.log_time_ns, dtype=np.int64)
        if n:
            first = (int(t.min()) - bag.start_ns) * 1e-9
            last = (int(t.max()) - bag.start_ns) * 1e-9
            rate = (n - 1) / (last - first) if n > 1 and last > first else float("nan")
        else:
            first = last = rate = float("nan")
        rows.append([f"`{topic}`", d.msgtype, str(n), _g(rate, 6), f"{first:.3f}", f"{last:.3f}"])
    return _table(["topic", "type", "messages", "rate [Hz]", "first [s]", "last [s]"], rows)


def exactness_table(bag: BagData) -> list[str]:
    rows = []
    for _prefix, (pair, res) in bag.residuals.items():
        if isinstance(res, str):
            rows.append([f"`{pair}`", "—", "—", "—", "—", res])
            continue
        ok = "ok" if res.within_spec() else "**DEFECT** (docs/interface.md §3)"
        rows.append([
            f"`{pair}`", str(res.attitude.size), _e(res.max_attitude), _e(res.max_velocity),
            _e(res.max_position), ok,
        ])  # fmt: skip
    head = ["streams", "cycles", "max attitude [rad]", "max velocity [m/s]", "max position [m]",
            "result"]  # fmt: skip
    model = bag.settings.describe() if bag.settings is not None else "gravity model j2"
    limits = (
        f"Limits: {Residuals.TOL_ATTITUDE:g} rad, {Residuals.TOL_VELOCITY:g} m/s, "
        f"{Residuals.TOL_POSITION:g} m per step (Savage 2020 eqs. (2)-(4) in E0, gravity at the "
        f"published positions; {model}). Streams at oversample > 1 or with an error model are "
        "not expected to pass."
    )
    return _table(head, rows) + ["", limits]


def _final_max(t_vec: tuple[np.ndarray, np.ndarray] | None, f) -> tuple[float, float]:
    if t_vec is None or t_vec[1].shape[0] == 0:
        return float("nan"), float("nan")
    v = f(t_vec[1])
    return float(v[-1]), float(np.max(v))


def error_table(es: ErrorSet) -> list[str]:
    rows = []
    specs = (
        ("horizontal position (RSS north, east)", "position", "m",
         lambda v: np.hypot(v[:, 0], v[:, 1])),
        ("vertical position (|down|)", "position", "m", lambda v: np.abs(v[:, 2])),
        ("velocity (|NED|)", "velocity", "m/s", lambda v: np.linalg.norm(v, axis=1)),
        ("horizontal velocity (RSS north, east)", "velocity", "m/s",
         lambda v: np.hypot(v[:, 0], v[:, 1])),
        ("attitude, heading |θ1|", "attitude", "rad", lambda v: np.abs(v[:, 0])),
        ("attitude, tilt (RSS θ2, θ3)", "attitude", "rad", lambda v: np.hypot(v[:, 1], v[:, 2])),
    )  # fmt: skip
    for label, name, unit, f in specs:
        data = getattr(es, name)
        if data is None:
            continue
        final, peak = _final_max(data, f)
        rows.append([label, _e(final), _e(peak), unit])
    t_end = max(
        (float(x[0][-1]) for x in (es.position, es.velocity, es.attitude) if x is not None
         and x[0].size),
        default=float("nan"),
    )  # fmt: skip
    return _table(["quantity", f"final (t = {t_end:.3f} s)", "max", "unit"], rows)


def comparison_table(cmp: Comparison) -> list[str]:
    mags = [np.linalg.norm(x, axis=-1) for x in (cmp.alt_a, cmp.alt_b)]
    rows = [
        ["median cycle-to-cycle velocity alternation |Δ⁴V|/16 [m/s]"]
        + [_e(float(np.median(m))) if m.size else "—" for m in mags],
        ["max cycle-to-cycle velocity alternation [m/s]"]
        + [_e(float(m.max(initial=0.0))) for m in mags],
    ]
    lines = _table(["", cmp.label_a, cmp.label_b], rows)
    lines += [
        "",
        f"Common cycles: {cmp.t.size}; max |V_a − V_b| = {_e(float(cmp.dv.max()))} m/s; "
        f"max |R_a − R_b| = {_e(cmp.even_cycles_dr)} m at even cycles, "
        f"{_e(cmp.odd_cycles_dr)} m at odd cycles (Method 2 meets the position constraint only "
        "at even cycles, Method 1 at every cycle).",
    ]
    return lines


def _at_tau(res: AllanResult, tau: float, k: int) -> float:
    taus, adev = res.taus, res.adev[:, k]
    if taus.size == 0 or tau < taus[0] or tau > taus[-1]:
        return float("nan")
    return float(np.exp(np.interp(np.log(tau), np.log(taus), np.log(adev))))


def allan_table(mi: MeasuredImu) -> list[str]:
    rows = []
    for what, res, scale, unit in (
        ("gyro", mi.error_gyro or mi.total_gyro, np.degrees(1.0) * 3600.0, "deg/h"),
        ("accel", mi.error_accel or mi.total_accel, 1.0, "m/s²"),
    ):
        if res is None:
            continue
        for k, axis in enumerate("xyz"):
            i = int(np.argmin(res.adev[:, k]))
            rows.append([
                f"{what} {axis}", _e(_at_tau(res, 1.0, k) * scale),
                _e(float(res.adev[i, k]) * scale), _g(float(res.taus[i])), unit,
            ])  # fmt: skip
    what = "measured − ideal" if mi.error_gyro is not None else "measured (motion included)"
    lines = [f"Allan deviation of {what}, `{mi.measured.topic}`:", ""]
    lines += _table(["axis (FLU)", "σ(τ = 1 s)", "min σ", "at τ [s]", "unit"], rows)
    lines += [
        "",
        "White noise reads σ(1 s) as a random walk: angle random walk [deg/√h] = σ_gyro(1 s) "
        "[deg/h] / 60, velocity random walk [m/s/√h] = σ_accel(1 s) [m/s²] · 60; the minimum "
        "over τ bounds the bias instability (flicker floor ≈ min σ / 0.664).",
    ]
    return lines
