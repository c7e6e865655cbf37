"""Every executable answers ``--help`` (exit 0) and bad arguments (exit 2) without ROS.

The executables run as child processes, as a user types them, with the ROS-free tier's stand-in
``rclpy`` (test/ros_free: importing it raises ImportError) first on their ``PYTHONPATH``
whatever the tier of the session, so a ``--help`` or an argument error that imported rclpy
fails here. Each answer must come within
:data:`ANSWER_S`, measured (about 0.1 s per call on the development machine; a start-up that
loaded numba, scipy or rclpy takes 1-3 s).
"""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

import pytest
from node_testing import executable

from strapdown_ros.nodes import usage

NODES = tuple(usage.PARAMETERS)
#: Seconds an answer may take (CPU contention on CI included).
ANSWER_S = 5.0
STUB = Path(__file__).resolve().parent / "ros_free"


def _run(name: str, *args: str) -> tuple[int, str, float]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(STUB), env.get("PYTHONPATH")) if p)
    start = time.monotonic()
    proc = subprocess.run(
        [executable(name), *args], capture_output=True, text=True, timeout=30,
        stdin=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    return proc.returncode, proc.stdout + proc.stderr, time.monotonic() - start


def test_every_node_executable_is_described() -> None:
    from test_package_layout import CONSOLE_SCRIPTS

    assert set(NODES) == set(CONSOLE_SCRIPTS) - {"strapdown-sim"}
    assert set(usage.DESCRIPTIONS) == set(NODES)


@pytest.mark.parametrize("name", NODES)
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_node_help(name: str, flag: str) -> None:
    code, out, took = _run(name, flag)
    assert code == 0, out
    assert took < ANSWER_S, f"{name} {flag} took {took:.1f} s"
    assert out.startswith(f"usage: {name}")
    assert usage.DESCRIPTIONS[name].splitlines()[0] in out
    for pname, _default, _description in usage.PARAMETERS[name]:
        assert f"\n  {pname} (default " in out, pname
    assert "--ros-args -p" in out


@pytest.mark.parametrize("name", NODES)
def test_node_rejects_unknown_arguments(name: str) -> None:
    code, out, took = _run(name, "--bogus")
    assert code == 2, out
    assert took < ANSWER_S
    assert "unrecognized arguments: --bogus" in out


def test_parameter_without_ros_args_is_explained() -> None:
    code, out, _ = _run("navigator_node", "-p", "scenario:=x.yaml")
    assert code == 2
    assert "parameters go after --ros-args" in out


def test_unknown_parameter_name_is_rejected_with_a_suggestion() -> None:
    code, out, _ = _run("trajectory_node", "--ros-args", "-p", "rate_factr:=2.0")
    assert code == 2, out
    assert "'rate_factr' is not a parameter of trajectory_node" in out
    assert "did you mean 'rate_factor'" in out


def test_cli_help_and_bad_arguments() -> None:
    code, out, took = _run("strapdown-sim", "--help")
    assert code == 0 and "usage: strapdown-sim" in out and took < ANSWER_S
    code, out, _ = _run("strapdown-sim", "run", "--help")
    assert code == 0 and "--rate-factor" in out
    code, out, _ = _run("strapdown-sim", "no-such-command")
    assert code == 2 and "invalid choice" in out


def test_help_after_ros_args_is_left_to_rclpy() -> None:
    """Only what precedes ``--ros-args`` (or follows a lone ``--``) is ours to check."""
    plain, ros = usage._split(["--ros-args", "-p", "a:=1", "--", "--help"])
    assert plain == ["--help"] and ros == ["-p", "a:=1"]
    plain, ros = usage._split(["--ros-args", "--params-file", "f.yaml", "-r", "__node:=x"])
    assert plain == [] and ros == ["--params-file", "f.yaml", "-r", "__node:=x"]


def test_front_accepts_the_launch_command_line() -> None:
    """What ``ros2 launch`` passes (a node name remap, a params file, -p) goes through."""
    usage._done.discard("bag_recorder")
    usage.front(
        "bag_recorder",
        ["bag_recorder", "--ros-args", "-r", "__node:=bag_recorder", "--params-file",
         "/tmp/launch_params_x", "-p", "output:=/tmp/x", "-p", "use_sim_time:=false"],
    )  # fmt: skip
    assert "bag_recorder" in usage._done
    usage._done.discard("bag_recorder")
