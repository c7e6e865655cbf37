#!/usr/bin/env python3
"""Build ``tf2_msgs/msg/TFMessage`` into the venv so that the nodes can publish live TF.

ROS 2 Jazzy's PyPI wheels (``ros-jazzy-common-interfaces``) do not ship ``tf2_msgs``, but the
ROS build tools are on PyPI as wheels too. This script (run by ``make setup``):

1. installs the pinned build-only wheels (ament_cmake and its extensions, rosidl's default
   generators; ``requirements/tf2_build.txt``) with ``--no-deps`` into a separate prefix
   ``<venv>/tf2_build/tools`` — nothing in the venv's site-packages changes;
2. writes a package with the message part of Jazzy's tf2_msgs (``TFMessage.msg``: the same
   definition, hence the same RIHS01 type hash) and configures it with CMake against the
   venv's rosidl, geometry_msgs and Python;
3. builds it (C and Python type support, ~30 s on 2 cores) and installs it into the venv prefix
   (``lib/``, ``lib/python3.X/site-packages/tf2_msgs``, ``share/tf2_msgs``), where the ROS
   wheels' loader finds it like any other message package;
4. checks that ``from tf2_msgs.msg import TFMessage`` works in a fresh interpreter.

It needs ``cmake`` (>= 3.8) and a C/C++ compiler. Without them, or if any step fails, it prints
why and exits 0 with ``--optional`` (``make setup`` goes on; the nodes then report once that
live TF is off, and ``bag_recorder`` derives TF from the recorded truth: docs/recording.md),
or 1 without. Idempotent: does nothing when TFMessage already imports, unless ``--force``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PINS = REPO / "requirements" / "tf2_build.txt"

MSG = "geometry_msgs/TransformStamped[] transforms\n"

PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>tf2_msgs</name>
  <version>0.36.0</version>
  <description>tf2_msgs/msg/TFMessage (the message part of ROS 2 Jazzy's tf2_msgs), built for
    the strapdown_ros venv by tools/build_tf2_msgs.py</description>
  <maintainer email="maintainer@example.com">strapdown_ros maintainers</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <depend>geometry_msgs</depend>
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""

CMAKELISTS = """cmake_minimum_required(VERSION 3.8)
project(tf2_msgs)
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
find_package(geometry_msgs REQUIRED)
find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)
# The ROS wheels' exported CMake targets name the include paths of the machine that built the
# wheels (/opt/python/...): point them at this interpreter's headers.
foreach(dep IN ITEMS builtin_interfaces std_msgs geometry_msgs)
  if(TARGET ${dep}::${dep}__rosidl_generator_py)
    set_target_properties(${dep}::${dep}__rosidl_generator_py PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
  endif()
endforeach()
rosidl_generate_interfaces(${PROJECT_NAME} "msg/TFMessage.msg" DEPENDENCIES geometry_msgs)
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""

CHECK = (
    "from tf2_msgs.msg import TFMessage; from rclpy.serialization import serialize_message; "
    "import sys; sys.stdout.write(str(len(serialize_message(TFMessage()))))"
)


class BuildError(RuntimeError):
    """A step failed; the message says which and why."""


def _run(cmd: list[str], log: Path, env: dict[str, str], cwd: Path | None = None) -> None:
    with log.open("a") as out:
        out.write(f"$ {' '.join(cmd)}\n")
        out.flush()
        proc = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, cwd=cwd)
    if proc.returncode:
        tail = log.read_text(errors="replace").splitlines()[-15:]
        step = " ".join(cmd[:2])
        raise BuildError(f"{step} failed:\n  " + "\n  ".join(tail))


def importable(python: Path) -> bool:
    """Whether ``tf2_msgs.msg.TFMessage`` imports (and serializes) in ``python``."""
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    proc = subprocess.run(
        [str(python), "-c", CHECK], capture_output=True, text=True, env=env, timeout=120
    )
    return proc.returncode == 0


def build(prefix: Path, python: Path, jobs: int) -> Path:
    """Build and install tf2_msgs into ``prefix``; returns the log file."""
    for tool in ("cmake", "c++", "cc"):
        if shutil.which(tool) is None:
            raise BuildError(f"`{tool}` not found: a C/C++ toolchain and CMake are needed")
    work = prefix / "tf2_build"
    tools = work / "tools"
    work.mkdir(parents=True, exist_ok=True)
    log = work / "build.log"
    log.write_text("")
    py_ver = f"python{sys.version_info.major}.{sys.version_info.minor}"
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    # 1. build-only wheels into their own prefix
    _run(
        [
            str(python),
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--prefix",
            str(tools),
            "-r",
            str(PINS),
        ],
        log,
        env,
    )
    tools_site = tools / "lib" / py_ver / "site-packages"
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(tools_site), env.get("PYTHONPATH", "")) if p
    )
    env["AMENT_PREFIX_PATH"] = os.pathsep.join((str(tools), str(prefix)))
    env["PATH"] = os.pathsep.join((str(python.parent), env.get("PATH", "")))
    # 2. the package sources
    with tempfile.TemporaryDirectory(prefix="tf2_msgs_") as tmp:
        src = Path(tmp) / "src"
        (src / "msg").mkdir(parents=True)
        (src / "msg" / "TFMessage.msg").write_text(MSG)
        (src / "package.xml").write_text(PACKAGE_XML)
        (src / "CMakeLists.txt").write_text(CMAKELISTS)
        build_dir = Path(tmp) / "build"
        _run(
            [
                "cmake",
                "-S",
                str(src),
                "-B",
                str(build_dir),
                f"-DCMAKE_PREFIX_PATH={tools};{prefix}",
                f"-DCMAKE_INSTALL_PREFIX={prefix}",
                f"-DPython3_EXECUTABLE={python}",
                "-DBUILD_TESTING=OFF",
                "-DCMAKE_BUILD_TYPE=Release",
            ],
            log,
            env,
        )
        # 3. build and install into the prefix
        _run(["cmake", "--build", str(build_dir), "-j", str(jobs)], log, env)
        _run(["cmake", "--install", str(build_dir)], log, env)
    return log


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prefix", type=Path, default=Path(sys.prefix), help="venv prefix")
    parser.add_argument("--python", type=Path, default=None, help="venv interpreter")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--force", action="store_true", help="rebuild even if it imports")
    parser.add_argument(
        "--optional", action="store_true", help="exit 0 when it cannot be built (say why)"
    )
    args = parser.parse_args(argv)
    prefix = args.prefix.resolve()
    python = args.python or prefix / "bin" / "python"
    if not args.force and importable(python):
        print("tf2_msgs: TFMessage already importable; nothing to do")
        return 0
    try:
        log = build(prefix, python, args.jobs)
        if not importable(python):
            raise BuildError("built and installed, but `from tf2_msgs.msg import TFMessage` fails")
    except (BuildError, OSError, subprocess.SubprocessError) as exc:
        print(f"tf2_msgs: NOT built — {exc}", file=sys.stderr)
        print(
            "tf2_msgs: live TF is off in this environment (nodes say so once; bag_recorder "
            "derives /tf from the recorded truth); generate writes TF regardless",
            file=sys.stderr,
        )
        return 0 if args.optional else 1
    print(f"tf2_msgs: TFMessage built into {prefix} (log: {log})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
