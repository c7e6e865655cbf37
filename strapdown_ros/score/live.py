"""``strapdown-sim score BAG --topic T --node CMD``: a bag played into the user's node, what it
publishes recorded, then scored (hardware-in-the-loop style; docs/score.md, "Live").

The order (each step waits for the one before, so that nothing is lost):

1. ``bag_recorder`` subscribes to the estimate topic ``T`` once a publisher appears;
2. the user's node (``CMD``, any command: its own process group, the same private
   ``ROS_DOMAIN_ID``) starts; it must create its publisher on ``T`` at start-up (the recorder's
   "subscribed to T (type, ...)" line is the sign, and gives the type, checked to be one the
   scorer reads);
3. ``bag_player`` plays the ``inputs`` topics of the bag at ``rate_factor`` once each of them has
   a subscription (the node's: the start-up handshake of bag_player ``wait_for_subscribers``);
4. after the play, ``linger_s`` for the node's last outputs, then SIGINT to the node's process
   group (what Ctrl-C does), then SIGTERM to the recorder, which closes the bag.

Errors (:class:`LiveScoreError`, the log of the process at fault attached): the command not
found, the node exiting before the end of the play (any status), no publisher on ``T``, a
publisher of another type, no subscription to an input, nothing recorded. Ctrl-C or SIGTERM to
``strapdown-sim`` stops the node, the player and the recorder (the bag is closed) and leaves no
process running.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from strapdown_ros.launch_logic import LaunchError, parse_command
from strapdown_ros.pipeline.processes import (
    Child,
    Children,
    PipelineError,
    _die_with_parent,
    check_out,
    list_param,
)
from strapdown_ros.pipeline.run import STARTUP_TIMEOUT_S, say_to_stderr
from strapdown_ros.score.estimate_types import ESTIMATE_TYPES

__all__ = [
    "LiveInputError",
    "LiveRecording",
    "LiveScoreError",
    "UserNode",
    "bag_topic_types",
    "record_live_estimate",
]

#: Seconds the user's node has after SIGINT, then after SIGTERM, before SIGKILL.
NODE_STOP_GRACE_S = 5.0
#: Name of the user's node in the logs directory (``<out>.logs/node.log``).
NODE_LOG_NAME = "node"


class LiveScoreError(PipelineError):
    """The live run cannot go on; the message says why, ``log`` is the log at fault."""


class LiveInputError(LiveScoreError):
    """Bad input found before the user's node started (exit status 2): an unknown command, an
    input topic the bag does not have."""


@dataclass
class LiveRecording:
    """What a live run recorded: the bag, the estimate topic's type and count, the logs."""

    out: Path
    topic: str
    msgtype: str
    count: int
    played: dict[str, int] = field(default_factory=dict)
    log_dir: Path | None = None
    elapsed_s: float = 0.0


class UserNode:
    """The user's command, started in a process group of its own (a shell wrapper's children
    are signalled with it), its output in ``<log_dir>/node.log``."""

    def __init__(self, command: str, env: dict[str, str], log_dir: Path) -> None:
        self.args = command_args(command)
        self.command = command
        self.log_path = log_dir / f"{NODE_LOG_NAME}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 - closed in close()
        preexec = _die_with_parent if sys.platform.startswith("linux") else None
        try:
            self.proc = subprocess.Popen(
                self.args, env=env, stdin=subprocess.DEVNULL, stdout=self._log,
                stderr=subprocess.STDOUT, preexec_fn=preexec, process_group=0,
            )  # fmt: skip
        except FileNotFoundError:
            self._log.close()
            raise LiveInputError(
                f"--node {command!r}: command not found: {self.args[0]}"
            ) from None
        except PermissionError:
            self._log.close()
            raise LiveInputError(
                f"--node {command!r}: {self.args[0]} is not executable"
            ) from None

    def poll(self) -> int | None:
        return self.proc.poll()

    @property
    def log(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def stop(self) -> None:
        """SIGINT to the process group, SIGTERM after :data:`NODE_STOP_GRACE_S`, SIGKILL after
        as long again; every process of the group is gone afterwards."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            if self.proc.poll() is None:
                self._signal_group(sig)
                try:
                    self.proc.wait(timeout=NODE_STOP_GRACE_S)
                except subprocess.TimeoutExpired:
                    continue
        self._signal_group(signal.SIGKILL)  # the group's other processes, if any are left
        if self.proc.poll() is None:
            self.proc.wait()

    def close(self) -> None:
        self._log.close()


def command_args(command: str) -> list[str]:
    """``command`` split as a POSIX shell would (no shell runs it); LiveInputError when it is
    empty or its program is not found."""
    try:
        return parse_command("--node ", command, "--node: the command is empty")
    except LaunchError as exc:
        raise LiveInputError(str(exc)) from None


def bag_topic_types(bag: str | os.PathLike[str]) -> dict[str, str]:
    """Topic → type of the bag's metadata (BagReadError for a bag that does not read)."""
    from strapdown_ros.bag.reader import check_bag

    info, _ = check_bag(bag)
    entries = info.get("topics_with_message_count") or []
    return {e["topic_metadata"]["name"]: e["topic_metadata"]["type"] for e in entries}


def record_live_estimate(
    bag: str | os.PathLike[str],
    node_command: str,
    topic: str,
    out: str | os.PathLike[str],
    *,
    inputs: Sequence[str],
    rate_factor: float = 1.0,
    force: bool = False,
    domain_id: int | None = None,
    startup_timeout_s: float = 60.0,
    linger_s: float = 2.0,
    timeout_s: float | None = None,
    progress: bool = True,
) -> LiveRecording:
    """Play ``inputs`` of ``bag`` into ``node_command``, record its ``topic`` into ``out``.

    Raises :class:`LiveScoreError` (see the module docstring), :class:`FileExistsError` when
    ``out`` exists and ``force`` is false.
    """
    t_start = time.monotonic()
    bag = Path(bag).resolve()
    out = Path(out).absolute()
    types = bag_topic_types(bag)
    _check_inputs(types, inputs, topic, bag)
    command_args(node_command)
    check_out(out, force)
    if timeout_s is None:
        timeout_s = _play_duration_s(bag, inputs) / max(rate_factor, 1e-3) + 120.0
    say = say_to_stderr("score", progress)
    children = Children(out, domain_id)
    node: UserNode | None = None
    try:
        say(f"ROS_DOMAIN_ID={children.domain}; logs in {children.log_dir}")
        recorder = children.start(
            "bag_recorder", f"output:={out}", f"force:={str(force).lower()}",
            list_param("topics", [topic]), "progress_period_s:=0.0",
        )  # fmt: skip
        say(f"bag_recorder started (pid {recorder.proc.pid})")
        recorder.wait_for("recording 1 topic", STARTUP_TIMEOUT_S, children.started)
        node = UserNode(node_command, children.env, children.log_dir)
        say(f"node started (pid {node.proc.pid}): {node_command}")
        msgtype = _wait_for_publisher(recorder, node, topic, startup_timeout_s)
        say(f"the node publishes {topic} ({msgtype}); playing {', '.join(inputs)} of {bag}")
        player = children.start(
            "bag_player", f"bag:={bag}", f"rate_factor:={float(rate_factor)}",
            list_param("topics", list(inputs)), "wait_for_subscribers:=1",
            f"wait_timeout_s:={float(startup_timeout_s)}", "qos_depth:=10000",
        )  # fmt: skip
        say(f"bag_player started (pid {player.proc.pid})")
        _wait_for_play(children, recorder, node, player, timeout_s)
        say(f"played; {linger_s:g} s for the node's last outputs, then stopping it")
        _linger(children, recorder, node, linger_s)
        node.stop()
        recorder.stop()
        _wait_for_recorder(recorder, timeout=30.0)
    except BaseException:
        if node is not None:
            node.stop()
        children.stop_all()
        raise
    finally:
        children.reap()
        if node is not None:
            node.close()
    count = _recorded_count(out, topic)
    played = _played_counts(player.log_path.read_text(errors="replace"))
    if count == 0:
        raise LiveScoreError(
            f"the node published nothing on {topic} while {sum(played.values())} messages "
            f"were played ({', '.join(f'{t} {n}' for t, n in played.items())})",
            node.log_path.read_text(errors="replace"),
        )
    say(f"recorded {count} messages on {topic} into {out}")
    return LiveRecording(
        out=out, topic=topic, msgtype=msgtype, count=count, played=played,
        log_dir=children.log_dir, elapsed_s=time.monotonic() - t_start,
    )  # fmt: skip


def _check_inputs(types: dict[str, str], inputs: Sequence[str], topic: str, bag: Path) -> None:
    if not inputs:
        raise LiveInputError("--input: name the topics of the bag the node subscribes to")
    missing = [t for t in inputs if t not in types]
    if missing:
        raise LiveInputError(
            f"{bag} has no topic {', '.join(missing)}; it has: {', '.join(sorted(types))}"
        )
    if topic in inputs:
        raise LiveInputError(f"{topic} is the estimate topic: it cannot be an --input too")
    if len(set(inputs)) != len(inputs):
        raise LiveInputError("--input: a topic is named twice")


def _play_duration_s(bag: Path, inputs: Sequence[str]) -> float:
    """Seconds of log time the player covers (the bag's span)."""
    from strapdown_ros.bag.reader import check_bag

    info, _ = check_bag(bag)
    duration = info.get("duration") or {}
    return float(duration.get("nanoseconds", 0)) * 1e-9


def _wait_for_publisher(recorder: Child, node: UserNode, topic: str, timeout_s: float) -> str:
    """The type of the node's publisher on ``topic`` (the recorder subscribed to it)."""
    pattern = re.compile(rf"subscribed to {re.escape(topic)} \(([^,)]+)")
    refused = re.compile(rf"{re.escape(topic)}: (cannot record|publishers offer) .*")
    deadline = time.monotonic() + timeout_s
    while True:
        log = recorder.log
        match = pattern.search(log)
        if match:
            break
        problem = refused.search(log)
        if problem:
            raise LiveScoreError(
                f"the node's {topic} cannot be recorded: {problem.group(0)}; the scorer reads "
                + ", ".join(ESTIMATE_TYPES), node.log
            )
        code = node.poll()
        if code is not None:
            raise LiveScoreError(
                f"the node exited with status {code} during start-up (before it published "
                f"{topic})", node.log
            )
        if recorder.poll() is not None:
            raise LiveScoreError(
                f"bag_recorder exited with status {recorder.poll()}", recorder.log
            )
        if time.monotonic() > deadline:
            raise LiveScoreError(
                f"the node has no publisher on {topic} after {timeout_s:g} s (is --topic "
                "right? the node must create its publisher at start-up)", node.log
            )
        time.sleep(0.05)
    msgtype = match.group(1)
    if msgtype not in ESTIMATE_TYPES:
        raise LiveScoreError(
            f"the node publishes {topic} as {msgtype}; the scorer reads "
            + ", ".join(ESTIMATE_TYPES), node.log
        )
    return msgtype


def _wait_for_play(
    children: Children, recorder: Child, node: UserNode, player: Child, timeout_s: float
) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        code = player.poll()
        if code == 0:
            return
        if code is not None:
            log = player.log
            if "waiting for subscriptions" in log or "timeout after" in log:
                short = re.search(r"waiting for subscriptions on (.*)", log)
                raise LiveScoreError(
                    "the node did not subscribe to every --input in time: "
                    + (short.group(1) if short else "see the player's log"), node.log
                )
            raise LiveScoreError(f"bag_player exited with status {code}", log)
        _check_alive(recorder, node, "while the bag was playing")
        if time.monotonic() > deadline:
            raise LiveScoreError(f"the play did not finish within {timeout_s:g} s", player.log)
        time.sleep(0.05)


def _linger(children: Children, recorder: Child, node: UserNode, linger_s: float) -> None:
    end = time.monotonic() + linger_s
    while time.monotonic() < end:
        if node.poll() == 0:  # done by itself after the play: fine
            return
        _check_alive(recorder, node, "after the play")
        time.sleep(0.05)


def _check_alive(recorder: Child, node: UserNode, when: str) -> None:
    code = node.poll()
    if code is not None and (code != 0 or when != "after the play"):
        raise LiveScoreError(f"the node exited with status {code} {when}", node.log)
    if recorder.poll() is not None:
        raise LiveScoreError(f"bag_recorder exited with status {recorder.poll()}", recorder.log)


def _wait_for_recorder(recorder: Child, timeout: float) -> None:
    try:
        recorder.proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        raise LiveScoreError(
            f"bag_recorder did not close the bag within {timeout:g} s", recorder.log
        ) from None
    recorder.poll()
    if recorder.proc.returncode != 0:
        raise LiveScoreError(
            f"bag_recorder exited with status {recorder.proc.returncode}", recorder.log
        )


def _recorded_count(out: Path, topic: str) -> int:
    types_counts = {}
    from strapdown_ros.bag.reader import check_bag

    info, _ = check_bag(out)
    for e in info.get("topics_with_message_count") or []:
        types_counts[e["topic_metadata"]["name"]] = int(e.get("message_count", 0))
    return types_counts.get(topic, 0)


def _played_counts(log: str) -> dict[str, int]:
    """Topic → messages played, from the player's summary lines (``  /topic: N``)."""
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^\s+(/\S+): (\d+)$", log, re.M)
            if "(clock)" not in m.group(0)}  # fmt: skip
