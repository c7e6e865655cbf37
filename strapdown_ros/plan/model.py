"""The resolved plan of a scenario: what every stage, node and command reads instead of
re-deriving it (docs/architecture.md).

A :class:`Plan` is made once per process from a validated :class:`~strapdown_ros.config.
Scenario` by :func:`strapdown_ros.plan.resolve_plan`: the cycle counts, each section resolved,
the chain links the scenario enables and every topic it produces with its type, message count
and first and last stamps (:class:`TopicPlan`). The trajectory model is built on first use
only (:attr:`Plan.trajectory`): the counts do not need it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

from strapdown_ros.config import Scenario
from strapdown_ros.config.aiding import AidingSpec
from strapdown_ros.config.imu_errors import ImuErrorsSpec
from strapdown_ros.config.navigator import NavigatorSpec
from strapdown_ros.config.tf import TFSpec
from strapdown_ros.core.trajectory.base import Trajectory
from strapdown_ros.plan.trajectory import build_trajectory

if TYPE_CHECKING:  # the samples module loads numba: only a samples trajectory needs it
    from strapdown_ros.core.trajectory.samples import Samples

__all__ = ["Plan", "TopicPlan", "variation_end_cycle"]


def variation_end_cycle(cycles: int) -> int:
    """Last cycle of the variation streams for M reference cycles: the last even cycle below
    M (Method 2 solves cycle pairs and needs the truth one cycle past the pair;
    docs/variation.md)."""
    return cycles - 1 - (cycles - 1) % 2


@dataclass(frozen=True)
class TopicPlan:
    """One topic a scenario produces.

    ``link``: the chain link that produces it (``tf`` for the topics derived from others);
    ``key``: its ``recording.topics`` key, if any; ``first_ns``/``last_ns``: header stamps of
    its first and last message (None when it has none or they are not fixed in advance);
    ``log_delay_ns``: bag log time minus header stamp (the GNSS latency).
    """

    topic: str
    msgtype: str
    count: int
    link: str
    key: str | None = None
    first_ns: int | None = None
    last_ns: int | None = None
    log_delay_ns: int = 0


@dataclass(frozen=True, eq=False)
class Plan:
    """A scenario resolved once. Attributes are read-only; see the module docstring.

    Attributes
    ----------
    scenario : Scenario
    cycles : int
        Reference output cycles M (truth messages 0..M, IMU messages 1..M).
    natural_duration_s : float
        Length of the trajectory as described (before ``duration_s``).
    navigator : NavigatorSpec or None
        The ``navigator`` section, resolved (topics, mode, gravity model).
    imu_errors : tuple of ImuErrorsSpec
        The IMU error models (empty: none).
    imu_errors_topics : tuple of (str, str)
        Input and output topic of each IMU error model.
    aiding : AidingSpec or None
        The ``aiding`` section when it enables a sensor.
    tf : TFSpec
        The ``tf`` section (its defaults when absent).
    samples : Samples or None
        The unfitted samples of a ``samples`` trajectory.
    variation_static : bool
        The variation's offsets are constant (no bending, no scan): ``base_link →
        variation_imu`` is a static transform.
    links : tuple of str
        Names of the chain links the scenario enables, in chain order.
    topics : mapping
        Topic name → :class:`TopicPlan`, in the order ``generate`` creates them.
    """

    scenario: Scenario
    cycles: int
    natural_duration_s: float
    navigator: NavigatorSpec | None
    imu_errors: tuple[ImuErrorsSpec, ...]
    imu_errors_topics: tuple[tuple[str, str], ...]
    aiding: AidingSpec | None
    tf: TFSpec
    samples: Samples | None = None
    variation_static: bool = False
    links: tuple[str, ...] = ()
    topics: Mapping[str, TopicPlan] = field(default_factory=dict)

    # -- the scenario's time grid ------------------------------------------------------------

    @property
    def period_ns(self) -> int:
        """Output cycle period T (ns)."""
        return self.scenario.period_ns

    @property
    def start_ns(self) -> int:
        """Stamp of cycle 0 (ns since the epoch)."""
        return self.scenario.start_time_ns

    @property
    def duration_s(self) -> float:
        """Seconds of data: M T."""
        return self.cycles * self.period_ns * 1e-9

    @property
    def variation_cycles(self) -> int:
        """Last cycle of the variation streams (:func:`variation_end_cycle`)."""
        return variation_end_cycle(self.cycles)

    @cached_property
    def trajectory(self) -> Trajectory | None:
        """The continuous trajectory model, built on first use (None for ``increments``)."""
        return build_trajectory(self.scenario, self.samples)

    # -- topics ------------------------------------------------------------------------------

    def counts(self) -> dict[str, int]:
        """Message count of every topic (what ``generate`` writes and ``run`` must record)."""
        return {t: p.count for t, p in self.topics.items()}

    def topic_types(self) -> dict[str, str]:
        """Topic name → message type (``pkg/msg/Name``)."""
        return {t: p.msgtype for t, p in self.topics.items()}

    def log_delays(self) -> dict[str, int]:
        """Bag log time minus header stamp (ns) of the topics that have one."""
        return {t: p.log_delay_ns for t, p in self.topics.items() if p.log_delay_ns}

    def last_cycle(self, imu_topic: str) -> int | None:
        """Last cycle published on an IMU topic of the scenario (None: not one of its IMU
        topics)."""
        p = self.topics.get(imu_topic)
        if p is None or p.last_ns is None or p.msgtype != "sensor_msgs/msg/Imu":
            return None
        return (p.last_ns - self.start_ns) // self.period_ns

    def last_stamp(self, topic: str) -> int | None:
        """Header stamp of the last message on ``topic`` (None if unknown)."""
        p = self.topics.get(topic)
        return None if p is None else p.last_ns

    def has(self, link: str) -> bool:
        """Whether the scenario enables the chain link ``link``."""
        return link in self.links
