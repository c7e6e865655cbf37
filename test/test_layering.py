"""Layering rule: ``strapdown_ros.core`` is ROS-free (numpy/scipy only).

Checked in fresh interpreters so that nothing this test session imported leaks in.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

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
