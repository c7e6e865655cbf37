"""``strapdown-sim run``: the live pipeline as separate ROS 2 processes (interface.md §6, issue 6).

Starts ``bag_recorder``, ``navigator_node``, ``imu_model_node``, ``variation_node`` and
``trajectory_node`` (those the scenario needs) as child processes in a private ROS domain
(LOCALHOST discovery), downstream first: each node waits until every one of its output topics
has as many matched subscriptions as the pipeline will have on it (``subscribers_per_topic``:
the recorder plus the downstream nodes), and only then subscribes to its inputs, so no message
is published before everyone who should record or process it is listening. The trajectory node
then publishes the scenario paced at ``rate_factor`` x real time; every node exits after its last
message, the recorder (``stop_when_done``) when all its publishers are gone, and the recorded
message counts are checked against what the scenario produces.

Runs not tied to the wall clock (``rate_factor`` > 1, or <= 0: unpaced, as fast as the slowest
node allows) are flow-controlled (:mod:`strapdown_ros.nodes.flow`): the recorder and the nodes
report their progress and the trajectory node never gets more than a window ahead of any
consumer, so they are lossless by construction; the throughput reached is reported. Real-time
and slower runs (0 < ``rate_factor`` <= 1, hardware in the loop) keep the wall-clock pace and
any loss shows as a count mismatch.

Children die with this process (``PR_SET_PDEATHSIG`` on Linux); when one fails, the others are
stopped (SIGTERM, then SIGKILL) and its log is printed. Logs: ``<out>.logs/<node>.log``.
"""

from __future__ import annotations

import ctypes
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from strapdown_ros.config import load_scenario
from strapdown_ros.plan import resolve_plan
from strapdown_ros.plan.chain import live_graph

__all__ = [
    "PipelineError",
    "PipelineResult",
    "ReplayResult",
    "replay_into_navigator",
    "run_pipeline",
]

#: Seconds a node may take to start and subscribe.
STARTUP_TIMEOUT_S = 60.0
#: Seconds the recorder may take to notice that every publisher is gone.
RECORDER_GRACE_S = 30.0
#: Seconds between SIGINT and SIGKILL when stopping children.
STOP_GRACE_S = 10.0
#: Environment variable: a directory where ``run`` writes a cProfile of each node process
#: (``<node>.prof``; bench/bench_live.py --profile). Profiling slows the nodes down.
PROFILE_ENV = "STRAPDOWN_PROFILE_DIR"


class PipelineError(RuntimeError):
    """A child process failed; ``log`` is its output."""

    def __init__(self, message: str, log: str = "") -> None:
        super().__init__(message)
        self.log = log


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

    @property
    def lost(self) -> dict[str, int]:
        """Topics with fewer (or more) messages than the scenario produces: topic → difference."""
        return {
            t: n - self.counts.get(t, 0)
            for t, n in self.expected.items()
            if self.counts.get(t, 0) != n
        }

    def format(self) -> str:
        lines = [
            f"bag:       {self.out}",
            f"duration:  {self.duration_s:.3f} s of data in {self.elapsed_s:.2f} s "
            f"(ROS_DOMAIN_ID={self.domain_id})",
            "topics:    recorded / expected",
        ]
        width = max((len(t) for t in self.expected), default=0)
        for topic, n in self.expected.items():
            got = self.counts.get(topic, 0)
            flag = "" if got == n else "   <-- MISMATCH"
            lines.append(f"  {topic:<{width}}  {got:>9d} / {n:<9d}{flag}")
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


def _die_with_parent() -> None:  # pragma: no cover - runs in the child
    """Linux: the child gets SIGTERM when the parent dies (no orphans)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class _Child:
    def __init__(self, name: str, args: list[str], env: dict[str, str], log_dir: Path) -> None:
        self.name = name
        self.log_path = log_dir / f"{name}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 - closed in close()
        preexec = _die_with_parent if sys.platform.startswith("linux") else None
        # A process group of its own: Ctrl-C in the terminal reaches this process only, which
        # stops every child once, in order (a child still importing must not get SIGINT).
        self.proc = subprocess.Popen(
            args, env=env, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            preexec_fn=preexec, process_group=0,
        )  # fmt: skip

    #: CPU seconds (user + system) of the process, known once :meth:`poll` reaped it.
    cpu_s: float | None = None

    def poll(self) -> int | None:
        """``proc.poll()`` that also takes the process' CPU time when it has exited."""
        if self.proc.returncode is None:
            try:
                pid, status, usage = os.wait4(self.proc.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere
                return self.proc.poll()
            if pid:
                self.proc.returncode = os.waitstatus_to_exitcode(status)
                self.cpu_s = usage.ru_utime + usage.ru_stime
        return self.proc.returncode

    @property
    def log(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def wait_for(self, text: str, timeout_s: float, others: list[_Child]) -> None:
        deadline = time.monotonic() + timeout_s
        while text not in self.log:
            for c in [self, *others]:
                if c.proc.poll() is not None and c.proc.returncode != 0:
                    raise PipelineError(f"{c.name} exited with status {c.proc.returncode}", c.log)
            if self.proc.poll() is not None:
                raise PipelineError(f"{self.name} exited before '{text}'", self.log)
            if time.monotonic() > deadline:
                raise PipelineError(f"{self.name}: no '{text}' within {timeout_s:g} s", self.log)
            time.sleep(0.05)

    def stop(self) -> None:
        # SIGTERM: the nodes finish as on SIGINT (summary, bag closed); a child interrupted
        # before its handlers are installed ends silently (no KeyboardInterrupt traceback).
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)

    def close(self) -> None:
        self._log.close()


def _stop_all(children: list[_Child]) -> None:
    for c in children:
        c.stop()
    deadline = time.monotonic() + STOP_GRACE_S
    for c in children:
        try:
            c.proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            c.proc.kill()
            c.proc.wait()


def _reap(children: list[_Child]) -> None:
    """No child outlives the caller: kill what still runs, close the logs."""
    for c in children:
        if c.proc.poll() is None:
            c.proc.kill()
            c.proc.wait()
        c.close()


def _executable(name: str) -> str:
    local = Path(sys.executable).parent / name
    return str(local) if local.exists() else name


def _child_env(domain: int) -> dict[str, str]:
    """The children's environment: a private ROS domain, LOCALHOST discovery, Fast DDS."""
    env = dict(os.environ)
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        RMW_IMPLEMENTATION=env.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp",
        PYTHONUNBUFFERED="1",
    )
    env.pop("ROS_LOCALHOST_ONLY", None)  # superseded; Jazzy warns when both are set
    return env


def _log_dir(out: Path) -> Path:
    """``<out>.logs/``, created: one log file per child process."""
    log_dir = out.parent / f"{out.name}.logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    return log_dir


def _private_domain() -> int:
    """A domain id in 102..232 from the pid (test sessions use 1..101; see test/conftest.py)."""
    return 102 + os.getpid() % 131


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
) -> PipelineResult:
    """Run the scenario live and record it into ``out``; see the module docstring.

    ``rate_factor`` <= 0: unpaced. ``flow_control`` None: on when ``rate_factor`` > 1 or
    unpaced (the runs not tied to the wall clock), off for (slower than) real time.

    Raises
    ------
    PipelineError
        A node failed (its log attached), or the pipeline did not finish within ``timeout_s``
        (default: the data duration / ``rate_factor`` + 120 s; unpaced: 5 x the data duration
        + 120 s).
    FileExistsError
        ``out`` exists and ``force`` is false.
    """
    from strapdown_ros.bag.reader import read_bag

    t_start = time.monotonic()
    scenario = load_scenario(scenario_path, list(overrides), duration_s)
    out = Path(out)
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")
    plan = resolve_plan(scenario)
    expected = plan.counts()
    data_s = plan.duration_s
    if flow_control is None:
        flow_control = rate_factor > 1 or rate_factor <= 0
    if timeout_s is None:
        timeout_s = (data_s / rate_factor if rate_factor > 0 else 5 * data_s) + 120.0
    domain = _private_domain() if domain_id is None else int(domain_id)
    env, log_dir = _child_env(domain), _log_dir(out)

    common = [f"scenario:={Path(scenario_path).resolve()}"]
    if overrides:
        common.append("overrides:=[" + ",".join(f"'{o}'" for o in overrides) + "]")
    if duration_s is not None:
        common.append(f"duration_s:={float(duration_s)}")

    # The chain's nodes and the subscriptions each topic will have (the recorder's and the
    # nodes reading it).
    nodes, subs = live_graph(plan)

    def per_topic(names: Sequence[str]) -> str:
        items = [f"'{t}={subs[t]}'" for t in names if t in subs]
        return "subscribers_per_topic:=[" + ",".join(items) + "]"

    def ros_args(*params: str) -> list[str]:
        args = ["--ros-args"]
        for p in (*common, *params):
            args += ["-p", p]
        return args

    children: list[_Child] = []

    def start(name: str, *params: str) -> _Child:
        command = [_executable(name)]
        if os.environ.get(PROFILE_ENV):
            prof = Path(os.environ[PROFILE_ENV]) / f"{name}.prof"
            script = command[0] if os.sep in command[0] else shutil.which(name) or name
            command = [sys.executable, "-m", "cProfile", "-o", str(prof), script]
        child = _Child(name, [*command, *ros_args(*params)], env, log_dir)
        children.append(child)
        return child

    def say(text: str) -> None:
        if progress:
            print(f"[run] {text}", file=sys.stderr, flush=True)

    node_params = ["qos_depth:=10000"]
    flow_nodes = ["bag_recorder"]
    if flow_control:
        # The nodes may wait for the slowest consumer: no idle stop in the middle of a run.
        node_params += ["report_progress:=true", "idle_timeout_s:=120.0"]
    *downstream, source = nodes
    try:
        rec_params = [f"output:={out}", "stop_when_done:=true", "force:=" + str(force).lower()]
        if flow_control:
            rec_params.append("report_progress:=true")
        if storage:
            rec_params.append(f"storage:={storage}")
        say(f"ROS_DOMAIN_ID={domain}; logs in {log_dir}")
        start("bag_recorder", *rec_params)
        for node in reversed(downstream):  # downstream first: each waits for its subscribers
            child = start(node.executable, per_topic(node.published), *node_params)
            flow_nodes.append(node.executable)
            child.wait_for("subscribed to", STARTUP_TIMEOUT_S, children)
            say(f"{node.executable} subscribed")
        time_source = "sim" if scenario.recording.clock else "wall"
        pace = f"rate_factor {rate_factor:g}" if rate_factor > 0 else "unpaced"
        traj_params = [f"rate_factor:={float(rate_factor)}", "qos_depth:=10000"]
        if flow_control:
            pace += ", flow control on " + ", ".join(flow_nodes)
            traj_params.append("flow_nodes:=[" + ",".join(f"'{n}'" for n in flow_nodes) + "]")
        say(f"{source.executable}: {data_s:g} s of data, {pace}")
        traj = start(
            source.executable, per_topic(source.published),
            f"time_source:={time_source}",
            "wait_for_all_topics:=false", *traj_params,
        )  # fmt: skip
        deadline = time.monotonic() + timeout_s
        recorder = children[0]
        done_at: float | None = None
        interrupted = False
        while True:
            for c in children:
                code = c.poll()
                if code is not None and code != 0:
                    raise PipelineError(f"{c.name} exited with status {code}", c.log)
            if recorder.poll() == 0:
                break
            producers_done = all(c.poll() == 0 for c in children if c is not recorder)
            if producers_done and traj.poll() == 0:
                # The recorder stops by itself once every publisher is gone (stop_when_done);
                # if it has not within RECORDER_GRACE_S, SIGINT makes it finalize the bag.
                if done_at is None:
                    done_at = time.monotonic()
                elif time.monotonic() - done_at > RECORDER_GRACE_S and not interrupted:
                    say("recorder still running after the producers finished; sending SIGINT")
                    recorder.stop()
                    interrupted = True
            if time.monotonic() > deadline:
                raise PipelineError(
                    f"the pipeline did not finish within {timeout_s:g} s", recorder.log
                )
            time.sleep(0.1)
        say("recorder finished")
        # The nodes are done (their publishers are gone); let them exit by themselves rather
        # than be killed in their teardown, so that their CPU time is known.
        end = time.monotonic() + STOP_GRACE_S
        while any(c.poll() is None for c in children) and time.monotonic() < end:
            time.sleep(0.05)
    except BaseException:
        _stop_all(children)
        raise
    finally:
        cpu = {c.name: c.cpu_s for c in children if c.cpu_s is not None}
        _reap(children)
    contents = read_bag(out)
    counts = {t: len(d) for t, d in contents.topics.items()}
    result = PipelineResult(
        out=out,
        counts=counts,
        expected=expected,
        elapsed_s=time.monotonic() - t_start,
        duration_s=data_s,
        domain_id=domain,
        rate_factor=rate_factor,
        flow_control=flow_control,
        cpu_s=cpu,
    )
    _read_trajectory_summary(log_dir / "trajectory_node.log", result)
    return result


def _read_trajectory_summary(path: Path, result: PipelineResult) -> None:
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


def replay_into_navigator(
    bag: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    scenario_path: str | os.PathLike[str] | None = None,
    overrides: Sequence[str] = (),
    rate_factor: float = 1.0,
    force: bool = False,
    domain_id: int | None = None,
    timeout_s: float | None = None,
    progress: bool = True,
) -> ReplayResult:
    """Play a bag's navigator input into a live ``navigator_node`` and record its output.

    ``bag_player`` publishes the navigator's IMU and truth topics of ``bag`` paced at
    ``rate_factor`` (hardware-in-the-loop style); ``navigator_node`` (settings: the scenario's
    ``navigator`` section, else the node's defaults) processes them; ``bag_recorder`` writes
    ``/navigator/*`` to ``out``. The recording is then compared payload for payload with the
    offline navigator on the same messages (the bag's own ``/navigator/*`` topics when they were
    written with the same settings, else :func:`strapdown_ros.stages.navigator.navigate_messages`).
    """
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.config import DEFAULT_TOPICS
    from strapdown_ros.config.navigator import NavigatorSpec, resolve_navigator
    from strapdown_ros.stages.navigator import OUTPUT_TOPICS, navigate_messages

    t_start = time.monotonic()
    out = Path(out)
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")
    scenario = None
    if scenario_path is not None:
        scenario = load_scenario(scenario_path, list(overrides))
        topics = dict(scenario.recording.topics)
        settings = resolve_navigator(
            scenario.navigator or NavigatorSpec(), topics, scenario.gravity_model
        )
    else:
        topics = dict(DEFAULT_TOPICS)
        settings = resolve_navigator(NavigatorSpec(), topics, "j2")
    inputs = [settings.imu_topic] + ([settings.truth_topic] if settings.truth_topic else [])
    contents = read_bag(bag, inputs, raw=True)
    imu = contents.topics[settings.imu_topic]
    truth = contents.topics.get(settings.truth_topic) if settings.truth_topic else None
    n_imu = len(imu)
    data_s = (n_imu + 1) * float(np.median(np.diff(imu.log_time_ns))) * 1e-9 if n_imu > 1 else 0
    if timeout_s is None:
        timeout_s = data_s / max(rate_factor, 1e-3) + 120.0
    expected = navigate_messages(
        settings, imu.fields, truth.fields if truth else None,
        initial=scenario.initial if scenario else None,
        start_ns=scenario.start_time_ns if scenario else None,
    )  # fmt: skip
    out_topics = {k: topics[v] for k, v in OUTPUT_TOPICS.items()}

    domain = _private_domain() if domain_id is None else int(domain_id)
    env, log_dir = _child_env(domain), _log_dir(out)
    children: list[_Child] = []

    def start(name: str, params: list[str]) -> _Child:
        args = [_executable(name), "--ros-args"]
        for p in params:
            args += ["-p", p]
        child = _Child(name, args, env, log_dir)
        children.append(child)
        return child

    def say(text: str) -> None:
        if progress:
            print(f"[replay] {text}", file=sys.stderr, flush=True)

    recorded = [t for k, t in out_topics.items() if settings.truth_topic or not k.startswith("e")]
    node_params = [f"imu_topic:={settings.imu_topic}", "qos_depth:=10000", "idle_timeout_s:=2.0"]
    node_params.append(f"truth_topic:={settings.truth_topic or '-'}")
    if scenario_path is not None:
        node_params.append(f"scenario:={Path(scenario_path).resolve()}")
        if overrides:
            node_params.append("overrides:=[" + ",".join(f"'{o}'" for o in overrides) + "]")
    node_params.append("subscribers_per_topic:=[" + ",".join(f"'{t}=1'" for t in recorded) + "]")
    try:
        say(f"ROS_DOMAIN_ID={domain}; logs in {log_dir}")
        recorder = start(
            "bag_recorder",
            [f"output:={out}", "stop_when_done:=true", f"force:={str(force).lower()}",
             "topics:=[" + ",".join(f"'{t}'" for t in recorded) + "]"],
        )  # fmt: skip
        nav = start("navigator_node", node_params)
        nav.wait_for("subscribed to", STARTUP_TIMEOUT_S, children)
        say(f"navigator_node subscribed; playing {', '.join(inputs)} of {bag}")
        player = start(
            "bag_player",
            [f"bag:={Path(bag).resolve()}", f"rate_factor:={float(rate_factor)}",
             "topics:=[" + ",".join(f"'{t}'" for t in inputs) + "]", "publish_clock:=false",
             "wait_for_subscribers:=1", "qos_depth:=10000"],
        )  # fmt: skip
        deadline = time.monotonic() + timeout_s
        done_at: float | None = None
        while recorder.proc.poll() is None:
            for c in children:
                code = c.proc.poll()
                if code is not None and code != 0:
                    raise PipelineError(f"{c.name} exited with status {code}", c.log)
            if player.proc.poll() == 0 and nav.proc.poll() == 0:
                done_at = done_at or time.monotonic()
                if time.monotonic() - done_at > RECORDER_GRACE_S:
                    recorder.stop()
            if time.monotonic() > deadline:
                raise PipelineError(f"the replay did not finish within {timeout_s:g} s", nav.log)
            time.sleep(0.1)
        if recorder.proc.returncode != 0:
            raise PipelineError(
                f"bag_recorder exited with {recorder.proc.returncode}", recorder.log
            )
    except BaseException:
        _stop_all(children)
        raise
    finally:
        _reap(children)
    got = read_bag(out, raw=True)
    result = ReplayResult(out=out, reference="the offline navigator on the bag's messages")
    want = expected
    for key, topic in out_topics.items():
        if topic not in recorded:
            continue
        payloads = [bytes(p) for p in got.topics[topic].payloads] if topic in got.topics else []
        result.counts[topic] = len(payloads)
        ref = want.get(key, [])
        if payloads != ref:
            result.mismatches[topic] = f"{len(payloads)} recorded vs {len(ref)} expected" + (
                "" if len(payloads) != len(ref) else ", payloads differ"
            )
    result.elapsed_s = time.monotonic() - t_start
    return result
