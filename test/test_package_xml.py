"""package.xml declares exactly what the package uses, with rosdep keys (``rosdep install``).

* Every third-party top-level module imported by ``strapdown_ros/**.py`` or the launch files
  (AST walk, function-level imports included) maps to an ``exec_depend`` key; every one imported
  by ``test/**.py`` only maps to a ``test_depend`` (or ``exec_depend``) key.
* Every ROS message package whose types the package serializes or records
  (``bag.cdr.MSGTYPES``, ``topics.MSGTYPES``) is an ``exec_depend``.
* Every declared key is used by one of the above (nothing declared that nothing needs).

The mapping module → key is :data:`MODULE_KEYS`. A module added to the code without an entry
here fails :func:`test_every_import_has_a_key` with its name and the files importing it: add the
rosdep key (``rosdep resolve KEY`` / rosdistro's ``rosdep/python.yaml``) and the package.xml
line. ``None`` marks a module for which rosdistro has no key (pip-only, documented in
docs/development.md).
"""

from __future__ import annotations

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = "strapdown_ros"

#: Import name → rosdep key (None: no rosdep key exists; installed with pip, documented).
MODULE_KEYS: dict[str, str | None] = {
    # ROS 2 (Jazzy packages)
    "rclpy": "rclpy",
    "rcl_interfaces": "rcl_interfaces",
    "launch": "launch",
    "launch_ros": "launch_ros",
    "ament_index_python": "ament_index_python",
    "sensor_msgs": "sensor_msgs",
    "nav_msgs": "nav_msgs",
    "geometry_msgs": "geometry_msgs",
    "rosgraph_msgs": "rosgraph_msgs",
    "tf2_msgs": "tf2_msgs",
    "std_msgs": "std_msgs",
    "builtin_interfaces": "builtin_interfaces",
    # Python libraries with Debian/Ubuntu packages
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "pytest": "python3-pytest",
    "bokeh": "python3-bokeh-pip",  # optional (Dask dashboard): imported under except ImportError
    # not declared: the pip step of requirements/ros-overlay.txt (package.xml says why)
    "numba": None,  # noble has no python3-numba
    "pydantic": None,  # noble's python3-pydantic is 1.10; the package needs 2.x
    "rosbags": None,  # python3-rosbags-pip: rosdep's pip installer fails on noble (PEP 668)
    "mcap": None,  # no key (python3-mcap-pip does not exist)
    # no rosdep key (pip install, see docs/development.md)
    "mpmath": None,
    "mcap_ros2": None,
    "pyIGRF14": None,  # IGRF-14 coefficients (aiding magnetometer)
    "ambiance": None,  # ICAO atmosphere reference in the aiding tests
    "dask": None,  # campaign engine
    "distributed": None,  # campaign engine
    "pyarrow": None,  # campaign results (Parquet)
    "lz4": None,  # MCAP lz4 chunks (recording.compression: lz4); installed with rosbags
    "pandas": None,  # bench peer pyins' data frames (test_score, bench/); skipped without it
    "pyins": None,  # the bench peer (requirements/bench.txt); its tests skip without it
}

#: Keys used without an import: pytest plugins configured in setup.cfg.
CONFIG_KEYS = {"python3-pytest-timeout": "setup.cfg [tool:pytest] timeout"}

#: Local modules imported by tests: the test tree's own files and the repository's tools.
LOCAL_TEST_MODULES = (
    {p.stem for p in (REPO / "test").rglob("*.py")}
    | {p.stem for p in (REPO / "tools").glob("*.py")}
    | {"ros_helpers"}
)


_IMPORT_ERRORS = {"ImportError", "ModuleNotFoundError"}


def _optional_imports(tree: ast.AST) -> set[int]:
    """ids of the import nodes inside ``try: ... except ImportError`` (optional features)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Try):
            continue
        caught = set()
        for handler in node.handlers:
            types = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
            caught |= {t.id for t in types if isinstance(t, ast.Name)}
        if caught & _IMPORT_ERRORS:
            for stmt in node.body:
                out |= {id(n) for n in ast.walk(stmt) if isinstance(n, ast.Import | ast.ImportFrom)}
    return out


def _imports(paths: list[Path], *, optional: bool = False) -> dict[str, set[str]]:
    """Third-party top-level module → files importing it (stdlib and the package excluded).

    Imports guarded by ``except ImportError`` are optional features (numba's JIT, Dask's
    dashboard): they need no key, but may have one (``optional=True`` includes them).
    """
    found: dict[str, set[str]] = {}
    for path in paths:
        tree = ast.parse(path.read_text(), filename=str(path))
        skip = set() if optional else _optional_imports(tree)
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            elif (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("importorskip", "import_module")
                and node.args
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)
            ):
                names = [node.args[0].value]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top in sys.stdlib_module_names or top == PACKAGE:
                    continue
                found.setdefault(top, set()).add(path.relative_to(REPO).as_posix())
    return found


def _package_files() -> list[Path]:
    return sorted((REPO / PACKAGE).rglob("*.py")) + sorted((REPO / "launch").glob("*.py"))


def _test_files() -> list[Path]:
    return sorted((REPO / "test").rglob("*.py"))


def _message_packages() -> set[str]:
    """ROS packages of every message type the package serializes, publishes or records."""
    from strapdown_ros import topics
    from strapdown_ros.bag import cdr

    types = set(cdr.MSGTYPES) | set(topics.MSGTYPES.values())
    return {t.split("/")[0] for t in types}


def _declared() -> dict[str, set[str]]:
    root = ET.parse(REPO / "package.xml").getroot()
    out: dict[str, set[str]] = {}
    for tag in ("depend", "exec_depend", "test_depend", "build_depend", "buildtool_depend"):
        out[tag] = {(e.text or "").strip() for e in root.findall(tag)}
    return out


def _run_keys() -> set[str]:
    d = _declared()
    return d["exec_depend"] | d["depend"]


def test_every_import_has_a_key() -> None:
    package = _imports(_package_files())
    tests = _imports(_test_files())
    unknown = {
        m: sorted(files)
        for m, files in {**tests, **package}.items()
        if m not in MODULE_KEYS and m not in LOCAL_TEST_MODULES
    }
    assert not unknown, (
        f"imports without a rosdep mapping in {__name__}.MODULE_KEYS: {unknown} — add the "
        "rosdep key (or None if rosdistro has none, and document it) and the package.xml line"
    )
    run = _run_keys()
    test = _declared()["test_depend"]
    missing_run = {
        m: MODULE_KEYS[m] for m in package if MODULE_KEYS.get(m) and MODULE_KEYS[m] not in run
    }
    assert not missing_run, f"package imports without an exec_depend: {missing_run}"
    missing_test = {
        m: MODULE_KEYS[m]
        for m in tests
        if m in MODULE_KEYS and MODULE_KEYS[m] and MODULE_KEYS[m] not in run | test
    }
    assert not missing_test, f"test imports without a test_depend: {missing_test}"


def test_message_packages_are_run_dependencies() -> None:
    missing = _message_packages() - _run_keys()
    assert not missing, f"message packages used without an exec_depend: {sorted(missing)}"


def test_every_declared_key_is_used() -> None:
    package = {MODULE_KEYS.get(m) for m in _imports(_package_files(), optional=True)}
    tests = {MODULE_KEYS.get(m) for m in _imports(_test_files(), optional=True)}
    used_run = (package | _message_packages()) - {None}
    declared = _declared()
    unused_run = _run_keys() - used_run
    assert not unused_run, f"exec_depend keys nothing in the package uses: {sorted(unused_run)}"
    used_test = (tests | set(CONFIG_KEYS)) - {None}
    unused_test = declared["test_depend"] - used_test
    assert not unused_test, f"test_depend keys no test uses: {sorted(unused_test)}"
    # a test_depend that is already a run dependency is redundant
    assert not declared["test_depend"] & _run_keys()


def test_config_keys_are_configured() -> None:
    """The pytest plugins declared without an import are really configured."""
    cfg = (REPO / "setup.cfg").read_text()
    assert re.search(r"^timeout\s*=", cfg, re.M), "setup.cfg no longer sets pytest-timeout"


def test_pip_only_modules_are_documented() -> None:
    """Modules without a rosdep key are named in docs/development.md with how to install them."""
    text = (REPO / "docs" / "development.md").read_text()
    for module, key in MODULE_KEYS.items():
        if key is None:
            assert module.replace("_", "-") in text or module in text, module


@pytest.mark.parametrize("module", sorted(m for m, k in MODULE_KEYS.items() if k))
def test_keys_follow_rosdep_naming(module: str) -> None:
    """Python library keys are ``python3-<name>`` (``-pip`` for pip-only ones); ROS packages
    are their own names (lower case with underscores)."""
    key = MODULE_KEYS[module]
    assert key is not None
    assert re.fullmatch(r"python3-[a-z0-9-]+|[a-z][a-z0-9_]*", key), key
