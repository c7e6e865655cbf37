"""What ``launch/score_live.launch.py`` does, decided in plain Python (standard library only).

The launch file plays a bag into the user's node (``node:=`` a command) and scores what it
publishes, like ``strapdown-sim score --node`` (:mod:`strapdown_ros.score.live`), as launch
actions: :func:`plan_score_live` checks the arguments and gives the commands and parameters;
:class:`LiveSequence` takes the processes' output lines and exits and answers with the next
steps, which the launch file turns into actions:

1. ``bag_recorder`` (the estimate topic) and the user's node start;
2. the recorder's ``subscribed to TOPIC (TYPE`` line (the node's publisher was discovered; the
   type checked) starts ``bag_player`` (it waits for the node's subscriptions to the inputs);
3. the player's exit 0 → after ``linger_s``, SIGINT to the node; the node's exit → SIGINT to
   the recorder (it closes the bag); the recorder's exit 0 → ``strapdown-sim score`` on the
   recording; its exit → the launch shuts down.

Any other exit (the node before the end of the play, a non-zero status) is a
:class:`~strapdown_ros.launch_logic.NodeFailedError` with the reason: launch logs it, stops
everything and exits 1. On Ctrl-C launch stops every process itself; exits during the shutdown
give no step and no reason.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from strapdown_ros.launch_logic import (
    LaunchError,
    NodeFailedError,
    parse_bool,
    parse_command,
    parse_float,
)
from strapdown_ros.score.estimate_types import ESTIMATE_TYPES

__all__ = ["LiveSequence", "ScoreLivePlan", "Step", "plan_score_live"]

#: The processes' names in the steps.
NODE, PLAYER, RECORDER, SCORE = "node", "bag_player", "bag_recorder", "score"


@dataclass(frozen=True)
class Step:
    """One thing to do: ``start`` a process (``bag_player``, ``score``), ``signal`` one
    (``sig`` "SIGINT"), both possibly ``after`` seconds, or ``shutdown`` (``reason``)."""

    kind: str
    target: str = ""
    sig: str = ""
    after_s: float = 0.0
    reason: str = ""


@dataclass
class ScoreLivePlan:
    """The commands and parameters of one live score."""

    node: list[str]
    recorder: dict[str, Any]
    player: dict[str, Any]
    score: list[str]
    record_to: Path
    out: Path
    topic: str
    linger_s: float


def plan_score_live(
    bag: str, node: str, topic: str, inputs: str, out: str = "", *, force: str | bool = False,
    rate_factor: str | float = 1.0, linger_s: str | float = 2.0, scenario: str = "",
    strapdown_sim: str = "strapdown-sim", startup_timeout_s: float = 60.0,
) -> ScoreLivePlan:  # fmt: skip
    """The plan of the launch arguments; :class:`LaunchError` for one that cannot work.

    ``inputs``: the bag's topics the node subscribes to, separated by commas or spaces; ``out``
    (default ``BAG/score``): the score's directory, the recording in ``out/estimate``.
    """
    force = parse_bool("force", str(force))
    rate = parse_float("rate_factor", str(rate_factor))
    linger = parse_float("linger_s", str(linger_s))
    bag_dir = Path(bag).absolute()
    if not (bag_dir / "metadata.yaml").is_file():
        raise LaunchError(f"bag:={bag}: not a bag directory (no metadata.yaml)")
    command = parse_command("node:=", node, "node:= is required: the command that runs your node")
    if not topic.startswith("/"):
        raise LaunchError(f"topic:={topic!r}: the estimate topic, an absolute name (/name)")
    topics = [t for t in re.split(r"[,\s]+", inputs) if t]
    if not topics:
        raise LaunchError("inputs:= is required: the bag's topics your node subscribes to")
    if topic in topics:
        raise LaunchError(f"{topic} is the estimate topic: it cannot be an input too")
    if rate <= 0:
        raise LaunchError(f"rate_factor:={rate_factor}: must be > 0 (the node runs in real time)")
    out_dir = Path(out).absolute() if out else bag_dir / "score"
    record_to = out_dir / "estimate"
    if record_to.exists() and not force:
        raise LaunchError(f"{record_to} exists already (force:=true replaces it)")
    recorder = {"output": str(record_to), "force": force, "topics": [topic],
                "progress_period_s": 0.0}  # fmt: skip
    player = {"bag": str(bag_dir), "rate_factor": rate, "topics": topics,
              "wait_for_subscribers": 1, "wait_timeout_s": float(startup_timeout_s),
              "qos_depth": 10000}  # fmt: skip
    score = [strapdown_sim, "score", str(bag_dir), "--topic", topic, "--estimate-bag",
             str(record_to), "--out", str(out_dir)]  # fmt: skip
    if scenario:
        score += ["--scenario", str(Path(scenario).absolute())]
    return ScoreLivePlan(command, recorder, player, score, record_to, out_dir, topic, linger)


@dataclass
class LiveSequence:
    """The order of the live score (module docstring): output lines and exits in, steps out."""

    plan: ScoreLivePlan
    exited: dict[str, int] = field(default_factory=dict)
    player_started: bool = False

    def on_output(self, name: str, text: str) -> list[Step]:
        """Steps for a piece of output of process ``name``."""
        if name != RECORDER or self.player_started:
            return []
        match = re.search(rf"subscribed to {re.escape(self.plan.topic)} \(([^,)]+)", text)
        if match is None:
            return []
        msgtype = match.group(1)
        if msgtype not in ESTIMATE_TYPES:
            raise NodeFailedError(
                f"the node publishes {self.plan.topic} as {msgtype}; the scorer reads "
                + ", ".join(ESTIMATE_TYPES)
            )
        self.player_started = True
        return [Step("start", PLAYER)]

    def on_exit(self, name: str, returncode: int, shutting_down: bool) -> list[Step]:
        """Steps for the exit of process ``name``; NodeFailedError when it ends the run."""
        self.exited[name] = returncode
        if shutting_down:
            return []
        if name == PLAYER:
            if returncode != 0:
                raise NodeFailedError(
                    f"bag_player exited with status {returncode} (the node did not subscribe "
                    "to every input in time, or an input is not in the bag: its log says)"
                )
            if NODE in self.exited:
                return [Step("signal", RECORDER, "SIGINT")]
            return [Step("signal", NODE, "SIGINT", after_s=self.plan.linger_s)]
        if name == NODE:
            if PLAYER not in self.exited:
                raise NodeFailedError(
                    f"the node exited with status {returncode} before the bag was played"
                )
            if returncode not in (0, -2) and returncode != 130:
                raise NodeFailedError(f"the node exited with status {returncode}")
            return [Step("signal", RECORDER, "SIGINT")]
        if name == RECORDER:
            if returncode != 0 or NODE not in self.exited:
                raise NodeFailedError(f"bag_recorder exited with status {returncode}")
            return [Step("start", SCORE)]
        if name == SCORE:
            if returncode != 0:
                raise NodeFailedError(
                    f"strapdown-sim score exited with status {returncode} (its message says "
                    "why: nothing recorded, a missing frame, ...)"
                )
            return [Step("shutdown", reason=f"scored into {self.plan.out}")]
        return []
