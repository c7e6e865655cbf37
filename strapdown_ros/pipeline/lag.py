"""Who falls behind in a real-time ``run``: the nodes' and the recorder's lag lines, attributed.

The recorder (``lag_warning_s``) logs ``behind real time: /topic 1.23 s, ...``: how far each
topic's data is behind the wall clock at the recorder, which includes everything upstream of
it. The trajectory node logs ``behind real time: publishing 0.80 s late``. :class:`LagWatch`
reads both logs as they grow and says, per node, how far its outputs are behind and how much of
that it added itself (its outputs' lag minus its inputs'); what the source's own topics lag
beyond the source's lateness is the recorder's.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from pathlib import Path

from strapdown_ros.plan.chain import LiveNode

__all__ = ["LagWatch", "attribute"]

_TOPICS = re.compile(r"behind real time: (/[^\n]*)")
_SOURCE = re.compile(r"behind real time: publishing ([0-9.]+) s late")
_ITEM = re.compile(r"(/\S+) ([0-9.]+) s")


def attribute(lags: dict[str, float], nodes: Sequence[LiveNode], source_late_s: float) -> str:
    """One line: how far each node's outputs are behind at the recorder and how much of it the
    node added (its outputs' lag minus its inputs'); the source's topics' lag beyond the
    source's own lateness is the recorder's (and the middleware's)."""
    parts = []
    for k, node in enumerate(nodes):
        out = [lags[t] for t in node.published if t in lags]
        if not out:
            continue
        behind = max(out)
        if k == 0:  # the source: late itself, the rest is on the receiving side
            parts.append(f"{node.executable} {source_late_s:.1f} s late publishing")
            parts.append(f"bag_recorder {max(behind - source_late_s, 0.0):.1f} s behind it")
            continue
        upstream = max([lags.get(t, 0.0) for t in node.inputs] or [0.0])
        parts.append(f"{node.node_name} +{max(behind - upstream, 0.0):.1f} s")
    worst = max(lags.values(), default=0.0)
    return (
        f"behind real time: up to {worst:.1f} s at the recorder ({max(lags, key=lags.get)}); "
        + ", ".join(parts) + " (+: added by the node: its outputs' lag minus its inputs')"
    )


class LagWatch:
    """Follows the recorder's and the source's logs; ``poll()`` says each new lag line."""

    def __init__(
        self, recorder_log: Path, source_log: Path, nodes: Sequence[LiveNode],
        say: Callable[[str], None],
    ) -> None:  # fmt: skip
        self.logs = {"recorder": recorder_log, "source": source_log}
        self.offsets = dict.fromkeys(self.logs, 0)
        self.nodes = list(nodes)
        self.say = say
        self.source_late_s = 0.0
        #: every line said (for the result)
        self.lines: list[str] = []

    def _new_text(self, key: str) -> str:
        try:
            with open(self.logs[key], "rb") as f:
                f.seek(self.offsets[key])
                data = f.read()
        except OSError:
            return ""
        cut = data.rfind(b"\n") + 1  # whole lines only
        self.offsets[key] += cut
        return data[:cut].decode(errors="replace")

    def poll(self) -> None:
        for m in _SOURCE.finditer(self._new_text("source")):
            self.source_late_s = float(m.group(1))
        for m in _TOPICS.finditer(self._new_text("recorder")):
            lags = {t: float(s) for t, s in _ITEM.findall(m.group(1))}
            line = attribute(lags, self.nodes, self.source_late_s)
            self.lines.append(line)
            self.say(line)
