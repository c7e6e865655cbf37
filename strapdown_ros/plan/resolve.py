"""Resolving a scenario into its :class:`~strapdown_ros.plan.model.Plan`, once."""

from __future__ import annotations

from dataclasses import replace

from strapdown_ros.config import Scenario, navigator_spec, tf_spec
from strapdown_ros.config.variation import VariationSpec
from strapdown_ros.core.trajectory.base import Trajectory
from strapdown_ros.plan.chain import CHAIN, Topics
from strapdown_ros.plan.model import Plan
from strapdown_ros.plan.trajectory import load_samples, natural_duration, output_cycles

__all__ = ["resolve_plan", "variation_is_static"]


def variation_is_static(spec: VariationSpec | None) -> bool:
    """Whether a variation's offsets are constant: no scan and no bending term of nonzero
    amplitude (lever arm, displacement and mounting alone)."""
    if spec is None or spec.scan is not None:
        return False
    bending = spec.bending
    if bending is None:
        return True
    sines = all(not any(s.amplitude_m) for s in bending.sinusoids)
    return sines and (bending.random is None or not any(bending.random.sigma_m))


def resolve_plan(
    scenario: Scenario, trajectory: Trajectory | None = None, *, topics: bool = True
) -> Plan:
    """The plan of a validated scenario: cycle counts, resolved sections, enabled links and
    every produced topic with its count and stamps. Reads a ``samples`` trajectory's samples
    (no fit); the trajectory model is built only when :attr:`Plan.trajectory` is first read.
    ``trajectory``: a model built elsewhere (e.g. fitted to samples held in memory), used
    instead of the scenario's own. ``topics=False``: the counts and sections only, no chain
    links and no topic plans (``strapdown-sim validate``: every check that can reject the
    scenario, without importing the stages that plan the topics).

    Raises
    ------
    ScenarioError
        ``duration_s`` longer than the trajectory or shorter than a cycle, samples that cannot
        be read, a navigator section that does not fit the scenario.
    """
    samples = load_samples(scenario) if trajectory is None else None
    natural = natural_duration(scenario, samples) if trajectory is None else trajectory.duration
    imu_errors = scenario.imu_errors
    aiding = scenario.aiding if scenario.aiding is not None and scenario.aiding.sensors() else None
    plan = Plan(
        scenario=scenario,
        cycles=output_cycles(scenario, natural),
        natural_duration_s=natural,
        navigator=navigator_spec(scenario),
        imu_errors=imu_errors,
        imu_errors_topics=scenario.measured_imu_topics(),
        aiding=aiding,
        tf=tf_spec(scenario),
        samples=samples,
        variation_static=variation_is_static(scenario.variation),
    )
    if topics:
        links = [item for item in CHAIN if item.enabled(scenario)]
        planned: Topics = {}
        for item in links:
            planned.update(item.outputs(plan, planned))
        plan = replace(plan, links=tuple(item.name for item in links), topics=planned)
    if trajectory is not None:
        plan.__dict__["trajectory"] = trajectory  # the cached_property's value
    return plan
