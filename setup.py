"""Setuptools script of strapdown_ros (ament_python build type)."""

import importlib.util
import os
import sys
from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = "strapdown_ros"
SHARE = os.path.join("share", PACKAGE_NAME)
HERE = os.path.dirname(os.path.abspath(__file__))


def _requirements_table():
    """strapdown_ros/requirements_check.py (stdlib only), loaded by path: the one table of the
    runtime libraries and their oldest supported versions."""
    path = os.path.join(HERE, PACKAGE_NAME, "requirements_check.py")
    spec = importlib.util.spec_from_file_location("_strapdown_requirements", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while it executes
    spec.loader.exec_module(module)
    return module


REQ = _requirements_table()
#: Node executables: each answers --help (and bad arguments) in strapdown_ros/nodes/usage.py,
#: without importing rclpy, then runs strapdown_ros.nodes.<name>:main.
NODE_EXECUTABLES = (
    "trajectory_node",
    "variation_node",
    "navigator_node",
    "imu_model_node",
    "aiding_node",
    "aided_node",
    "transfer_node",
    "bag_recorder",
    "bag_player",
)


def _tree_data_files(top):
    """Return data_files entries installing every file below ``top`` under share/<pkg>/top.

    Hidden files (``.gitkeep`` and the like) are skipped; the directory structure is kept.
    """
    entries = []
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "__")))
        files = sorted(os.path.join(dirpath, f) for f in filenames if not f.startswith("."))
        if files:
            entries.append((os.path.join(SHARE, dirpath), files))
    return entries


setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE_NAME]),
        (SHARE, ["package.xml"]),
        (os.path.join(SHARE, "launch"), sorted(glob("launch/*.launch.py"))),
        *_tree_data_files("config"),
    ],
    # rclpy and the message packages come from the ROS install (package.xml), not from pip.
    install_requires=["setuptools"] + [f"{d}>={REQ.MINIMUM[d]}" for d in REQ.CORE],
    extras_require={
        extra: [f"{d}>={REQ.MINIMUM[d]}" for d in dists]
        for extra, (_what, dists) in REQ.EXTRAS.items()
    },
    zip_safe=True,
    maintainer="strapdown_ros maintainers",
    maintainer_email="maintainer@example.com",
    description=(
        "Exact synthetic strapdown IMU data, variation trajectories, a multirate "
        "strapdown navigator and rosbag2 datasets for ROS 2."
    ),
    license="Apache-2.0",
    python_requires=">=" + ".".join(map(str, REQ.MINIMUM_PYTHON)),
    entry_points={
        "console_scripts": [
            "strapdown-sim = strapdown_ros.cli:main",
            *(f"{n} = strapdown_ros.nodes.usage:{n}" for n in NODE_EXECUTABLES),
        ],
    },
)
