"""What ``strapdown-sim run`` and ``replay --into navigator`` report: counts, losses,
throughput, and the comparison with the offline navigator."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from strapdown_ros.topics import topic_lines

__all__ = ["PipelineResult", "ReplayResult", "read_trajectory_summary"]


@dataclass
class PipelineResult:
    """What ``run`` recorded."""

    out: Path
    counts: dict[str, int] = field(default_factory=dict)
    expected: dict[str, int] = field(default_factory=dict)
    elapsed_s: float = 0.0
    duration_s: float = 0.0
    domain_id: int = 0
    rate_factor: float = 1.0
    flow_control: bool = False
    #: Wall seconds from the trajectory node's first to its last message (0: unknown).
    publish_s: float = 0.0
    #: Seconds the trajectory node waited for its consumers (flow control).
    stalled_s: float = 0.0
    #: The trajectory node's pacing line (paced runs without flow control).
    pacing: str = ""
    #: CPU seconds (user + system) of each child process, start-up included.
    cpu_s: dict[str, float] = field(default_factory=dict)
    #: CPU seconds of each child when the source started publishing (its start-up; Linux).
    cpu_start_s: dict[str, float] = field(default_factory=dict)

    @property
    def cpu_run_s(self) -> dict[str, float]:
        """CPU seconds of each child from the start of publishing to its exit (start-up
        excluded; :attr:`cpu_s` where the start is not known)."""
        return {n: s - self.cpu_start_s.get(n, 0.0) for n, s in self.cpu_s.items()}

    @property
    def lost(self) -> dict[str, int]:
        """Topics with fewer (or more) messages than the scenario produces: topic → difference."""
        return {
            t: n - self.counts.get(t, 0)
            for t, n in self.expected.items()
            if self.counts.get(t, 0) != n
        }

    @property
    def ok(self) -> bool:
        """Every expected topic has its count (zero loss)."""
        return not self.lost

    def format(self) -> str:
        lines = [
            f"bag:       {self.out}",
            f"duration:  {self.duration_s:.3f} s of data in {self.elapsed_s:.2f} s "
            f"(ROS_DOMAIN_ID={self.domain_id})",
            "topics:    recorded / expected",
        ]
        cells = {}
        for topic, n in self.expected.items():
            got = self.counts.get(topic, 0)
            cells[topic] = f"{got:>9d} / {n:<9d}" + ("" if got == n else "   <-- MISMATCH")
        lines += topic_lines(cells)
        extra = sorted(set(self.counts) - set(self.expected))
        lines += [f"  {t}: {self.counts[t]} (not expected)" for t in extra]
        lines.append("zero loss" if not self.lost else f"LOST OR EXTRA: {self.lost}")
        lines.append(self.throughput())
        return "\n".join(lines)

    def throughput(self) -> str:
        """What the run reached: messages and IMU cycles per second of publishing, speed-up."""
        mode = (
            "unpaced" if self.rate_factor <= 0 else f"rate_factor {self.rate_factor:g}"
        ) + (", flow control" if self.flow_control else ", wall-clock pace")
        if self.publish_s <= 0:
            return f"throughput: unknown ({mode})"
        total = sum(self.counts.values())
        text = (
            f"throughput: {total / self.publish_s:,.0f} msgs/s recorded, "
            f"{self.duration_s / self.publish_s:.2f}x real time ({mode}; {self.duration_s:.3f} s "
            f"of data published in {self.publish_s:.2f} s"
        )
        if self.flow_control:
            text += f", {self.stalled_s:.2f} s of it waiting for the consumers"
        text += ")"
        if self.pacing:
            text += f"\npacing:    {self.pacing}"
        if self.cpu_s:
            text += "\ncpu:       " + ", ".join(
                f"{n} {s:.1f} s" for n, s in self.cpu_s.items()
            ) + f" (total {sum(self.cpu_s.values()):.1f} s, start-up included)"
        return text


def read_trajectory_summary(path: Path, result: PipelineResult) -> None:
    """Fill ``publish_s``, ``stalled_s`` and ``pacing`` from trajectory_node's summary."""
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return
    if m := re.search(r"s of data in ([0-9.]+) s of wall time", text):
        result.publish_s = float(m.group(1))
    if m := re.search(r"flow control: waited ([0-9.]+) s", text):
        result.stalled_s = float(m.group(1))
    if m := re.search(r"(max lateness [^\n]*)", text):
        result.pacing = m.group(1)


@dataclass
class ReplayResult:
    """What ``replay --into navigator`` recorded and how it compares with the offline run."""

    out: Path
    counts: dict[str, int] = field(default_factory=dict)
    mismatches: dict[str, str] = field(default_factory=dict)
    reference: str = ""
    elapsed_s: float = 0.0

    @property
    def ok(self) -> bool:
        """Every recorded topic is identical to the offline navigator's."""
        return not self.mismatches

    def format(self) -> str:
        lines = [f"bag:       {self.out}", f"compared with: {self.reference}"]
        for topic, n in self.counts.items():
            lines.append(f"  {topic}: {n} messages  {self.mismatches.get(topic, 'identical')}")
        lines.append(
            "identical to the offline navigator"
            if not self.mismatches
            else f"DIFFERENT from the offline navigator: {self.mismatches}"
        )
        return "\n".join(lines)
