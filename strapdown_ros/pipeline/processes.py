"""The child processes of a live run: started with their parameters, watched, stopped, reaped.

Children die with this process (``PR_SET_PDEATHSIG`` on Linux) and run in a process group of
their own; when one fails, the others are stopped (SIGTERM, then SIGKILL) and its log is
attached to the :class:`PipelineError`. Logs: ``<out>.logs/<node>.log``.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = [
    "PROFILE_ENV",
    "STOP_GRACE_S",
    "Child",
    "Children",
    "PipelineError",
    "check_out",
    "child_env",
    "executable",
    "list_param",
    "log_dir",
    "private_domain",
]

#: Seconds between SIGTERM and SIGKILL when stopping children.
STOP_GRACE_S = 10.0
#: Environment variable: a directory where ``run`` writes a cProfile of each node process
#: (``<node>.prof``; bench/bench_live.py --profile). Profiling slows the nodes down.
PROFILE_ENV = "STRAPDOWN_PROFILE_DIR"


class PipelineError(RuntimeError):
    """A child process failed; ``log`` is its output."""

    def __init__(self, message: str, log: str = "") -> None:
        super().__init__(message)
        self.log = log


def _die_with_parent() -> None:  # pragma: no cover - runs in the child
    """Linux: the child gets SIGTERM when the parent dies (no orphans)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class Child:
    """One node process, its output in ``<log_dir>/<name>.log``."""

    #: CPU seconds (user + system) of the process, known once :meth:`poll` reaped it.
    cpu_s: float | None = None

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

    def wait_for(self, text: str, timeout_s: float, others: Iterable[Child]) -> None:
        """Wait until ``text`` is in the log; PipelineError if this or another child failed
        or ``timeout_s`` passed."""
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
        """SIGTERM: the nodes finish as on SIGINT (summary, bag closed); a child interrupted
        before its handlers are installed ends silently (no KeyboardInterrupt traceback)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)

    def close(self) -> None:
        self._log.close()


class Children:
    """The children of a run writing ``out``, in start order: nodes started with ``-p``
    parameters in ROS domain ``domain`` (:func:`child_env`), their logs in :func:`log_dir`.

    ``domain_id`` None: :func:`private_domain`. ``common`` parameters are given to every
    child; with ``profile`` and :data:`PROFILE_ENV` set, each child runs under cProfile.
    """

    def __init__(
        self,
        out: Path,
        domain_id: int | None = None,
        common: Sequence[str] = (),
        profile: bool = False,
    ) -> None:
        self.domain = private_domain() if domain_id is None else int(domain_id)
        self.env = child_env(self.domain)
        self.log_dir = log_dir(out)
        self.common = list(common)
        self.profile = profile
        self.started: list[Child] = []

    def start(self, name: str, *params: str, node_name: str | None = None) -> Child:
        """Start the node (console script) ``name`` with the common parameters and ``params``;
        ``node_name``: its ROS node name (``-r __node:=``) and the child's name (its log), for
        a node started more than once (default: the executable's own)."""
        command = [executable(name)]
        if self.profile and os.environ.get(PROFILE_ENV):
            prof = Path(os.environ[PROFILE_ENV]) / f"{name}.prof"
            script = command[0] if os.sep in command[0] else shutil.which(name) or name
            command = [sys.executable, "-m", "cProfile", "-o", str(prof), script]
        args = [*command, "--ros-args"]
        for p in (*self.common, *params):
            args += ["-p", p]
        if node_name is not None and node_name != name:
            args += ["-r", f"__node:={node_name}"]
        child = Child(node_name or name, args, self.env, self.log_dir)
        self.started.append(child)
        return child

    def check(self, when: str = "") -> None:
        """PipelineError (with its log) if a child has exited with a non-zero status; ``when``
        is added to the message (e.g. " after the recording ended")."""
        for c in self.started:
            code = c.poll()
            if code is not None and code != 0:
                raise PipelineError(f"{c.name} exited with status {code}{when}", c.log)

    def cpu_s(self) -> dict[str, float]:
        """CPU seconds of each child that has exited (start-up included)."""
        return {c.name: c.cpu_s for c in self.started if c.cpu_s is not None}

    def cpu_now(self) -> dict[str, float]:
        """CPU seconds (user + system) so far of each running child (Linux ``/proc``; empty
        elsewhere)."""
        out = {}
        tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
        for c in self.started:
            try:
                stat = Path(f"/proc/{c.proc.pid}/stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
            out[c.name] = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
        return out

    def stop_all(self) -> None:
        """SIGTERM to every child, SIGKILL to those still running after STOP_GRACE_S."""
        for c in self.started:
            c.stop()
        deadline = time.monotonic() + STOP_GRACE_S
        for c in self.started:
            try:
                c.proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                c.proc.kill()
                c.proc.wait()

    def reap(self) -> None:
        """No child outlives the caller: kill what still runs, close the logs."""
        for c in self.started:
            if c.proc.poll() is None:
                c.proc.kill()
                c.proc.wait()
            c.close()


def executable(name: str) -> str:
    """The console script ``name`` beside this interpreter, else ``name`` (found on PATH)."""
    local = Path(sys.executable).parent / name
    return str(local) if local.exists() else name


def list_param(name: str, items: Iterable[str]) -> str:
    """A string-array parameter, ``name:=['a','b']``."""
    return f"{name}:=[" + ",".join(f"'{i}'" for i in items) + "]"


def child_env(domain: int) -> dict[str, str]:
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


def check_out(out: Path, force: bool) -> None:
    """FileExistsError when the bag directory ``out`` exists and ``force`` is false."""
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists already; not overwriting (use --force)")


def log_dir(out: Path) -> Path:
    """``<out>.logs/``, created: one log file per child process."""
    path = out.parent / f"{out.name}.logs"
    path.mkdir(parents=True, exist_ok=True)
    return path


def private_domain() -> int:
    """A domain id in 102..232 from the pid (test sessions use 1..101; see test/conftest.py)."""
    return 102 + os.getpid() % 131
