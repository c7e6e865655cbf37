"""The chain of stages: which stages exist, in which order, and what feeds what — written once.

:data:`CHAIN` lists the links in ``generate``'s order. A link names its scenario section (the
link is enabled when the section is), the node executable that runs it live, the topics it
reads and the topics it produces with their message counts and stamps (computed from the plan,
never from the trajectory), and how ``generate`` builds its stage. ``generate``
(:func:`offline_stages`), ``campaign`` (:func:`links_for`) and ``run`` (:func:`live_graph`:
which nodes to start, downstream first, and how many subscriptions each topic will have) are
all made from it; adding a stage is one entry here plus the stage itself.

The ``tf`` link is not a process of its own: every node derives the TF, map-frame odometry and
increment topics of its own outputs (``stages/tf.py``), and ``generate`` derives them after
the other stages.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from strapdown_ros.config import Scenario
from strapdown_ros.plan.model import Plan, TopicPlan
from strapdown_ros.topics import MSGTYPES

__all__ = [
    "CHAIN",
    "Link",
    "LiveNode",
    "enabled_links",
    "feed_stages",
    "link",
    "links_for",
    "live_graph",
    "offline_only",
    "offline_stages",
]

Topics = dict[str, TopicPlan]


@dataclass(frozen=True)
class Link:
    """One stage of the chain.

    ``enabled(scenario)``; ``inputs(plan)``: the topics its node subscribes to;
    ``outputs(plan, upstream)``: the :class:`TopicPlan` of each topic it produces, given those
    of the links before it; ``stage(plan, built)``: the stage object ``generate`` feeds
    (``built``: the stages of the links before it, by name), None for the source.
    """

    name: str
    node: str | None
    enabled: Callable[[Scenario], bool]
    inputs: Callable[[Plan], tuple[str, ...]]
    outputs: Callable[[Plan, Mapping[str, TopicPlan]], Topics]
    stage: Callable[[Plan, Mapping[str, Any]], Any] | None = None


def _grid(plan: Plan, key: str, count: int, link_name: str, first: int) -> TopicPlan:
    """The topic of ``recording.topics`` key ``key``: ``count`` messages on the cycle grid from
    cycle ``first``."""
    t0, t = plan.start_ns, plan.period_ns
    topic = plan.scenario.recording.topics[key]
    return TopicPlan(topic, MSGTYPES[key], count, link_name, key, t0 + first * t,
                     t0 + (first + count - 1) * t)  # fmt: skip


# -- trajectory: the reference stream (the source) ----------------------------------------------


def _trajectory_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    m = plan.cycles
    keys = [("reference_odom", m + 1, 0), ("reference_fix", m + 1, 0), ("reference_imu", m, 1)]
    if plan.scenario.recording.clock:
        keys.insert(0, ("clock", m + 1, 0))
    return {p.topic: p for p in (_grid(plan, k, n, "trajectory", f) for k, n, f in keys)}


# -- variation ----------------------------------------------------------------------------------


def _variation_inputs(plan: Plan) -> tuple[str, ...]:
    topics = plan.scenario.recording.topics
    return topics["reference_imu"], topics["reference_odom"]


def _variation_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    m = plan.variation_cycles
    keys = (
        ("variation_odom", m + 1, 0),
        ("variation_fix", m + 1, 0),
        ("variation_imu", m, 1),
        ("variation_reference_odom", m + 1, 0),
        ("variation_reference_imu", m, 1),
    )
    return {p.topic: p for p in (_grid(plan, k, n, "variation", f) for k, n, f in keys)}


def _variation_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.variation import VariationStage

    return VariationStage.offline(plan.scenario, plan.cycles)


# -- imu_model: the IMU error model -------------------------------------------------------------


def _imu_model_inputs(plan: Plan) -> tuple[str, ...]:
    return tuple(source for source, _ in plan.imu_errors_topics)


def _imu_model_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    out: Topics = {}
    for source, measured in plan.imu_errors_topics:  # one output per model, in order
        src = upstream[source]
        key = "variation_imu_measured"  # a recording.topics key only under its recording name
        key = key if plan.scenario.recording.topics[key] == measured else None
        out[measured] = TopicPlan(measured, MSGTYPES["variation_imu_measured"], src.count,
                                  "imu_errors", key, src.first_ns, src.last_ns)  # fmt: skip
    return out


def _imu_model_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.imu_errors import ImuErrorsStages

    return ImuErrorsStages(plan.scenario)


def _imu_model_nodes(plan: Plan) -> list[tuple[str, tuple[str, ...], tuple[str, ...]]]:
    """One ``imu_model_node`` per model: (node name, its ``model`` parameter, its input)."""
    from strapdown_ros.stages.imu_errors import imu_model_node_name

    return [(imu_model_node_name(i), (f"model:={i}",), (source,))
            for i, (source, _) in enumerate(plan.imu_errors_topics)]  # fmt: skip


# -- navigator ----------------------------------------------------------------------------------

#: Navigator output keys (``recording.topics`` keys), the errors last.
NAVIGATOR_OUTPUTS = (
    "navigator_odom",
    "navigator_fix",
    "navigator_error_position",
    "navigator_error_velocity",
    "navigator_error_attitude",
)


def _navigator_inputs(plan: Plan) -> tuple[str, ...]:
    nav = plan.navigator
    assert nav is not None
    return (nav.imu_topic, nav.truth_topic) if nav.truth_topic else (nav.imu_topic,)


def _navigator_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    nav = plan.navigator
    assert nav is not None
    topics = plan.scenario.recording.topics
    count = upstream[nav.imu_topic].count // nav.n + 1
    keys = NAVIGATOR_OUTPUTS if nav.truth_topic else NAVIGATOR_OUTPUTS[:2]
    t_nav = nav.n * plan.period_ns
    out: Topics = {}
    last = plan.start_ns + (count - 1) * t_nav
    for key in keys:
        out[topics[key]] = TopicPlan(topics[key], MSGTYPES[key], count, "navigator", key,
                                     plan.start_ns, last)  # fmt: skip
    return out


def _navigator_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.navigator import NavigatorStage

    return NavigatorStage.for_scenario(plan.scenario, plan.navigator, period_ns=plan.period_ns)


# -- aiding sensors -----------------------------------------------------------------------------


def _aiding_inputs(plan: Plan) -> tuple[str, ...]:
    return (plan.scenario.recording.topics["reference_odom"],)


def _aiding_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    from strapdown_ros.stages.aiding import aiding_topic_plans

    assert plan.aiding is not None
    return {p.topic: p for p in aiding_topic_plans(plan.scenario, plan.aiding, plan.cycles)}


def _aiding_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.aiding import AidingStage

    assert plan.aiding is not None
    return AidingStage(plan.scenario, plan.aiding)


# -- aided: the error-state Kalman filter on the measured IMU and the aiding sensors ----------


def _aided_enabled(scenario: Scenario) -> bool:
    return getattr(scenario, "aided", None) is not None


def _aided_inputs(plan: Plan) -> tuple[str, ...]:
    from strapdown_ros.stages.aided import aided_input_topics

    return tuple(aided_input_topics(plan.scenario))


def _aided_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    from strapdown_ros.stages.aided import aided_topic_plans

    return {p.topic: p for p in aided_topic_plans(plan.scenario, plan.cycles)}


def _aided_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.aided import AidedStage

    return AidedStage(plan.scenario)


# -- transfer_alignment: the variation IMU's INS aided by the reference state -------------------


def _transfer_enabled(scenario: Scenario) -> bool:
    from strapdown_ros.config.transfer import transfer_spec

    return transfer_spec(scenario) is not None


def _transfer_inputs(plan: Plan) -> tuple[str, ...]:
    from strapdown_ros.stages.transfer import transfer_input_topics

    return tuple(transfer_input_topics(plan.scenario))


def _transfer_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    from strapdown_ros.stages.transfer import transfer_topic_plans

    return {p.topic: p for p in transfer_topic_plans(plan.scenario, plan.variation_cycles)}


def _transfer_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.transfer import TransferStage

    return TransferStage(plan.scenario, plan.variation_cycles)


# -- timing: sensor timing errors on the published IMU and aiding messages ----------------------


def _timing_inputs(plan: Plan) -> tuple[str, ...]:
    from strapdown_ros.stages.timing import timed_topics

    return tuple(t for t in timed_topics(plan) if t in plan.topics)


def _timing_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    from strapdown_ros.stages.timing import timing_topic_plans

    return {p.topic: p for p in timing_topic_plans(plan, upstream)}


def _timing_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.timing import TimingStage

    return TimingStage(plan)


# -- tf: TF, map-frame odometry and increments, derived from every other link's outputs ---------


def _tf_outputs(plan: Plan, upstream: Mapping[str, TopicPlan]) -> Topics:
    from strapdown_ros.stages.tf import derived_topic_plans

    return {p.topic: p for p in derived_topic_plans(plan, upstream)}


def _tf_stage(plan: Plan, built: Mapping[str, Any]) -> Any:
    from strapdown_ros.stages.tf import TFStage

    variation = built.get("variation")
    offsets = None if variation is None else variation.offsets
    return TFStage(plan, offsets=offsets)


def _none(plan: Plan) -> tuple[str, ...]:
    return ()


def _always(scenario: Scenario) -> bool:
    return True


#: The stages in ``generate``'s order.
CHAIN: tuple[Link, ...] = (
    Link("trajectory", "trajectory_node", _always, _none, _trajectory_outputs),
    Link("variation", "variation_node", lambda s: s.variation is not None, _variation_inputs,
         _variation_outputs, _variation_stage),  # fmt: skip
    Link("imu_errors", "imu_model_node", lambda s: bool(s.imu_errors), _imu_model_inputs,
         _imu_model_outputs, _imu_model_stage),  # fmt: skip
    Link("navigator", "navigator_node", lambda s: s.navigator is not None, _navigator_inputs,
         _navigator_outputs, _navigator_stage),  # fmt: skip
    Link("aiding", "aiding_node", lambda s: s.aiding is not None and bool(s.aiding.sensors()),
         _aiding_inputs, _aiding_outputs, _aiding_stage),  # fmt: skip
    Link("aided", "aided_node", _aided_enabled, _aided_inputs, _aided_outputs, _aided_stage),
    Link("transfer_alignment", "transfer_node", _transfer_enabled, _transfer_inputs,
         _transfer_outputs, _transfer_stage),  # fmt: skip
    Link("timing", None, lambda s: s.timing is not None and bool(s.timing.sensors()),
         _timing_inputs, _timing_outputs, _timing_stage),  # fmt: skip
    Link("tf", None, _always, _none, _tf_outputs, _tf_stage),
)


def link(name: str) -> Link:
    """The chain link called ``name``."""
    for item in CHAIN:
        if item.name == name:
            return item
    raise KeyError(f"no chain link {name!r}; links: {', '.join(i.name for i in CHAIN)}")


def enabled_links(plan: Plan) -> list[Link]:
    """The links the plan enables, in chain order."""
    return [link(name) for name in plan.links]


# -- generate and campaign ----------------------------------------------------------------------


def offline_stages(plan: Plan, names: Iterable[str] | None = None) -> list[tuple[str, Any]]:
    """``(link name, stage)`` of the enabled links after the source (or of ``names`` only),
    built in chain order, as ``generate`` feeds them."""
    wanted = None if names is None else set(names)
    built: dict[str, Any] = {}
    for item in enabled_links(plan):
        if item.stage is None or (wanted is not None and item.name not in wanted):
            continue
        built[item.name] = item.stage(plan, built)
    return list(built.items())


def feed_stages(stages: Sequence[tuple[str, Any]], batches: list[Any]) -> list[Any]:
    """One piece through the stages: each stage takes every batch so far and adds its own."""
    for _, stage in stages:
        batches = batches + stage.feed_batches(batches)
    return batches


def links_for(plan: Plan, targets: Iterable[str], have: Iterable[str] = ()) -> list[str]:
    """The enabled links needed to produce the topics of the links ``targets``, in chain order,
    without those producing the topics in ``have`` (computed elsewhere)."""
    have = set(have)
    producer = {t: p.link for t, p in plan.topics.items()}
    needed: set[str] = set()
    todo = [t for t in targets if plan.has(t)]
    while todo:
        name = todo.pop()
        if name in needed:
            continue
        needed.add(name)
        for topic in link(name).inputs(plan):
            if topic not in have and producer.get(topic) not in needed:
                todo.append(producer[topic])
    return [name for name in plan.links if name in needed]


# -- run: the live graph ------------------------------------------------------------------------


@dataclass(frozen=True)
class LiveNode:
    """A node of the live pipeline: its link, executable, inputs and the topics it publishes
    (its link's outputs and, ``derived``, the TF / map / increment topics derived from them).
    ``name``: its ROS node name (the executable's unless a link runs several nodes, as
    ``imu_errors`` does, one per model); ``params``: the ``name:=value`` parameters saying
    which part of the link it runs."""

    link: str
    executable: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    derived: tuple[str, ...]
    name: str = ""
    params: tuple[str, ...] = ()

    @property
    def node_name(self) -> str:
        """The ROS node name."""
        return self.name or self.executable

    @property
    def published(self) -> tuple[str, ...]:
        return self.outputs + self.derived


def offline_only(plan: Plan) -> list[str]:
    """The enabled links no node runs live (``tf`` excepted: every node derives its own)."""
    return [item.name for item in enabled_links(plan) if item.node is None and item.name != "tf"]


def live_graph(plan: Plan) -> tuple[list[LiveNode], dict[str, int]]:
    """The nodes ``run`` starts (in chain order; start them reversed, downstream first) and the
    number of subscriptions each produced topic will have: the recorder's plus one per node
    reading it."""
    from strapdown_ros.stages.tf import node_derived_topics

    subscribers = dict.fromkeys(plan.topics, 1)
    nodes: list[LiveNode] = []
    for item in enabled_links(plan):
        if item.node is None:
            continue
        inputs = item.inputs(plan)
        for topic in inputs:
            subscribers[topic] = subscribers.get(topic, 0) + 1
        outputs = tuple(t for t, p in plan.topics.items() if p.link == item.name)
        if item.name == "imu_errors":  # one node per model, each its own output
            for (name, params, source), output in zip(_imu_model_nodes(plan), outputs,
                                                      strict=True):  # fmt: skip
                derived = tuple(node_derived_topics(plan, (output,), static=False))
                nodes.append(LiveNode(item.name, item.node, source, (output,), derived, name,
                                      params))  # fmt: skip
            continue
        derived = tuple(node_derived_topics(plan, outputs, static=item.name == "trajectory"))
        nodes.append(LiveNode(item.name, item.node, inputs, outputs, derived))
    return nodes, subscribers
