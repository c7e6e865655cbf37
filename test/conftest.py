"""Test-session setup shared by every test of strapdown_ros.

DDS isolation: each pytest session gets its own ``ROS_DOMAIN_ID`` (derived from the pid, in
1..101 — the range in which Fast DDS' ports cannot collide with Linux ephemeral ports) and
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, so two test sessions on one machine (or a test
session and a developer's running nodes) never see each other's topics.  The variables are
written into ``os.environ`` in :func:`pytest_configure`, before any test module (and so any
``rclpy``) is imported, and child processes inherit them.  Set ``STRAPDOWN_TEST_DOMAIN_ID``
to choose the domain explicitly.

Test tiers: the ``dds`` marker is set automatically and the ROS-free tier is guarded by the
plugin ``test/tiers.py``, registered here.
"""

from __future__ import annotations

import os
import signal

import pytest
import tiers

# A test run started in the background of a non-interactive shell (``cmd &``) inherits SIGINT
# *ignored*, and an ignored signal stays ignored across exec: the command-line processes the
# Ctrl-C tests start would never see their Ctrl-C. A handled signal is reset to the default on
# exec, so installing Python's handler here gives every child the normal Ctrl-C behaviour.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

DOMAIN_ID_ENV = "STRAPDOWN_TEST_DOMAIN_ID"
#: Domain ids 1..101 keep Fast DDS' ports (7400 + 250 * id + ...) below Linux' ephemeral range.
DOMAIN_ID_MIN, DOMAIN_ID_MAX = 1, 101


def session_domain_id(pid: int | None = None) -> int:
    """Return the ROS domain id of this test session (``STRAPDOWN_TEST_DOMAIN_ID`` or from pid)."""
    override = os.environ.get(DOMAIN_ID_ENV, "").strip()
    if override:
        try:
            value = int(override)
        except ValueError:
            raise pytest.UsageError(f"{DOMAIN_ID_ENV}={override!r} is not an integer") from None
        if not 0 <= value <= 232:
            raise pytest.UsageError(f"{DOMAIN_ID_ENV}={value} is outside 0..232")
        return value
    pid = os.getpid() if pid is None else pid
    return DOMAIN_ID_MIN + pid % (DOMAIN_ID_MAX - DOMAIN_ID_MIN + 1)


def ros_isolation_env(domain_id: int) -> dict[str, str]:
    """Return the environment variables that isolate this session's DDS traffic."""
    return {
        "ROS_DOMAIN_ID": str(domain_id),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "RMW_IMPLEMENTATION": os.environ.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp",
    }


def pytest_configure(config: pytest.Config) -> None:
    """Export the session's DDS isolation variables before any test module is imported."""
    if not config.pluginmanager.is_registered(tiers):
        config.pluginmanager.register(tiers, "strapdown-tiers")
    if not hasattr(config, "workerinput"):  # pytest-xdist workers inherit the controller's
        os.environ.update(ros_isolation_env(session_domain_id()))
    # Jazzy warns when the deprecated variable is set next to the new one; it is superseded.
    os.environ.pop("ROS_LOCALHOST_ONLY", None)
    os.environ.pop("ROS_STATIC_PEERS", None)


def pytest_report_header(config: pytest.Config) -> str:
    """Show the DDS isolation settings in pytest's header."""
    return (
        f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
        f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')} "
        f"RMW_IMPLEMENTATION={os.environ.get('RMW_IMPLEMENTATION')}"
    )


@pytest.fixture
def ros_env() -> dict[str, str]:
    """Environment for ROS subprocesses: a copy of ``os.environ`` with the session's isolation.

    Tests may modify the returned dict freely.
    """
    env = dict(os.environ)
    env.update(ros_isolation_env(int(os.environ["ROS_DOMAIN_ID"])))
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


@pytest.fixture
def procs():
    """Child processes started by a test (node_testing.Proc); killed at teardown if running."""
    children: list = []
    yield children
    for child in children:
        child.kill()
