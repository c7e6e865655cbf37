"""Sweep of initial orientation errors: generate, navigate, compare with Young 1980 eq. (51).

For each initial error (azimuth a, tilt τ: the navigator starts with roll, pitch, heading offsets
``[τ, τ, a]`` deg, ``navigator.initial_errors.attitude_rph_deg``) the sweep writes the
scenario's bag with ``generate_dataset``, reads it back from disk, integrates eq. (51) and its
linear (phi-angle) limit along the run (:func:`~strapdown_ros.analysis.orientation.
compare_orientation`) and keeps a table row: the final and max-over-span angles of the
navigator, of eq. (51) and of the linear model, their agreement and when the linear model
departs by more than 10 %. ``strapdown-sim sweep-orientation`` is the command line.

The navigator (``setup``):

* ``damped`` (default): Waldmann Table 1 ``paper`` mode with vertical-channel damping on the
  truth altitude — a free-inertial horizontal solution whose vertical channel stays bounded
  (large tilts otherwise drive the unstable channel out of the atmosphere within the hour);
* ``exact``: the high-accuracy ``exact`` mode, undamped (the attitude is then exactly Young's
  model of the gyro data; the indicated altitude may run away with large tilts);
* ``scenario``: the scenario's ``navigator`` section as it is.

Scenarios without a ``navigator`` section get one on ``/reference/imu`` with truth
``/reference/odom``. Outputs in ``out``: ``sweep.json`` (the table) and ``series/<case>.npz``
(t, actual, nonlinear, linear θ, rad).
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from strapdown_ros.analysis.navigator_record import NavigatorRecord, read_navigator_record
from strapdown_ros.analysis.orientation import (
    GyroErrors,
    OrientationComparison,
    compare_orientation,
)
from strapdown_ros.config import Scenario, load_scenario
from strapdown_ros.config.scenario import apply_overrides, navigator_spec, read_document
from strapdown_ros.core.earth import geodetic_to_ecef

__all__ = [
    "SETUPS",
    "SweepCase",
    "case_scenario",
    "format_table",
    "gyro_errors_of",
    "run_case",
    "sweep_orientation",
]

#: Navigator set-ups: overrides applied after the scenario's own.
SETUPS: dict[str, tuple[str, ...]] = {
    "damped": ("navigator.mode=paper", "navigator.vertical_damping=true"),
    "exact": ("navigator.mode=exact", "navigator.vertical_damping=null"),
    "scenario": (),
}

#: The navigator section given to scenarios without one.
DEFAULT_NAVIGATOR = ("navigator.imu_topic=/reference/imu", "navigator.truth_topic=/reference/odom")

Progress = Callable[[str], None]


@dataclass(frozen=True)
class SweepCase:
    """One initial orientation error: heading offset ``azimuth_deg``, roll and pitch offsets
    ``tilt_deg`` (deg)."""

    azimuth_deg: float
    tilt_deg: float

    @property
    def name(self) -> str:
        """File-name-safe label, e.g. ``az170_tilt10``."""
        return f"az{self.azimuth_deg:g}_tilt{self.tilt_deg:g}".replace("-", "m")

    @property
    def attitude_rph_deg(self) -> list[float]:
        """``navigator.initial_errors.attitude_rph_deg``."""
        return [self.tilt_deg, self.tilt_deg, self.azimuth_deg]


def case_scenario(
    path: str | Path,
    case: SweepCase,
    overrides: Sequence[str] = (),
    duration_s: float | None = None,
    setup: str = "damped",
) -> Scenario:
    """The scenario of one case: ``path`` with ``overrides``, a navigator if it has none, the
    ``setup``'s navigator keys and the case's initial attitude error.

    A navigator section that names no ``imu_topic`` gets :data:`DEFAULT_NAVIGATOR`'s topics.
    """
    if setup not in SETUPS:
        raise ValueError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
    document = apply_overrides(read_document(Path(path)), overrides)
    nav = document.get("navigator")
    extra = [] if isinstance(nav, dict) and "imu_topic" in nav else list(DEFAULT_NAVIGATOR)
    rph = ",".join(f"{x:g}" for x in case.attitude_rph_deg)
    extra += [*SETUPS[setup], f"navigator.initial_errors.attitude_rph_deg=[{rph}]"]
    return load_scenario(path, [*overrides, *extra], duration_s)


def gyro_errors_of(scenario: Scenario) -> tuple[GyroErrors | None, str | None]:
    """The deterministic gyro errors the navigator sees and the ideal IMU topic under them.

    ``(None, None)`` when the navigator reads an ideal IMU topic.
    """
    nav = navigator_spec(scenario)
    spec = None if nav is None else scenario.imu_errors_of(nav.imu_topic)
    if nav is None or spec is None:
        return None, None
    ideal, measured = spec.topics(scenario.recording.topics)
    return GyroErrors.from_parameters(spec.parameters(), scenario.period_ns * 1e-9), ideal


def _vertical_and_horizontal(record: NavigatorRecord) -> tuple[float, float]:
    truth = record.truth.rows(record.truth_index)
    nav = record.navigator
    dh = float(np.max(np.abs(nav.alt - truth.alt)))
    r_nav = geodetic_to_ecef(nav.lat, nav.lon, truth.alt)  # horizontal: both at the true height
    r_true = geodetic_to_ecef(truth.lat, truth.lon, truth.alt)
    return dh, float(np.max(np.linalg.norm(r_nav - r_true, axis=1)))


def run_case(
    scenario: Scenario, bag: str | Path, keep_bag: bool = True
) -> tuple[OrientationComparison, dict[str, Any]]:
    """Generate ``scenario`` into ``bag``, read the run back and compare (eq. (51), linear).

    Returns the comparison and the case's extra facts: max altitude and horizontal position
    errors of the navigator (m), which gyro errors the oracle carries and which it does not,
    generation and comparison times (s).
    """
    from strapdown_ros.generate import generate_dataset

    nav = navigator_spec(scenario)
    if nav is None:
        raise ValueError("the scenario has no navigator section")
    topics = scenario.recording.topics
    start = time.perf_counter()
    generate_dataset(scenario, bag, force=True)
    generated = time.perf_counter()
    gyro, ideal = gyro_errors_of(scenario)
    record = read_navigator_record(
        bag,
        truth_topic=str(nav.truth_topic),
        navigator_topic=topics["navigator_odom"],
        error_topic=topics["navigator_error_attitude"],
        imu_topic=ideal,
    )
    comparison = compare_orientation(record, gyro)
    dh, dx = _vertical_and_horizontal(record)
    if not keep_bag:
        shutil.rmtree(bag, ignore_errors=True)
    extra = {
        "navigator": {"mode": str(nav.mode), "vertical_damping": nav.vertical_damping is not None,
                      "n": nav.n, "p": nav.p, "imu_topic": nav.imu_topic},
        "rate_hz": scenario.rate_hz,
        "max_altitude_error_m": dh,
        "max_horizontal_error_m": dx,
        "gyro_errors": None if gyro is None else {
            "bias_dph": (np.degrees(gyro.bias) * 3600).tolist(),
            "error_matrix": gyro.error_matrix.tolist(),
            "g_sensitivity": gyro.g_sensitivity.tolist(),
            "not_modelled": list(gyro.stochastic),
        },
        "generate_s": generated - start,
        "compare_s": time.perf_counter() - generated,
    }  # fmt: skip
    return comparison, extra


def sweep_orientation(
    scenario: str | Path,
    azimuth_deg: Sequence[float],
    tilt_deg: Sequence[float],
    out: str | Path,
    *,
    duration_s: float | None = None,
    overrides: Sequence[str] = (),
    setup: str = "damped",
    keep_bags: bool = False,
    progress: Progress | None = None,
    command: str | None = None,
) -> dict[str, Any]:
    """Run every (azimuth, tilt) case; write ``out/sweep.json`` and ``out/series/*.npz``.

    Returns the table written to ``sweep.json``. Bags go to ``out/bags/<case>`` and are removed
    after reading unless ``keep_bags``.
    """
    out = Path(out)
    (out / "series").mkdir(parents=True, exist_ok=True)
    rows = []
    cases = [SweepCase(float(a), float(t)) for t in tilt_deg for a in azimuth_deg]
    for i, case in enumerate(cases):
        if progress is not None:
            progress(f"[{i + 1}/{len(cases)}] {case.name}")
        sc = case_scenario(scenario, case, overrides, duration_s, setup)
        comparison, extra = run_case(sc, out / "bags" / case.name, keep_bags)
        np.savez(
            out / "series" / f"{case.name}.npz",
            t=comparison.t,
            actual=comparison.actual,
            nonlinear=comparison.nonlinear,
            linear=comparison.linear,
        )
        rows.append({"name": case.name, "azimuth_deg": case.azimuth_deg,
                     "tilt_deg": case.tilt_deg, **comparison.summary(), **extra})  # fmt: skip
    if not keep_bags:
        shutil.rmtree(out / "bags", ignore_errors=True)
    table = {
        "scenario": str(scenario),
        "overrides": list(overrides),
        "duration_s": duration_s,
        "setup": setup,
        "command": command,
        "cases": rows,
    }
    (out / "sweep.json").write_text(json.dumps(table, indent=1) + "\n", encoding="utf-8")
    return table


def _fmt_s(value: float | None) -> str:
    return "never" if value is None else f"{value:.1f}"


def format_table(table: dict[str, Any]) -> str:
    """The sweep table as text.

    Per case: θ0, the navigator's final angles, the max |θ_pred - θ_nav| (rad) of eq. (51) and
    of the linear model with their ``max_rel`` (relative to |θ|), the times (s) the linear
    model departs by more than 10 % of |θ| and of the largest change of θ, and the navigator's
    max altitude error (m).
    """
    lines = [
        f"{'case':<16} {'θ0 (deg)':>22} {'navigator final (deg)':>24} {'eq51 max':>9} "
        f"{'rel':>7} {'lin max':>8} {'rel':>5} {'>10%|θ|':>8} {'>10%Δθ':>7} {'Δh max':>8}",
    ]
    for row in table["cases"]:
        th0 = " ".join(f"{x:6.1f}" for x in row["theta0_deg"])
        fin = " ".join(f"{x:7.2f}" for x in row["actual"]["final_deg"])
        nl, li = row["nonlinear"], row["linear"]
        lines.append(
            f"{row['name']:<16} {th0:>22} {fin:>24} {nl['max_norm']:9.2e} {nl['max_rel']:7.1e} "
            f"{li['max_norm']:8.2e} {li['max_rel']:5.2f} {_fmt_s(li['departure_s']):>8} "
            f"{_fmt_s(li['departure_change_s']):>7} {row['max_altitude_error_m']:8.1e}"
        )
    return "\n".join(lines)
