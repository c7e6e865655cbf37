"""Layering rules of ``strapdown_ros.core``: ROS-free (numpy/scipy only), and it reads no
configuration: no ``from_config``, no ``Mapping``, no yaml/pydantic, no import of the scenario
model, the stages, the nodes or the bag code (issue 13: core takes typed objects or plain
numbers and arrays; the model builds them outside core).

The ROS checks run in fresh interpreters, so that nothing this session imported leaks in; the
configuration checks read the sources (``test/import_graph.py``: every import, function-level
and ``TYPE_CHECKING`` ones included).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import import_graph

REPO_ROOT = Path(__file__).resolve().parent.parent
#: Modules the core must neither need nor load.
FORBIDDEN = ("rclpy", "rosbags", "sensor_msgs", "matplotlib")


def _run(code: str) -> dict:
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, f"rc={proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_core_imports_without_ros():
    """With rclpy (and the other ROS/plotting modules) unimportable, all of core imports."""
    result = _run(f"""
        import importlib, json, pkgutil, sys
        sys.path.insert(0, {str(REPO_ROOT)!r})
        for name in {FORBIDDEN!r}:
            sys.modules[name] = None   # any import of it raises ImportError
        import strapdown_ros.core as core
        names = sorted(
            m.name for m in pkgutil.walk_packages(core.__path__, core.__name__ + '.')
        )
        for name in names:
            importlib.import_module(name)
        print(json.dumps({{'modules': names, 'file': core.__file__}}))
    """)
    assert Path(result["file"]).resolve().is_relative_to(REPO_ROOT / "strapdown_ros")
    core_dir = REPO_ROOT / "strapdown_ros" / "core"
    on_disk = sorted(
        [p.stem for p in core_dir.glob("*.py") if p.stem != "__init__"]
        + [p.parent.name for p in core_dir.glob("*/__init__.py")]
    )
    assert [m.rsplit(".", 1)[1] for m in result["modules"] if m.count(".") == 2] == on_disk


def test_core_import_loads_no_ros_or_plotting_module():
    """Importing strapdown_ros.core and all its submodules loads none of the forbidden ones."""
    result = _run(f"""
        import importlib, json, pkgutil, sys
        sys.path.insert(0, {str(REPO_ROOT)!r})
        import strapdown_ros.core as core
        after_package = sorted(n for n in {FORBIDDEN!r} if n in sys.modules)
        for m in pkgutil.walk_packages(core.__path__, core.__name__ + '.'):
            importlib.import_module(m.name)
        after_all = sorted(n for n in {FORBIDDEN!r} if n in sys.modules)
        print(json.dumps({{'after_package': after_package, 'after_all': after_all}}))
    """)
    assert result["after_package"] == []
    assert result["after_all"] == []


# ---------------------------------------------------------------------------------------------
# core reads no configuration mapping
# ---------------------------------------------------------------------------------------------

CORE = REPO_ROOT / "strapdown_ros" / "core"
#: Third-party packages core may import (anything else but the standard library is refused).
CORE_MAY_IMPORT = ("numpy", "scipy", "numba")
#: Named in the failure message when imported by core.
CONFIG_MODULES = ("yaml", "pydantic", "strapdown_ros.config", "strapdown_ros.stages",
                  "strapdown_ros.nodes", "strapdown_ros.bag")  # fmt: skip
MAPPING_SOURCES = ("typing", "collections.abc", "collections", "typing_extensions")


def _within(name: str, prefixes) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def core_violations(package_dir: Path, package: str) -> list[str]:
    """Every way a module under ``package_dir`` (the core) reads configuration, as text."""
    modules = import_graph.package_modules(package_dir, package)
    known = frozenset(modules)
    found = []
    root = package_dir.parents[package.count(".")]
    for name, path in sorted(modules.items()):
        rel = path.relative_to(root)
        for imp in import_graph.imports_of(path, name, known):
            at = f"{rel}:{imp.line}"
            target = imp.target
            if _within(target, CONFIG_MODULES):
                found.append(f"{at}: imports {target} ({imp.statement})")
            elif target.split(".")[0] == package.split(".")[0] and not _within(target, [package]):
                found.append(f"{at}: imports {target} outside the core ({imp.statement})")
            elif target.split(".")[0] in sys.stdlib_module_names or target == "__future__":
                if target in MAPPING_SOURCES and any("Mapping" in n for n in imp.names):
                    found.append(f"{at}: imports a Mapping type ({imp.statement})")
            elif not _within(target, (package, *CORE_MAY_IMPORT)):
                found.append(f"{at}: imports {target}, not numpy/scipy/numba ({imp.statement})")
        for node in ast.walk(import_graph.parse(path)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and (
                node.name == "from_config"
            ):
                found.append(f"{rel}:{node.lineno}: defines from_config()")
            elif isinstance(node, ast.Attribute) and node.attr == "from_config":
                found.append(f"{rel}:{node.lineno}: uses .from_config")
            elif isinstance(node, ast.Name) and node.id == "from_config":
                found.append(f"{rel}:{node.lineno}: uses from_config")
            elif isinstance(node, ast.Attribute) and "Mapping" in node.attr:
                found.append(f"{rel}:{node.lineno}: uses {ast.unparse(node)}")
    return found


def test_core_reads_no_configuration() -> None:
    found = core_violations(CORE, "strapdown_ros.core")
    assert not found, f"{len(found)} configuration reader(s) in strapdown_ros/core:\n" + (
        "\n".join(f"  {f}" for f in found)
    )


def test_core_check_finds_every_form(tmp_path: Path) -> None:
    """The checker itself: each forbidden form is reported, allowed imports are not."""
    core = tmp_path / "pkg" / "core"
    core.mkdir(parents=True)
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (core / "__init__.py").write_text("from .ok import f\n")
    (core / "ok.py").write_text(
        "import math\nfrom collections.abc import Sequence\nimport numpy as np\n"
        "from scipy.signal import lfilter\nfrom . import sub\n"
        "def f(x: Sequence[float]) -> float:\n    return math.fsum(x)\n"
    )
    (core / "sub.py").write_text("X = 1\n")
    (core / "bad.py").write_text(
        "from collections.abc import Mapping\n"
        "import typing\n"
        "def g(c: typing.Mapping) -> None:\n"
        "    import yaml\n"
        "    from pydantic import BaseModel\n"
        "    from ..config import Scenario\n"
        "    from pkg.stages import variation\n"
        "    from pkg.topics import DEFAULT\n"
        "    import requests\n"
        "class T:\n"
        "    @classmethod\n"
        "    def from_config(cls, d):\n"
        "        return cls.from_config(d)\n"
    )
    found = core_violations(core, "pkg.core")
    text = "\n".join(found)
    assert len(found) == 10, text
    for expected in (
        "bad.py:1: imports a Mapping type",
        "bad.py:3: uses typing.Mapping",
        "bad.py:4: imports yaml",
        "bad.py:5: imports pydantic",
        "bad.py:6: imports pkg.config outside the core",
        "bad.py:7: imports pkg.stages outside the core",
        "bad.py:8: imports pkg.topics outside the core",
        "bad.py:9: imports requests, not numpy/scipy/numba",
        "bad.py:12: defines from_config()",
        "bad.py:13: uses .from_config",
    ):
        assert expected in text, (expected, text)
    assert "ok.py" not in text
