"""Setuptools script of strapdown_ros (ament_python build type)."""

import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = "strapdown_ros"
SHARE = os.path.join("share", PACKAGE_NAME)


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
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="strapdown_ros maintainers",
    maintainer_email="maintainer@example.com",
    description=(
        "Exact synthetic strapdown IMU data, variation trajectories, a multirate "
        "strapdown navigator and rosbag2 datasets for ROS 2."
    ),
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "strapdown-sim = strapdown_ros.cli:main",
            "trajectory_node = strapdown_ros.nodes.trajectory_node:main",
            "variation_node = strapdown_ros.nodes.variation_node:main",
            "navigator_node = strapdown_ros.nodes.navigator_node:main",
            "imu_model_node = strapdown_ros.nodes.imu_model_node:main",
            "aiding_node = strapdown_ros.nodes.aiding_node:main",
            "bag_recorder = strapdown_ros.nodes.bag_recorder:main",
            "bag_player = strapdown_ros.nodes.bag_player:main",
        ],
    },
)
