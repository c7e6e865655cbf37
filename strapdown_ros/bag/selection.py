"""Which topics a bag gets: include / exclude patterns over topic names (no ROS).

As ``ros2 bag record`` selects (``--topics``, ``--regex``, ``--exclude-regex``,
``--exclude-topics``): a topic is written when it matches a pattern of ``include`` (every topic
when there is none) and no pattern of ``exclude``. A pattern is a regular expression that must
match the **whole** topic name (``re.fullmatch``), so a plain name selects that topic only
(``/reference/imu`` is not ``/reference/imu_dv``) and ``/navigator/.*`` a namespace. Topic
names given as names (``--topics``) are escaped into patterns (:func:`name_pattern`).

Only what is written is selected: ``generate`` still computes every stage (an excluded topic
can be another stage's input), ``run`` still runs every node, and its recorder subscribes to
the selected topics only and expects their counts (:meth:`TopicSelection.counts`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from strapdown_ros.config.base import ScenarioError

__all__ = ["SelectionError", "TopicSelection", "name_pattern"]


class SelectionError(ScenarioError):
    """A pattern matches none of the topics there are (a typo would silently drop data), or
    nothing is left; ``key`` names the pattern (``recording.include.0`` ...)."""


def name_pattern(topic: str) -> str:
    """The pattern that matches the topic name ``topic`` only."""
    return re.escape(topic)


@dataclass(frozen=True)
class TopicSelection:
    """Include and exclude patterns (whole-name regular expressions); see the module docstring.

    ``include`` None: every topic; ``exclude`` empty: none excluded. ``where`` names the source
    of each list in error messages (scenario keys, or command line options).
    """

    include: tuple[str, ...] | None = None
    exclude: tuple[str, ...] = ()
    where: tuple[str, str] = ("recording.include", "recording.exclude")

    @classmethod
    def of(
        cls,
        include: Sequence[str] | None,
        exclude: Sequence[str] | None,
        where: tuple[str, str] = ("recording.include", "recording.exclude"),
    ) -> TopicSelection:
        """From the lists of a scenario's ``recording`` section (None: not given)."""
        return cls(None if include is None else tuple(include), tuple(exclude or ()), where)

    @property
    def everything(self) -> bool:
        """No pattern at all: every topic is written."""
        return self.include is None and not self.exclude

    def selects(self, topic: str) -> bool:
        """Whether ``topic`` is written."""
        if self.include is not None and not any(re.fullmatch(p, topic) for p in self.include):
            return False
        return not any(re.fullmatch(p, topic) for p in self.exclude)

    def select(self, topics: Iterable[str]) -> list[str]:
        """The written ones of ``topics``, in their order."""
        return [t for t in topics if self.selects(t)]

    def check(self, topics: Iterable[str]) -> list[str]:
        """:meth:`select`, after checking that every pattern matches one of ``topics`` and that
        something is left; :class:`SelectionError` otherwise (naming the pattern and the topics
        there are)."""
        topics = list(topics)
        there = ", ".join(topics)
        for key, patterns in zip(self.where, (self.include or (), self.exclude), strict=True):
            for i, pattern in enumerate(patterns):
                if not any(re.fullmatch(pattern, t) for t in topics):
                    raise SelectionError(
                        f"{key}.{i}", f"{pattern!r} matches none of the topics ({there})"
                    )
        selected = self.select(topics)
        if not selected:
            raise SelectionError(self.where[0], f"the selection leaves no topic of ({there})")
        return selected

    @classmethod
    def of_recording(cls, recording: Any) -> TopicSelection:
        """The selection of a scenario's ``recording`` section (its ``include``/``exclude``)."""
        return cls.of(getattr(recording, "include", None), getattr(recording, "exclude", None))

    def counts(self, counts: Mapping[str, int]) -> dict[str, int]:
        """The entries of ``counts`` (topic → messages) whose topic is written."""
        return {t: n for t, n in counts.items() if self.selects(t)}
