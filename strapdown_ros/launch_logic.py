"""What ``launch/pipeline.launch.py`` starts, decided in plain Python (no ``launch`` import).

The launch file's ``OpaqueFunction`` calls :func:`plan_launch_with` (:func:`plan_launch` in the
nodes' Python, below) with its arguments (scenario, out, force, duration_s, rate_factor) and
turns the :class:`LaunchPlan` into ``Node`` actions and one exit handler per node. Everything
that can be wrong is decided here, before any process starts, so it is testable without
``launch``/``launch_ros`` (which are not on PyPI):

* the nodes the scenario needs and, for each, ``subscribers_per_topic`` (the start-up
  handshake: every output topic waits for the recorder plus the downstream nodes) computed from
  the scenario's live graph, as ``strapdown-sim run`` computes them (:func:`pipeline_counts`;
  any scenario, not only the one ``config/params.yaml`` was written for);
* the output directory: absolute; by default a new time-stamped one in the current directory
  (``strapdown_run_YYYY_MM_DD-HH_MM_SS``, like ``ros2 bag record``'s ``rosbag2_...``), never an
  existing one; an existing ``out:=`` is refused unless ``force:=true`` (:class:`LaunchError`,
  before anything starts);
* :func:`exit_reason`: the shutdown reason when a node exits with an error (the launch file then
  shuts the whole launch down at once instead of leaving the others to their timeouts).

The plan is computed by the Python that runs the nodes, not by the one running ``ros2 launch``:
on a Jazzy system install ``ros2`` is ``/usr/bin/python3`` (noble's pydantic 1.10, no numba),
while the nodes run in the venv of the documented pip step (their executables' ``#!`` line).
The launch file calls :func:`plan_launch_with` (this module's stdlib part only), which runs
``python -m strapdown_ros.launch_logic`` (:func:`main`, JSON out) under
:func:`node_interpreter`; that child checks the libraries first (the fix is the launch's error).
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "LaunchError",
    "LaunchPlan",
    "NodeFailedError",
    "NodePlan",
    "default_out",
    "exit_reason",
    "main",
    "node_interpreter",
    "pipeline_counts",
    "plan_launch",
    "plan_launch_with",
    "resolve_out",
]

#: Prefix of the default output directory.
OUT_PREFIX = "strapdown_run"
#: Exit statuses of the nodes (those of strapdown-sim).
EXIT_MEANING = {1: "failure while running", 2: "invalid argument, parameter or scenario"}
#: The node executable whose interpreter plans the launch (all are installed with the same one).
PLANNER_EXECUTABLE = "trajectory_node"
#: Seconds the planning child may take (it loads the scenario: about 1 s).
PLAN_TIMEOUT_S = 120.0


class LaunchError(ValueError):
    """A launch argument that cannot work; the message says which and what to do."""


class NodeFailedError(RuntimeError):
    """A node exited with an error: raised in the launch's exit handler, it shuts the launch
    down (launch logs it as the reason and exits with status 1)."""


@dataclass(frozen=True)
class NodePlan:
    """One node of the launch: its ROS node name, the parameters set over params.yaml and its
    executable (default: ``name``; another when an executable runs more than once, as
    ``imu_model_node`` does, once per IMU error model)."""

    name: str
    parameters: dict[str, Any]
    executable: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "executable", self.executable or self.name)


@dataclass
class LaunchPlan:
    """What the launch starts."""

    out: Path
    nodes: list[NodePlan] = field(default_factory=list)

    def node(self, name: str) -> NodePlan:
        return next(n for n in self.nodes if n.name == name)

    def to_json(self) -> str:
        return json.dumps({"out": str(self.out), "nodes": [asdict(n) for n in self.nodes]})

    @classmethod
    def from_json(cls, text: str) -> LaunchPlan:
        data = json.loads(text)
        nodes = [NodePlan(n["name"], n["parameters"], n.get("executable", ""))
                 for n in data["nodes"]]  # fmt: skip
        return cls(Path(data["out"]), nodes)


def default_out(cwd: str | os.PathLike[str] | None = None, now: float | None = None) -> Path:
    """``<cwd>/strapdown_run_YYYY_MM_DD-HH_MM_SS`` (local time), with ``_2``, ``_3``... if that
    exists already (two launches in the same second)."""
    base = Path(cwd if cwd is not None else os.getcwd()).absolute()
    stamp = time.strftime("%Y_%m_%d-%H_%M_%S", time.localtime(now))
    out = base / f"{OUT_PREFIX}_{stamp}"
    k = 2
    while out.exists():
        out = base / f"{OUT_PREFIX}_{stamp}_{k}"
        k += 1
    return out


def resolve_out(out: str, force: bool, cwd: str | os.PathLike[str] | None = None) -> Path:
    """The absolute output directory of ``out:=`` (empty: :func:`default_out`).

    Raises :class:`LaunchError` when it exists and ``force`` is false.
    """
    if not out.strip():
        return default_out(cwd)
    path = Path(out).expanduser()
    if not path.is_absolute():
        path = Path(cwd if cwd is not None else os.getcwd()).absolute() / path
    if path.exists() and not force:
        raise LaunchError(
            f"out:={out}: {path} exists already; choose another out:=, leave out:= unset for a "
            "new time-stamped directory, or set force:=true to replace it"
        )
    return path


def parse_bool(name: str, text: str) -> bool:
    """A launch argument's boolean (true/false, as ROS parameters spell them)."""
    value = text.strip().lower()
    if value in ("true", "1", "yes"):
        return True
    if value in ("false", "0", "no"):
        return False
    raise LaunchError(f"{name}:={text}: must be true or false")


def parse_float(name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise LaunchError(f"{name}:={text}: must be a number") from None


def parse_command(label: str, text: str, empty: str) -> list[str]:
    """``text`` split as a POSIX shell would (no shell runs it). :class:`LaunchError` when it
    does not split, is empty (``empty``: the message) or its program is not found; ``label``
    names the argument, e.g. ``node:=`` or ``--node ``."""
    try:
        args = shlex.split(text)
    except ValueError as exc:
        raise LaunchError(f"{label}{text!r}: {exc}") from None
    if not args:
        raise LaunchError(empty)
    if shutil.which(args[0]) is None:
        why = "is not executable" if Path(args[0]).is_file() else "command not found"
        raise LaunchError(f"{label}{text!r}: {args[0]}: {why}")
    return args


def pipeline_counts(plan: Any) -> dict[str, dict[str, int]]:
    """Node → {topic it publishes: subscriptions to wait for}, for the nodes the scenario's plan
    (:func:`strapdown_ros.plan.resolve_plan`) needs, in chain order (the source,
    trajectory_node, first).

    Taken from the live graph of the scenario's plan, as ``strapdown-sim run`` takes them
    (:func:`strapdown_ros.plan.chain.live_graph`): every produced topic has the recorder, plus
    the nodes reading it; each node also waits on the TF / map-frame topics it derives.
    test/test_launch_logic.py checks they equal what ``run`` passes, scenario by scenario.
    """
    from strapdown_ros.plan.chain import live_graph

    nodes, subscribers = live_graph(plan)
    return {
        n.node_name: {t: subscribers[t] for t in n.published if t in subscribers} for n in nodes
    }


def pipeline_nodes(plan: Any) -> dict[str, tuple[str, dict[str, Any]]]:
    """Node name → (its executable, the parameters saying which part of its link it runs),
    for the nodes of :func:`pipeline_counts` (e.g. ``imu_model_node_1`` →
    ``("imu_model_node", {"model": 1})``)."""
    from strapdown_ros.plan.chain import live_graph

    nodes, _ = live_graph(plan)
    out = {}
    for n in nodes:
        params = {}
        for p in n.params:
            key, value = p.split(":=", 1)
            params[key] = int(value) if value.isdigit() else value
        out[n.node_name] = (n.executable, params)
    return out


def _per_topic(counts: dict[str, int]) -> list[str]:
    return [f"{topic}={n}" for topic, n in counts.items()]


def plan_launch(
    scenario_path: str,
    out: str = "",
    *,
    force: str | bool = False,
    duration_s: str | float = 0.0,
    rate_factor: str | float = 1.0,
    cwd: str | os.PathLike[str] | None = None,
) -> LaunchPlan:
    """The nodes, their parameters and the output directory of a launch.

    Arguments are the launch arguments (strings, as ``ros2 launch`` passes them, or values).
    ``rate_factor`` > 1 or <= 0 (unpaced) turns on flow control as ``strapdown-sim run`` does
    (the trajectory node never runs more than a window ahead of any consumer: lossless).
    Raises :class:`LaunchError` for a bad argument, an existing ``out`` without ``force`` or a
    scenario section no node runs live (``timing``), and the scenario's
    :class:`~strapdown_ros.config.ScenarioError`.
    """
    from strapdown_ros.config import load_scenario
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import offline_only

    force = force if isinstance(force, bool) else parse_bool("force", force)
    duration = parse_float("duration_s", duration_s) if isinstance(duration_s, str) else duration_s
    rate = parse_float("rate_factor", rate_factor) if isinstance(rate_factor, str) else rate_factor
    if duration < 0:
        raise LaunchError(f"duration_s:={duration_s}: must be >= 0 (0: the scenario's)")
    path = Path(scenario_path).expanduser()
    if not path.is_absolute():
        path = Path(cwd if cwd is not None else os.getcwd()).absolute() / path
    scenario = load_scenario(path, [], duration if duration > 0 else None)
    resolved = resolve_plan(scenario)
    offline = offline_only(resolved)
    if offline:  # as strapdown-sim run refuses them
        raise LaunchError(
            f"scenario:={scenario_path}: its {', '.join(offline)} section(s) run in "
            "`strapdown-sim generate` only: no node runs them live yet (remove them to launch)"
        )
    out_dir = resolve_out(out, force, cwd)

    flow = rate > 1 or rate <= 0
    counts = pipeline_counts(resolved)
    common: dict[str, Any] = {"scenario": str(path), "duration_s": float(duration)}
    node_params: dict[str, Any] = {"qos_depth": 10000}
    if flow:
        node_params |= {"report_progress": True, "idle_timeout_s": 120.0}
    plan = LaunchPlan(out=out_dir)
    recorder = {"scenario": str(path), "output": str(out_dir), "force": force,
                "stop_when_done": True}  # fmt: skip
    if flow:
        recorder["report_progress"] = True
    plan.nodes.append(NodePlan("bag_recorder", recorder))
    (source, source_counts), *downstream = counts.items()
    flow_nodes = ["bag_recorder"]
    which = pipeline_nodes(resolved)
    for name, published in reversed(downstream):  # the order run starts them: downstream first
        executable, own = which[name]
        params = {**common, **own, **node_params, "subscribers_per_topic": _per_topic(published)}
        plan.nodes.append(NodePlan(name, params, executable))
        flow_nodes.append(name)
    traj = {
        **common,
        "subscribers_per_topic": _per_topic(source_counts),
        "time_source": "sim" if scenario.recording.clock else "wall",
        "wait_for_all_topics": False,
        "rate_factor": float(rate),
        "qos_depth": 10000,
    }
    if flow:
        traj["flow_nodes"] = flow_nodes
    plan.nodes.append(NodePlan(source, traj))
    return plan


def node_interpreter(prefix: str | os.PathLike[str]) -> str:
    """The Python running the package's nodes: the ``#!`` line of
    ``<prefix>/lib/strapdown_ros/trajectory_node`` (or, where the path is too long for one,
    the ``#!/bin/sh`` + ``'''exec' PYTHON`` form that pip writes)."""
    script = Path(prefix) / "lib" / "strapdown_ros" / PLANNER_EXECUTABLE
    try:
        with script.open("rb") as fh:
            head = fh.read(4096).decode("utf-8", "replace").splitlines()
    except OSError as exc:
        raise LaunchError(
            f"cannot read the node executable {script} ({exc.strerror}); build the package "
            "(colcon build) and source its install/setup.bash"
        ) from None
    line = head[0][2:].strip() if head and head[0].startswith("#!") else ""
    words = shlex.split(line) if line else []
    sh_exec = "'''exec' "
    if words == ["/bin/sh"] and len(head) > 1 and head[1].startswith(sh_exec):
        words = shlex.split(head[1][len(sh_exec) :])
    elif words and Path(words[0]).name == "env" and len(words) > 1:
        words = [shutil.which(words[1]) or words[1]]
    if not words:
        raise LaunchError(f"{script} has no interpreter line (#!): reinstall the package")
    return words[0]


def _plan_options() -> set[str]:
    """The keyword arguments of :func:`plan_launch`."""
    params = inspect.signature(plan_launch).parameters.values()
    return {p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY}


def plan_launch_with(
    python: str, scenario_path: str, out: str = "", **options: Any
) -> LaunchPlan:
    """:func:`plan_launch` computed by ``python`` (:func:`node_interpreter`) in a child process.

    ``options``: :func:`plan_launch`'s keyword arguments (``cwd`` defaults to this process's
    current directory), passed to the child as JSON. Raises :class:`LaunchError` with the
    child's message when it refuses (a bad argument or scenario, an existing ``out``, an
    unsupported library with its fix) or fails.
    """
    unknown = sorted(set(options) - _plan_options())
    if unknown:
        raise TypeError(f"plan_launch_with() got unexpected keyword arguments {unknown}")
    options.setdefault("cwd", os.getcwd())
    args = [python, "-m", __name__, str(scenario_path), "--out", str(out),
            "--options", json.dumps(options, default=str)]  # fmt: skip
    try:
        proc = subprocess.run(args, capture_output=True, text=True, timeout=PLAN_TIMEOUT_S,
                              stdin=subprocess.DEVNULL)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise LaunchError(f"planning the launch with {python} failed: {exc}") from None
    if proc.returncode != 0:
        message = proc.stderr.strip() or f"{python} -m {__name__} exited {proc.returncode}"
        raise LaunchError(message)
    return LaunchPlan.from_json(proc.stdout)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m strapdown_ros.launch_logic SCENARIO [--out ...]``: the plan as JSON on
    stdout; a refusal on stderr with exit status 2 (1 for unsupported libraries)."""
    parser = argparse.ArgumentParser(prog=f"python -m {__name__}")
    parser.add_argument("scenario")
    parser.add_argument("--out", default="")
    parser.add_argument("--options", default="{}", help="plan_launch's keyword arguments (JSON)")
    ns = parser.parse_args(argv)
    from strapdown_ros.requirements_check import exit_if_unsupported

    exit_if_unsupported("pipeline.launch.py")
    from strapdown_ros.config import ScenarioError

    try:
        plan = plan_launch(ns.scenario, ns.out, **json.loads(ns.options))
    except (LaunchError, ScenarioError) as exc:
        print(exc, file=sys.stderr)
        return 2
    print(plan.to_json())
    return 0


def exit_reason(name: str, returncode: int | None, shutting_down: bool = False) -> str | None:
    """The reason to shut the launch down when node ``name`` exited with ``returncode``.

    None when it finished normally (0; the others go on to their own end) and when the launch
    is shutting down already (``shutting_down``: a node failed before, or Ctrl-C): the nodes
    launch stops then exit by its SIGINT, which is no new reason.
    """
    if returncode in (0, None) or shutting_down:
        return None
    if returncode < 0:
        meaning = f"killed by signal {-returncode}"
    else:
        meaning = EXIT_MEANING.get(returncode, "error")
    return (
        f"{name} exited with status {returncode} ({meaning}); stopping the other nodes "
        "(its log above says why)"
    )


if __name__ == "__main__":
    sys.exit(main())
