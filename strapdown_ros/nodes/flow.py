"""Flow control of the live pipeline when it is not tied to the wall clock.

Every consumer (``bag_recorder``, the batched nodes) reports on :data:`FLOW_TOPIC` how many
messages of each input topic it has *taken* (processed) and how many it has published on each
output topic (:class:`ProgressReporter`; cumulative counts, so a lost or late report costs
nothing). ``trajectory_node`` holds a :class:`FlowGate`: it publishes message ``k`` of one of
its topics only while every consumer of that topic has taken more than ``k - window`` of them,
and publishes nothing while any consumer of a downstream topic is more than ``window`` messages
behind its producer. The backlog of every (topic, subscription) pair is therefore bounded (a few
windows along the chain) below the QoS depths, so nothing can be dropped however fast the
source goes: ``strapdown-sim run --rate-factor F`` (F > 1) and ``--unpaced`` are lossless by
construction. Protocol and figures: docs/nodes.md (Flow control).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

__all__ = [
    "DEFAULT_WINDOW",
    "FLOW_TOPIC",
    "FlowGate",
    "ProgressReporter",
    "decode_report",
    "encode_report",
]

#: The progress topic (std_msgs/String, one line per report).
FLOW_TOPIC = "/strapdown_ros/flow"
#: Messages per (topic, consumer) the source may be ahead (well below the pipeline's QoS depth
#: of 10 000: the chain trajectory → variation → imu_model → navigator stacks a few windows).
DEFAULT_WINDOW = 1000
#: Seconds between two reports of one node (while its counts change).
REPORT_PERIOD_S = 0.02
#: Seconds after which an unchanged report is sent again (a late joiner is not left waiting on
#: TRANSIENT_LOCAL delivery alone, which was seen to miss a node's report under load).
REPEAT_S = 0.5
#: Reports are cumulative: the last one of each node is all that matters, and a late joiner
#: (the trajectory subscribes after the consumers started) gets it (TRANSIENT_LOCAL).
FLOW_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def encode_report(node: str, taken: Mapping[str, int], published: Mapping[str, int]) -> str:
    """``node|/in=n,...|/out=n,...`` (topic names contain neither ``|``, ``,`` nor ``=``)."""

    def items(counts: Mapping[str, int]) -> str:
        return ",".join(f"{t}={int(n)}" for t, n in counts.items())

    return f"{node}|{items(taken)}|{items(published)}"


def decode_report(text: str) -> tuple[str, dict[str, int], dict[str, int]]:
    """Inverse of :func:`encode_report` (raises ValueError for a malformed report)."""
    node, taken, published = text.split("|")

    def counts(part: str) -> dict[str, int]:
        out: dict[str, int] = {}
        for item in filter(None, part.split(",")):
            topic, _, n = item.rpartition("=")
            out[topic] = int(n)
        return out

    return node, counts(taken), counts(published)


class ProgressReporter:
    """Publishes a node's progress on :data:`FLOW_TOPIC` at most every ``period_s``.

    ``counts()`` returns ``(taken, published)``: messages taken per input topic, published per
    output topic. :meth:`maybe_report` is cheap when nothing is due (one clock read).
    """

    def __init__(
        self,
        node: Node,
        counts: Callable[[], tuple[Mapping[str, int], Mapping[str, int]]],
        period_s: float = REPORT_PERIOD_S,
    ) -> None:
        self._name = node.get_name()
        self._counts = counts
        self._pub = node.create_publisher(String, FLOW_TOPIC, FLOW_QOS)
        self._period_s = period_s
        self._next = 0.0
        self._last = ""
        self._repeat_at = 0.0

    def maybe_report(self, now: float | None = None) -> None:
        """Publish the counts if ``period_s`` has passed and they changed."""
        now = time.monotonic() if now is None else now
        if now < self._next:
            return
        self._next = now + self._period_s
        self.report(now >= self._repeat_at)

    def report(self, repeat: bool = False) -> None:
        """Publish the counts now if they changed since the last report (or ``repeat``)."""
        taken, published = self._counts()
        text = encode_report(self._name, taken, published)
        if text != self._last or repeat:
            self._last = text
            self._repeat_at = time.monotonic() + REPEAT_S
            self._pub.publish(String(data=text))


class FlowGate:
    """The source's side: how many messages of each of its topics it may have published.

    ``limits[topic]`` is the count the source must not reach yet (it publishes message number
    ``counts[topic]`` only while ``counts[topic] < limits[topic]``); every limit is 0 until each
    of ``participants`` (node names) has reported and each of the source's topics is reported
    taken by one of them (the recorder takes them all), and while a downstream topic's backlog
    at one of its consumers exceeds ``window``.
    """

    def __init__(
        self, node: Node, topics: Iterable[str], participants: Iterable[str], window: int
    ) -> None:
        self.topics = list(topics)
        self.participants = set(participants)
        self.window = int(window)
        self.reports: dict[str, tuple[dict[str, int], dict[str, int]]] = {}
        self.limits = dict.fromkeys(self.topics, 0)
        self.behind = "no report yet from " + ", ".join(sorted(self.participants))
        self.stalled_s = 0.0
        self.stalls = 0
        self._sub = node.create_subscription(String, FLOW_TOPIC, self._on_report, FLOW_QOS)
        self._logger = node.get_logger()
        self._update()

    def _on_report(self, msg: String) -> None:
        try:
            name, taken, published = decode_report(msg.data)
        except ValueError:
            self._logger.warning(f"malformed flow report ignored: {msg.data!r}")
            return
        self.reports[name] = (taken, published)
        self._update()

    def _update(self) -> None:
        missing = self.participants - set(self.reports)
        if missing:
            self.behind = "no report yet from " + ", ".join(sorted(missing))
            self.limits = dict.fromkeys(self.topics, 0)
            return
        own = set(self.topics)
        produced: dict[str, int] = {}
        for _, published in self.reports.values():
            produced.update(published)
        limits = {t: 1 << 62 for t in self.topics}
        behind = ""
        for name, (taken, _) in self.reports.items():
            for topic, n in taken.items():
                if topic in own:
                    limits[topic] = min(limits[topic], n + self.window)
                elif topic in produced and produced[topic] - n > self.window:
                    behind = f"{name} is {produced[topic] - n} messages behind on {topic}"
        unconsumed = [t for t in self.topics if limits[t] == 1 << 62]
        if unconsumed:  # a consumer's report before its subscription: wait for the next one
            behind = "no report of taking " + ", ".join(unconsumed)
        if behind:
            limits = dict.fromkeys(self.topics, 0)
        self.behind = behind
        self.limits = limits

    def wait(self, topic: str, count: int, spin: Callable[[float], None], ok: Callable[[], bool]
             ) -> float:
        """Spin until message number ``count`` of ``topic`` may go out; return the seconds
        waited. ``ok()`` false (a signal) ends the wait early."""
        t0 = time.monotonic()
        warn_at = t0 + 30.0
        while count >= self.limits[topic] and ok():
            spin(0.005)
            if time.monotonic() > warn_at:
                self._logger.warning(f"flow control: waiting for the consumers ({self.behind})")
                warn_at += 30.0
        waited = time.monotonic() - t0
        self.stalled_s += waited
        self.stalls += 1
        return waited
