"""The trajectory of a scenario: its samples, its length and cycle count, the fitted model.

The length of every trajectory kind is known without building the model (segments and coning
from their section, samples from the sample times alone), so the cycle count of a scenario —
all that most stages and nodes need — costs no spline fit. :func:`build_trajectory` builds the
continuous model; :mod:`strapdown_ros.plan` calls it at most once per process (counted by
:func:`trajectory_builds`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.config.trajectory import IncrementsTrajectorySpec, SamplesTrajectorySpec
from strapdown_ros.core.trajectory.base import Trajectory, TrajectoryError

if TYPE_CHECKING:  # the samples module loads numba: only a samples trajectory needs it
    from strapdown_ros.core.trajectory.samples import Samples

__all__ = [
    "build_trajectory",
    "load_samples",
    "natural_duration",
    "output_cycles",
    "trajectory_builds",
]

_BUILDS = [0]


def trajectory_builds() -> int:
    """How many trajectory models this process has built (a check that it is done once)."""
    return _BUILDS[0]


def load_samples(scenario: Scenario) -> Samples | None:
    """The samples of a ``samples`` trajectory (CSV file or a bag's Odometry topic), unfitted;
    None for the other kinds.

    Raises
    ------
    ScenarioError
        ``trajectory.file`` / ``trajectory.bag`` ... for samples that cannot be read.
    """
    spec = scenario.trajectory
    if not isinstance(spec, SamplesTrajectorySpec):
        return None
    from strapdown_ros.inputs.samples import (
        SamplesInputError,
        load_samples_csv,
        odometry_samples,
    )

    source = _source(scenario, spec)
    try:
        if spec.file is not None:
            return load_samples_csv(source, columns=spec.columns, rate_frame=spec.rate_frame)
        return odometry_samples(source, spec.odometry_topic)
    except SamplesInputError as exc:
        raise ScenarioError(f"trajectory.{exc.key}", exc.problem) from None


def _source(scenario: Scenario, spec: SamplesTrajectorySpec) -> Path:
    source = Path(spec.file if spec.file is not None else spec.bag)  # type: ignore[arg-type]
    return source if source.is_absolute() else scenario.base_dir / source


def build_trajectory(scenario: Scenario, samples: Samples | None = None) -> Trajectory | None:
    """The continuous trajectory model of the scenario (``None`` for kind ``increments``).

    ``samples``: the already loaded samples of a ``samples`` trajectory (read here if None).

    Raises
    ------
    ScenarioError
        For a trajectory found impossible while building it (e.g.
        ``trajectory.segments[2].accel_mps2`` when the speed would become negative), samples
        that cannot be read or fitted (``trajectory.file``, ``trajectory.knots``, ...).
    """
    spec = scenario.trajectory
    if isinstance(spec, IncrementsTrajectorySpec):
        return None
    _BUILDS[0] += 1
    if isinstance(spec, SamplesTrajectorySpec):
        from strapdown_ros.core.trajectory.samples import SamplesTrajectory

        samples = load_samples(scenario) if samples is None else samples
        try:
            return SamplesTrajectory(samples, spec.fit_options())
        except TrajectoryError as exc:
            key, prefix = spec.key_of(exc.where)
            raise ScenarioError(key, prefix + exc.problem) from None
        except ValueError as exc:  # samples the fit cannot use
            raise ScenarioError(spec.source_key, f"{_source(scenario, spec)}: {exc}") from None
    assert scenario.initial is not None  # the model requires it for these kinds
    return spec.build(scenario.initial)


def natural_duration(scenario: Scenario, samples: Samples | None = None) -> float:
    """Length (s) of the trajectory as described, before ``duration_s`` truncates it: the
    sum of the segments, the coning duration, or the span of the sample times (the fitted
    model's ``duration``, bit for bit)."""
    spec = scenario.trajectory
    if isinstance(spec, SamplesTrajectorySpec):
        samples = load_samples(scenario) if samples is None else samples
        t = np.asarray(samples.t, dtype=np.float64)  # type: ignore[union-attr]
        return float((t - t[0])[-1])
    return spec.natural_duration  # type: ignore[union-attr]


def output_cycles(scenario: Scenario, natural_s: float) -> int:
    """Output cycles M of the scenario (``duration_s``, else the trajectory's whole length).

    Raises
    ------
    ScenarioError
        ``duration_s`` longer than the trajectory, or shorter than one cycle.
    """
    duration = scenario.duration_s if scenario.duration_s is not None else natural_s
    if duration > natural_s + 1e-9:
        raise ScenarioError(
            "duration_s",
            f"{duration} s exceeds the trajectory's length of {natural_s} s",
        )
    cycles = int(np.floor(duration * scenario.rate_hz + 1e-9))
    if cycles < 1:
        raise ScenarioError("duration_s", f"{duration} s is shorter than one cycle")
    return cycles
