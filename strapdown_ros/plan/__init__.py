"""A scenario resolved once (:class:`Plan`) and the chain of stages that runs it (:mod:`.chain`).

``resolve_plan(scenario)`` is called once per process by ``generate``, ``run``, ``campaign`` and
each node; everything downstream reads counts, stamps, resolved sections and topics from the
plan. docs/architecture.md draws scenario → plan → chain → sinks.
"""

from strapdown_ros.plan.model import Plan, TopicPlan, variation_end_cycle
from strapdown_ros.plan.resolve import resolve_plan, variation_is_static
from strapdown_ros.plan.trajectory import build_trajectory, trajectory_builds

__all__ = [
    "Plan",
    "TopicPlan",
    "build_trajectory",
    "resolve_plan",
    "trajectory_builds",
    "variation_end_cycle",
    "variation_is_static",
]
