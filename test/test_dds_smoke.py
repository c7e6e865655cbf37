"""DDS smoke test: two separate processes exchange sensor_msgs/Imu over real Fast DDS.

A publisher process and a subscriber process (test/ros_helpers/) run in this session's own
ROS domain (see conftest.py).  The subscriber must receive every message, in order, with
every field bit-identical to what was sent.  Every wait has a timeout, and children still
running when the test ends are killed.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

HELPERS = Path(__file__).resolve().parent / "ros_helpers"
COUNT = 200
TIMEOUT_S = 60.0

pytest.importorskip("rclpy", reason="rclpy (ros-jazzy-rclpy wheels) not installed")


class Child:
    """A subprocess whose stdout/stderr lines are collected by reader threads."""

    def __init__(self, args: list[str], env: dict[str, str], stdin: bool = False):
        self.args = args
        self.proc = subprocess.Popen(
            args,
            env=env,
            stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            bufsize=1,
        )
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._lines: queue.Queue[str] = queue.Queue()
        self._threads = [
            threading.Thread(
                target=self._drain, args=(self.proc.stdout, self.stdout, True), daemon=True
            ),
            threading.Thread(
                target=self._drain, args=(self.proc.stderr, self.stderr, False), daemon=True
            ),
        ]
        for thread in self._threads:
            thread.start()

    def _drain(self, stream, sink: list[str], notify: bool) -> None:
        for line in stream:
            sink.append(line.rstrip("\n"))
            if notify:
                self._lines.put(line.rstrip("\n"))

    def wait_for_line(self, wanted: str, deadline: float) -> None:
        """Block until stdout has a line equal to ``wanted``; fail at ``deadline`` or on exit."""
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                pytest.fail(f"timeout waiting for {wanted!r} from {self.describe()}")
            try:
                line = self._lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                if self.proc.poll() is not None and self._lines.empty():
                    pytest.fail(f"exited before printing {wanted!r}: {self.describe()}")
                continue
            if line == wanted:
                return

    def send(self, text: str) -> None:
        """Write ``text`` to the child's stdin and close it."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(text)
        self.proc.stdin.close()

    def wait(self, deadline: float) -> int:
        """Wait for exit (failing the test at ``deadline``); return the exit code."""
        try:
            code = self.proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            pytest.fail(f"timeout waiting for exit of {self.describe()}")
        for thread in self._threads:
            thread.join(timeout=5)
        return code

    def kill(self) -> None:
        """Kill the child if it is still running."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            self.proc.stdin.close()

    def describe(self) -> str:
        return (
            f"{Path(self.args[1]).name} (pid {self.proc.pid}, rc {self.proc.poll()})\n"
            f"--- stdout\n" + "\n".join(self.stdout) + "\n--- stderr\n" + "\n".join(self.stderr)
        )


def test_imu_messages_cross_dds_between_processes(ros_env):
    topic = f"/strapdown_test/smoke_imu_{os.getpid()}"
    common = ["--topic", topic, "--count", str(COUNT), "--timeout", str(TIMEOUT_S - 10)]
    deadline = time.monotonic() + TIMEOUT_S
    children: list[Child] = []
    try:
        sub = Child([sys.executable, str(HELPERS / "imu_sub.py"), *common], ros_env)
        children.append(sub)
        pub = Child([sys.executable, str(HELPERS / "imu_pub.py"), *common], ros_env, stdin=True)
        children.append(pub)

        pub.wait_for_line("MATCHED", deadline)  # the writer matched the reader
        sub.wait_for_line("READY", deadline)  # the reader matched the writer
        pub.send("go\n")

        pub_rc = pub.wait(deadline)
        sub_rc = sub.wait(deadline)
        assert pub_rc == 0, pub.describe()
        assert sub_rc == 0, sub.describe()
        assert f"PUBLISHED {COUNT} acked" in pub.stdout, pub.describe()
        assert f"RECEIVED {COUNT}" in sub.stdout, sub.describe()
        assert sub.stdout[-1] == "OK", sub.describe()
        assert not [line for line in sub.stdout if line.startswith("MISMATCH")]
    finally:
        for child in children:
            child.kill()


def test_session_is_isolated(ros_env):
    domain = int(ros_env["ROS_DOMAIN_ID"])
    assert 0 <= domain <= 232
    if not os.environ.get("STRAPDOWN_TEST_DOMAIN_ID"):
        assert 1 <= domain <= 101
    assert ros_env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert os.environ["ROS_DOMAIN_ID"] == ros_env["ROS_DOMAIN_ID"]  # exported for children
