"""``strapdown-sim run``: the scenario's chain of nodes started, watched and recorded.

The nodes are those of :func:`strapdown_ros.plan.chain.live_graph`, started downstream first
beside ``bag_recorder`` (see :mod:`strapdown_ros.pipeline` for the handshake and the flow
control); the recorded message counts are compared with what the scenario produces.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from strapdown_ros.bag.selection import TopicSelection
from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.pipeline.lag import LagWatch
from strapdown_ros.pipeline.processes import (
    STOP_GRACE_S,
    Child,
    Children,
    PipelineError,
    check_out,
    list_param,
)
from strapdown_ros.pipeline.result import PipelineResult, read_trajectory_summary
from strapdown_ros.plan import Plan, resolve_plan
from strapdown_ros.plan.chain import live_graph, offline_only

__all__ = ["RECORDER_GRACE_S", "STARTUP_TIMEOUT_S", "run_pipeline", "say_to_stderr"]

#: Seconds a node may take to start and subscribe.
STARTUP_TIMEOUT_S = 60.0
#: Real-time runs: the recorder warns when a topic's data is this far behind the wall clock.
LAG_WARNING_S = 1.0
#: Seconds the recorder may take to notice that every publisher is gone.
RECORDER_GRACE_S = 30.0


def say_to_stderr(tag: str, progress: bool) -> Callable[[str], None]:
    """Progress lines ``[tag] text`` on stderr (nothing unless ``progress``)."""

    def say(text: str) -> None:
        if progress:
            print(f"[{tag}] {text}", file=sys.stderr, flush=True)

    return say


def run_pipeline(
    scenario_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    overrides: Sequence[str] = (),
    duration_s: float | None = None,
    storage: str | None = None,
    force: bool = False,
    rate_factor: float = 1.0,
    domain_id: int | None = None,
    timeout_s: float | None = None,
    progress: bool = True,
    flow_control: bool | None = None,
    publish_period_s: float = 0.0,
) -> PipelineResult:
    """Run the scenario live and record it into ``out``; see :mod:`strapdown_ros.pipeline`.

    ``rate_factor`` <= 0: unpaced. ``flow_control`` None: on when ``rate_factor`` > 1 or
    unpaced (the runs not tied to the wall clock), off for (slower than) real time.
    ``publish_period_s`` > 0: the source publishes in groups of that much data time (the
    trajectory node's ``publish_period_s``), never early and at most that late.

    Raises
    ------
    PipelineError
        A node failed (its log attached), or the pipeline did not finish within ``timeout_s``
        (default: the data duration / ``rate_factor`` + 120 s; unpaced: 5 x the data duration
        + 120 s).
    FileExistsError
        ``out`` exists and ``force`` is false.
    """
    t_start = time.monotonic()
    scenario = load_scenario(scenario_path, list(overrides), duration_s)
    out = Path(out)
    check_out(out, force)
    plan = resolve_plan(scenario)
    offline = offline_only(plan)
    if offline:
        raise ScenarioError(
            offline[0],
            f"the scenario's {', '.join(offline)} section(s) run in `strapdown-sim generate` "
            "only: no node runs them live yet (remove them for `run`)",
        )
    if flow_control is None:
        flow_control = rate_factor > 1 or rate_factor <= 0
    if timeout_s is None:
        data_s = plan.duration_s
        timeout_s = (data_s / rate_factor if rate_factor > 0 else 5 * data_s) + 120.0
    common = [f"scenario:={Path(scenario_path).resolve()}"]
    if overrides:
        common.append(list_param("overrides", overrides))
    if duration_s is not None:
        common.append(f"duration_s:={float(duration_s)}")
    children = Children(out, domain_id, common, profile=True)
    run = _LiveRun(plan, out, storage, force, rate_factor, flow_control, children,
                   say_to_stderr("run", progress), publish_period_s)  # fmt: skip
    try:
        run.say(f"ROS_DOMAIN_ID={children.domain}; logs in {children.log_dir}")
        source = run.start()
        run.wait(source, timeout_s)
    except BaseException:
        children.stop_all()
        raise
    finally:
        cpu = children.cpu_s()
        children.reap()
    return run.result(t_start, children.domain, cpu)


@dataclass
class _LiveRun:
    """One live run: its settings, its children and how to start, watch and read them."""

    plan: Plan
    out: Path
    storage: str | None
    force: bool
    rate_factor: float
    flow_control: bool
    children: Children
    say: Callable[[str], None]
    #: The source's ``publish_period_s`` (s of data time; 0: every message at its own time).
    publish_period_s: float = 0.0
    #: Topic → the subscriptions it will have (the recorder's and the nodes reading it).
    subscriptions: dict[str, int] = field(default_factory=dict)
    #: The chain's nodes (source first).
    nodes: list = field(default_factory=list)
    #: CPU seconds of each child when the source starts publishing (start-up done).
    cpu_start: dict[str, float] = field(default_factory=dict)

    def start(self) -> Child:
        """Start the recorder, then the chain's nodes downstream first (each waits for its
        subscribers before it subscribes), the source (first in chain order) last; return the
        source."""
        nodes, self.subscriptions = live_graph(self.plan)
        self.nodes = list(nodes)
        selection = TopicSelection.of_recording(self.plan.scenario.recording)
        for topic in self.subscriptions:  # the recorder subscribes to the selected ones only
            if topic in self.plan.topics and not selection.selects(topic):
                self.subscriptions[topic] -= 1
        source, *downstream = nodes
        self.children.start("bag_recorder", *self._recorder_params())
        node_params = ["qos_depth:=10000"]
        if self.flow_control:
            # The nodes may wait for the slowest consumer: no idle stop in the middle of a run.
            node_params += ["report_progress:=true", "idle_timeout_s:=120.0"]
        flow_nodes = ["bag_recorder"]
        for node in reversed(downstream):
            child = self.children.start(
                node.executable, self._per_topic(node.published), *node.params, *node_params,
                node_name=node.node_name,
            )
            flow_nodes.append(node.node_name)
            child.wait_for("subscribed to", STARTUP_TIMEOUT_S, self.children.started)
            self.say(f"{node.node_name} subscribed")
        return self._start_source(source.executable, source.published, flow_nodes)

    def _recorder_params(self) -> list[str]:
        force = str(self.force).lower()
        params = [f"output:={self.out}", "stop_when_done:=true", f"force:={force}"]
        if self.flow_control:
            params.append("report_progress:=true")
        elif self.rate_factor == 1:  # real time: say while running which topics fall behind
            params.append(f"lag_warning_s:={LAG_WARNING_S}")
        if self.storage:
            params.append(f"storage:={self.storage}")
        return params

    def _per_topic(self, topics: Sequence[str]) -> str:
        subs = self.subscriptions
        return list_param("subscribers_per_topic", [f"{t}={subs[t]}" for t in topics if t in subs])

    def _start_source(self, name: str, published: Sequence[str], flow_nodes: list[str]) -> Child:
        rate_factor = self.rate_factor
        time_source = "sim" if self.plan.scenario.recording.clock else "wall"
        pace = f"rate_factor {rate_factor:g}" if rate_factor > 0 else "unpaced"
        params = [f"rate_factor:={float(rate_factor)}", "qos_depth:=10000"]
        if self.publish_period_s != 0:  # any other value goes to the node, which checks it
            pace += f", in groups of {self.publish_period_s * 1e3:g} ms"
            params.append(f"publish_period_s:={float(self.publish_period_s)}")
        if self.flow_control:
            pace += ", flow control on " + ", ".join(flow_nodes)
            params.append(list_param("flow_nodes", flow_nodes))
        self.say(f"{name}: {self.plan.duration_s:g} s of data, {pace}")
        return self.children.start(
            name, self._per_topic(published), f"time_source:={time_source}",
            "wait_for_all_topics:=false", *params,
        )  # fmt: skip

    def wait(self, source: Child, timeout_s: float) -> None:
        """Until the recorder has finished (SIGTERM to it RECORDER_GRACE_S after the producers
        if it has not); PipelineError when a child fails or ``timeout_s`` passes."""
        deadline = time.monotonic() + timeout_s
        recorder, children = self.children.started[0], self.children.started
        lag = LagWatch(recorder.log_path, source.log_path, self.nodes, say_to_stderr("run", True))
        done_at: float | None = None
        interrupted = False
        while True:
            self.children.check()
            if recorder.poll() == 0:
                break
            producers_done = all(c.poll() == 0 for c in children if c is not recorder)
            if producers_done and source.poll() == 0:
                # The recorder stops by itself once every publisher is gone (stop_when_done);
                # if it has not within RECORDER_GRACE_S, SIGTERM makes it finalize the bag.
                if done_at is None:
                    done_at = time.monotonic()
                elif time.monotonic() - done_at > RECORDER_GRACE_S and not interrupted:
                    self.say("recorder still running after the producers finished; sending SIGTERM")
                    recorder.stop()
                    interrupted = True
            if not self.cpu_start and "publishing" in source.log:
                self.cpu_start = self.children.cpu_now()
            lag.poll()
            if time.monotonic() > deadline:
                raise PipelineError(
                    f"the pipeline did not finish within {timeout_s:g} s", recorder.log
                )
            time.sleep(0.1)
        self.say("recorder finished")
        # The nodes are done (their publishers are gone); let them exit by themselves rather
        # than be killed in their teardown, so that their CPU time is known.
        end = time.monotonic() + STOP_GRACE_S
        while any(c.poll() is None for c in children) and time.monotonic() < end:
            time.sleep(0.05)
        # a node that failed in its teardown (e.g. its summary) fails the run
        self.children.check(f" after the recording ended (the bag at {self.out} is complete)")

    def result(self, t_start: float, domain: int, cpu: dict[str, float]) -> PipelineResult:
        """The recorded counts read back from the bag, with the trajectory node's summary."""
        from strapdown_ros.bag.reader import read_bag

        contents = read_bag(self.out)
        result = PipelineResult(
            out=self.out,
            counts={t: len(d) for t, d in contents.topics.items()},
            expected=TopicSelection.of_recording(self.plan.scenario.recording).counts(
                self.plan.counts()
            ),  # what the recorder records: the topics recording.include/exclude select
            elapsed_s=time.monotonic() - t_start,
            duration_s=self.plan.duration_s,
            domain_id=domain,
            rate_factor=self.rate_factor,
            flow_control=self.flow_control,
            cpu_s=cpu,
            cpu_start_s=dict(self.cpu_start),
        )
        read_trajectory_summary(self.children.log_dir / "trajectory_node.log", result)
        return result
