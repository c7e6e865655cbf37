"""Package layout: package.xml, setup.py/setup.cfg and the ament prefix installed for ros2 run."""

from __future__ import annotations

import ast
import configparser
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "strapdown_ros"
TOOL = REPO_ROOT / "tools" / "install_ament_prefix.py"

# The complete check (every import has a key, every key is used) is test_package_xml.py.
EXEC_DEPENDS = {
    "rclpy",
    "sensor_msgs",
    "nav_msgs",
    "geometry_msgs",
    "rosgraph_msgs",
    "python3-numpy",
    "python3-scipy",
    "python3-yaml",
}
TEST_DEPENDS = {"python3-pytest", "python3-pytest-timeout"}
CONSOLE_SCRIPTS = {
    "strapdown-sim": "strapdown_ros.cli:main",
    "trajectory_node": "strapdown_ros.nodes.usage:trajectory_node",
    "variation_node": "strapdown_ros.nodes.usage:variation_node",
    "navigator_node": "strapdown_ros.nodes.usage:navigator_node",
    "imu_model_node": "strapdown_ros.nodes.usage:imu_model_node",
    "aiding_node": "strapdown_ros.nodes.usage:aiding_node",
    "aided_node": "strapdown_ros.nodes.usage:aided_node",
    "transfer_node": "strapdown_ros.nodes.usage:transfer_node",
    "bag_recorder": "strapdown_ros.nodes.usage:bag_recorder",
    "bag_player": "strapdown_ros.nodes.usage:bag_player",
}


def test_package_xml():
    root = ET.parse(REPO_ROOT / "package.xml").getroot()
    assert root.tag == "package"
    assert root.get("format") == "3"
    assert root.findtext("name") == PACKAGE
    assert root.findtext("license") == "Apache-2.0"
    assert root.findtext("version")
    assert root.find("maintainer") is not None
    assert EXEC_DEPENDS <= {e.text for e in root.findall("exec_depend")}
    assert TEST_DEPENDS <= {e.text for e in root.findall("test_depend")}
    assert root.findtext("export/build_type") == "ament_python"


def test_setup_cfg_script_dirs():
    cfg = configparser.ConfigParser(interpolation=None)
    cfg.read(REPO_ROOT / "setup.cfg")
    assert cfg["develop"]["script_dir"] == "$base/lib/strapdown_ros"
    assert cfg["install"]["install_scripts"] == "$base/lib/strapdown_ros"
    assert cfg["tool:pytest"]["testpaths"].split() == ["test"]
    assert "slow" in cfg["tool:pytest"]["markers"]


def test_resource_marker_and_layout():
    marker = REPO_ROOT / "resource" / PACKAGE
    assert marker.is_file() and marker.stat().st_size == 0
    assert (REPO_ROOT / "config" / "scenarios").is_dir()
    assert (REPO_ROOT / PACKAGE / "nodes" / "__init__.py").is_file()


def _setup_kwargs() -> dict:
    """setup() keyword arguments, read the same way tools/install_ament_prefix.py reads them."""
    sys.path.insert(0, str(TOOL.parent))
    try:
        import install_ament_prefix
    finally:
        sys.path.remove(str(TOOL.parent))
    return install_ament_prefix.read_setup(REPO_ROOT)


def test_setup_py_declares_entry_points_and_data_files():
    kwargs = _setup_kwargs()
    assert kwargs["name"] == PACKAGE
    scripts = dict(
        (part.strip() for part in spec.split("=", 1))
        for spec in kwargs["entry_points"]["console_scripts"]
    )
    assert scripts == CONSOLE_SCRIPTS
    data = {target: list(files) for target, files in kwargs["data_files"]}
    assert data["share/ament_index/resource_index/packages"] == ["resource/strapdown_ros"]
    assert data["share/strapdown_ros"] == ["package.xml"]
    assert "launch/pipeline.launch.py" in data["share/strapdown_ros/launch"]
    installed = {f for files in data.values() for f in files}
    for path in (REPO_ROOT / "config").rglob("*"):
        rel = path.relative_to(REPO_ROOT).as_posix()
        if path.is_file() and not path.name.startswith("."):
            assert rel in installed, f"{rel} is not installed by setup.py"
            assert f"share/strapdown_ros/{Path(rel).parent.as_posix()}" in data
    assert "test" not in kwargs["packages"]
    assert {"strapdown_ros", "strapdown_ros.core", "strapdown_ros.nodes"} <= set(kwargs["packages"])


def test_launch_file_imports_launch_lazily():
    for path in sorted((REPO_ROOT / "launch").glob("*.launch.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        top_imports = [node for node in tree.body if isinstance(node, ast.Import | ast.ImportFrom)]
        names = {
            (node.module if isinstance(node, ast.ImportFrom) else alias.name).split(".")[0]
            for node in top_imports
            for alias in node.names
        }
        assert not names & {"launch", "launch_ros", "rclpy"}, path
        functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert "generate_launch_description" in functions, path


def test_cli_subcommands_reject_missing_input():
    from strapdown_ros import cli

    for argv in (["generate", "x.yaml", "--out", "o"], ["run", "x.yaml", "--out", "o"]):
        assert cli.main(argv) == 2  # invalid input: the scenario file does not exist
    assert cli.main(["report", "o"]) == 1  # the bag directory does not exist
    with pytest.raises(SystemExit) as info:
        cli.main(["--help"])
    assert info.value.code == 0


def _run_tool(prefix: Path, *extra: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(TOOL), "--prefix", str(prefix), *extra],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def _check_prefix(prefix: Path) -> None:
    assert (prefix / "share/ament_index/resource_index/packages" / PACKAGE).is_file()
    assert (prefix / "share" / PACKAGE / "package.xml").is_file()
    assert (prefix / "share" / PACKAGE / "launch" / "pipeline.launch.py").is_file()
    lib = prefix / "lib" / PACKAGE
    for name in CONSOLE_SCRIPTS:
        exe = lib / name
        assert exe.is_file(), exe
        assert os.access(exe, os.X_OK), exe
        assert exe.read_text().startswith("#!"), exe


@pytest.mark.slow
@pytest.mark.parametrize("mode", [(), ("--symlink",)], ids=["copy", "symlink"])
def test_install_ament_prefix_on_temp_prefix(tmp_path, mode):
    prefix = tmp_path / "prefix"
    first = _run_tool(prefix, *mode)
    assert "change(s)" in first
    _check_prefix(prefix)
    if mode:
        assert (prefix / "share" / PACKAGE / "package.xml").is_symlink()
    # idempotent: a second run changes nothing
    second = _run_tool(prefix, *mode)
    assert "(0 change(s))" in second, second
    # the wrappers run the package's entry points
    exe = prefix / "lib" / PACKAGE / "strapdown-sim"
    proc = subprocess.run(
        [str(exe), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "generate" in proc.stdout
    proc = subprocess.run(
        [str(exe), "generate", "x.yaml", "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
    )
    assert proc.returncode == 2  # the wrapper reached the real CLI, which rejects the input
    assert "scenario file not found: x.yaml" in proc.stderr
    # stale wrappers of removed entry points are cleaned up, foreign files are kept
    stale = prefix / "lib" / PACKAGE / "old_node"
    stale.write_text((prefix / "lib" / PACKAGE / "bag_player").read_text())
    foreign = prefix / "lib" / PACKAGE / "user_script"
    foreign.write_text("#!/bin/sh\n")
    _run_tool(prefix, *mode)
    assert not stale.exists()
    assert foreign.exists()


def test_running_prefix_is_an_ament_prefix():
    """After `make setup`, the venv running the tests is an ament prefix for strapdown_ros."""
    prefix = Path(sys.prefix)
    marker = prefix / "share/ament_index/resource_index/packages" / PACKAGE
    if sys.prefix == sys.base_prefix or not marker.exists():
        pytest.skip("not running in a venv prepared by `make setup`")
    _check_prefix(prefix)
    ament = os.environ.get("AMENT_PREFIX_PATH", "")
    if ament:
        from ament_index_python.packages import get_package_prefix, get_package_share_directory

        if str(prefix) in ament.split(os.pathsep):
            assert Path(get_package_prefix(PACKAGE)) == prefix
            assert Path(get_package_share_directory(PACKAGE)) == prefix / "share" / PACKAGE
