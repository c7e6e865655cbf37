"""The report's table of navigation solutions: each with the IMU topic it consumes, ideal or
measured, and its truth.

* a **navigator** in the bag (a ``P/odom`` or ``P/error/*`` under a prefix naming the
  navigator): its IMU from the bag's ``custom_data`` (``navigator.imu_topic``, or
  ``<prefix>.imu_topic``), written by ``generate`` and the recorder;
* an **aided filter** in the bag (``P/odom`` + ``P/nees``, :mod:`strapdown_ros.report.aided`):
  the filter runs only on the ``imu_errors`` output of the reference IMU (``aided.imu_topic``,
  :func:`strapdown_ros.config.aided.check_aided`), so its IMU is the measured IMU whose ideal
  twin is ``/reference/imu``;
* a **free-inertial** solution the report computes (:mod:`strapdown_ros.report.free_inertial`).

An IMU is *ideal* when it is the exact stream ``P/imu`` of a truth ``P/odom``, *measured* when
it is an error model's output (``P/imu_measured``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from strapdown_ros.report.data import BagData, is_navigator

__all__ = ["REFERENCE_IMU", "Solution", "bag_solutions", "imu_kind", "solution_table"]

#: The IMU the aided filter's error model measures (``recording.topics.reference_imu``).
REFERENCE_IMU = "/reference/imu"
#: The IMU a transfer-alignment slave integrates (the variation stream's, ideal or measured).
VARIATION_IMU = "/variation/imu"


@dataclass(frozen=True)
class Solution:
    """One navigation solution and its input."""

    name: str  #: its prefix (in the bag) or a label (computed by the report)
    origin: str  #: ``navigator``, ``aided filter`` or ``free-inertial (report)``
    imu_topic: str | None  #: None: not recorded
    kind: str  #: ``ideal``, ``measured`` or ``unknown``
    truth_topic: str | None
    source: str  #: how the IMU topic is known


def imu_kind(bag: BagData, topic: str | None) -> str:
    """``measured`` (an error model's output), ``ideal`` (a stream's exact ``P/imu``) or
    ``unknown``."""
    if topic is None:
        return "unknown"
    if topic.endswith("/imu_measured") or any(
        m.measured.topic == topic for m in bag.measured.values()
    ):
        return "measured"
    if any(d.topic == topic for d in bag.imus.values()):
        return "ideal"
    return "unknown"


def _truth_of(bag: BagData, imu_topic: str | None) -> str | None:
    if imu_topic is None:
        return None
    prefix = imu_topic.rpartition("/")[0]
    topic = f"{prefix}/odom"
    return topic if topic in bag.contents.topics else None


def _aided_imu(bag: BagData) -> tuple[str | None, str]:
    for m in bag.measured.values():
        if m.ideal is not None and m.ideal.topic == REFERENCE_IMU:
            return m.measured.topic, (
                f"the filter runs on the imu_errors output of `{REFERENCE_IMU}` (aided.imu_topic)"
            )
    return None, f"the imu_errors output of `{REFERENCE_IMU}` is not in the bag"


def _transfer_imu(bag: BagData) -> tuple[str | None, str]:
    for m in bag.measured.values():
        if m.ideal is not None and m.ideal.topic == VARIATION_IMU:
            return m.measured.topic, (
                f"the slave runs on the variation IMU: the imu_errors output of `{VARIATION_IMU}` "
                "(transfer_alignment.imu_topic)")  # fmt: skip
    if VARIATION_IMU in bag.contents.topics:
        return VARIATION_IMU, "the slave runs on the variation IMU (transfer_alignment.imu_topic)"
    return None, f"`{VARIATION_IMU}` is not in the bag"


def bag_solutions(bag: BagData, aided: Sequence[str] = (),
                  transfer: Sequence[str] = ()) -> list[Solution]:  # fmt: skip
    """The navigators, aided filters (prefixes ``aided``) and transfer filters (``transfer``)
    of the bag, in that order."""
    cd = bag.contents.custom_data
    owners = [p for p in bag.streams if is_navigator(p)]
    owners += [p for p in bag.errors if p not in owners and p not in (*aided, *transfer)]
    out = []
    for owner in owners:
        key = owner.strip("/")
        topic = cd.get(f"{key}.imu_topic") or (
            cd.get("navigator.imu_topic") if key == "navigator" else None
        )
        source = f"bag metadata `{key}.imu_topic`" if topic else (
            f"not recorded (no `{key}.imu_topic` in the bag metadata)")  # fmt: skip
        out.append(Solution(owner, "navigator", topic, imu_kind(bag, topic),
                            _truth_of(bag, topic), source))  # fmt: skip
    for prefix in aided:
        topic, source = _aided_imu(bag)
        kind = imu_kind(bag, topic) if topic else "measured"
        out.append(Solution(prefix, "aided filter", topic, kind, "/reference/odom", source))
    for prefix in transfer:
        topic, source = _transfer_imu(bag)
        out.append(Solution(prefix, "transfer alignment (slave)", topic, imu_kind(bag, topic),
                            "/variation/odom", source))  # fmt: skip
    return out


def solution_table(solutions: Sequence[Solution]) -> list[str]:
    """Markdown table: solution, what it is, IMU topic, ideal or measured, truth, source."""

    def cell(x: str | None, fallback: str = "—") -> str:
        return f"`{x}`" if x else fallback

    head = ["solution", "made by", "IMU consumed", "ideal or measured", "truth", "IMU known from"]
    rows = [
        [cell(s.name), s.origin, cell(s.imu_topic, "not recorded"), s.kind,
         cell(s.truth_topic), s.source]
        for s in solutions
    ]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    return lines + ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]
