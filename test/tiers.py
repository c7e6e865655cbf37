"""Test tiers: the ``dds`` marker, set automatically, and the guard of the ROS-free tier.

Loaded by ``test/conftest.py`` (its hooks are re-exported there); see docs/development.md,
"Test tiers".

Marking (``pytest_collection_modifyitems``): a test is ``dds`` when it uses the ``ros_env`` or
``procs`` fixture (directly or through another fixture), when its module imports rclpy at module
level (``pytest.importorskip("rclpy")`` counts) or imports a module that does (e.g.
``strapdown_ros.nodes.lifecycle``; followed through ``strapdown_ros`` and the helpers in ``test/``
with the static import graph of ``import_graph.py``), or when the test function, a fixture
defined in its module or a module-level function either of them calls imports such a module.

Guard: when a session has selected no ``dds`` test (``make test-fast``, ``pytest -m "not dds"``,
``pytest test/test_earth.py``), rclpy is made unimportable for the rest of the session, in this
process (a ``sys.meta_path`` finder; rclpy modules already loaded by collection are dropped from
``sys.modules`` and ``rclpy.context.Context.init`` refuses) and in every child process (a
stand-in ``rclpy`` package, ``test/ros_free/rclpy``, first on ``PYTHONPATH``). Each attempt is
recorded and the test during which it happened fails, even if the test (or a child) swallowed
the ImportError. So a test that starts ``strapdown-sim run`` or a node without the fixtures
cannot pass in the fast tier: it fails with a message saying to give it ``ros_env``.
"""

from __future__ import annotations

import ast
import os
import shutil
import sys
import tempfile
import traceback
from functools import cache, lru_cache
from pathlib import Path

import pytest

TEST_DIR = Path(__file__).resolve().parent
REPO = TEST_DIR.parent
#: Fixtures that give a test ROS child processes (conftest.py).
DDS_FIXTURES = frozenset({"ros_env", "procs"})
#: Importing any of these needs the ROS graph's libraries.
ROS_MODULES = ("rclpy",)
STUB_DIR = TEST_DIR / "ros_free"
LOG_ENV = "STRAPDOWN_TEST_RCLPY_LOG"
HINT = (
    "rclpy was imported in the ROS-free test tier (no dds test selected). A test that needs "
    "ROS must be marked dds: give it the ros_env fixture (and procs for Proc children), or "
    "@pytest.mark.dds."
)


# ---------------------------------------------------------------------------------------------
# marking
# ---------------------------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _graph():
    import import_graph

    modules = import_graph.package_modules(REPO / "strapdown_ros")
    modules.update({p.stem: p for p in TEST_DIR.glob("*.py")})
    modules.update({p.stem: p for p in (TEST_DIR / "ros_helpers").glob("*.py")})
    return import_graph.Graph(modules)


def _ros_chain(target: str) -> list[str] | None:
    """How importing ``target`` loads rclpy (``[target, ..., "rclpy"]``), or None."""
    if any(target == m or target.startswith(m + ".") for m in ROS_MODULES):
        return [target]
    graph = _graph()
    internal = graph.internal(target)
    if internal is None:
        return None
    return graph.loads_at_import(target if target in graph.modules else internal, ROS_MODULES)


@cache
def _module_facts(path: Path) -> tuple[str | None, dict[str, list], dict[str, set[str]]]:
    """``(module-level reason, imports per function, names used per function)`` of a test file."""
    import import_graph

    graph = _graph()
    imports = import_graph.imports_of(path, path.stem, frozenset(graph.modules))
    module_reason = None
    per_function: dict[str, list] = {}
    for imp in imports:
        if imp.type_checking:
            continue
        if imp.function is None:
            chain = _ros_chain(imp.target)
            if chain and module_reason is None:
                module_reason = f"module imports {' -> '.join(chain)} (line {imp.line})"
        else:
            per_function.setdefault(imp.function.split(".")[-1], []).append(imp)
    names: dict[str, set[str]] = {}
    for node in ast.walk(import_graph.parse(path)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            used = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
            names.setdefault(node.name, set()).update(used)
    return module_reason, per_function, names


def dds_reason(path: Path, function: str, fixturenames: list[str] | tuple[str, ...]) -> str | None:
    """Why the test ``function`` of the file ``path`` needs ROS (None: it does not)."""
    used = sorted(DDS_FIXTURES & set(fixturenames))
    if used:
        return f"uses the {', '.join(used)} fixture"
    module_reason, per_function, names = _module_facts(path)
    if module_reason:
        return module_reason
    # the test, the fixtures of its module it requests, and module functions they name
    todo = [function, *(f for f in fixturenames if f in names)]
    seen = set(todo)
    while todo:
        name = todo.pop()
        for imp in per_function.get(name, []):
            chain = _ros_chain(imp.target)
            if chain:
                return f"{name}() imports {' -> '.join(chain)} (line {imp.line})"
        for other in names.get(name, ()):
            if other in names and other not in seen:
                seen.add(other)
                todo.append(other)
    return None


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "dds: needs rclpy / ROS processes over DDS; set automatically (test/tiers.py); "
        'the fast tier deselects it with -m "not dds"',
    )
    config.stash[_GUARD] = _Guard()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("dds") is not None or not isinstance(item, pytest.Function):
            continue
        reason = dds_reason(Path(item.path), item.originalname, item.fixturenames)
        if reason:
            item.add_marker(pytest.mark.dds(reason=reason))


# ---------------------------------------------------------------------------------------------
# guard of the ROS-free tier
# ---------------------------------------------------------------------------------------------


class _Guard:
    """Makes rclpy unimportable (here and in children) and records every attempt."""

    def __init__(self) -> None:
        self.active = False
        self.log_dir: Path | None = None
        self.in_process: list[str] = []  # and the children's, once noticed
        self._children_seen: set[str] = set()

    # sys.meta_path finder protocol
    def find_spec(self, name, path=None, target=None):  # noqa: ANN001
        if any(name == m or name.startswith(m + ".") for m in ROS_MODULES):
            stack = "".join(traceback.format_stack(limit=8)[:-1])
            self.in_process.append(f"import {name} in the test process:\n{stack}")
            raise ImportError(f"{name}: {HINT}")
        return None

    def activate(self) -> None:
        self.active = True
        self.log_dir = Path(tempfile.mkdtemp(prefix="strapdown-ros-free-"))
        os.environ[LOG_ENV] = str(self.log_dir)
        os.environ["PYTHONPATH"] = os.pathsep.join(
            p for p in (str(STUB_DIR), os.environ.get("PYTHONPATH", "")) if p
        )
        context = sys.modules.get("rclpy.context")
        if context is not None:  # loaded while collecting deselected modules: refuse contexts
            guard = self

            def refuse(self_, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003
                guard.in_process.append("rclpy.context.Context.init() in the test process")
                raise RuntimeError(HINT)

            context.Context.init = refuse
        for name in [n for n in sys.modules if n.split(".")[0] in ROS_MODULES]:
            del sys.modules[name]
        sys.meta_path.insert(0, self)

    def records(self) -> list[str]:
        """Every attempt so far, in the order they were noticed (children: at this call)."""
        if self.log_dir is not None:
            for path in sorted(self.log_dir.iterdir()):
                if path.name not in self._children_seen:
                    self._children_seen.add(path.name)
                    command = path.read_text().strip()
                    self.in_process.append(f"import rclpy in a child process: {command}")
        return list(self.in_process)

    def close(self) -> None:
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        if self.log_dir is not None:
            shutil.rmtree(self.log_dir, ignore_errors=True)


_GUARD = pytest.StashKey[_Guard]()
_SEEN = pytest.StashKey[int]()


def pytest_collection_finish(session: pytest.Session) -> None:
    if session.config.option.collectonly:
        return
    if not any(item.get_closest_marker("dds") for item in session.items):
        session.config.stash[_GUARD].activate()


def pytest_report_collectionfinish(config: pytest.Config, items: list[pytest.Item]) -> str:
    dds = sum(1 for item in items if item.get_closest_marker("dds"))
    if dds:
        return f"tier: {dds} of {len(items)} selected tests are dds (ROS processes over DDS)"
    return "tier: ROS-free (no dds test selected): rclpy is blocked here and in child processes"


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    item.stash[_SEEN] = len(item.config.stash[_GUARD].records())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    report = yield
    guard = item.config.stash[_GUARD]
    if call.when == "teardown" and guard.active:
        new = guard.records()[item.stash.get(_SEEN, 0) :]
        if new:
            report.outcome = "failed"
            report.longrepr = HINT + "\n\n" + "\n".join(new)
    return report


def pytest_unconfigure(config: pytest.Config) -> None:
    guard = config.stash.get(_GUARD, None)
    if guard is not None:
        guard.close()
