"""The scenario model loads no numerical core: importing ``strapdown_ros.config`` and validating
a scenario (``strapdown-sim validate``) stay cheap.

The section models import the core modules that build their objects (the aiding error models,
the IMU error model, the offsets and scan filter, the spline fit) only in the methods that build
them (``errors()``, ``parameters()``, ``offset_model()``, ``fit_options()``): those modules load
scipy.signal or numba, whose import alone takes seconds of CPU. The checks run in fresh
interpreters, so that nothing this session imported counts.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"
#: Modules the configuration layer must not load when imported.
HEAVY = ("scipy.signal", "numba", "strapdown_ros.core.aiding", "matplotlib", "rclpy")
#: Modules ``validate`` of a segments scenario must not load (it builds the trajectory model).
HEAVY_VALIDATE = ("scipy.signal", "numba", "strapdown_ros.core.aiding", "strapdown_ros.stages",
                  "rosbags", "matplotlib", "rclpy")  # fmt: skip


def _loaded_after(code: str, watch: tuple[str, ...]) -> list[str]:
    """The modules of ``watch`` in ``sys.modules`` after ``code`` ran in a fresh interpreter."""
    probe = textwrap.dedent(code) + textwrap.dedent(f"""
        import json, sys
        watch = {watch!r}
        print(json.dumps(sorted(m for m in sys.modules
                                if any(m == w or m.startswith(w + ".") for w in watch))))
        """)
    proc = subprocess.run(
        [sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, f"rc={proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_import_config_loads_no_numerical_core():
    assert _loaded_after("import strapdown_ros.config", HEAVY) == []


def test_validate_default_loads_no_numerical_core():
    """``validate`` of the default scenario (every section, a segments trajectory built)."""
    code = f"""
        import contextlib, io
        from strapdown_ros.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["validate", {str(DEFAULT)!r}]) == 0
        """
    assert _loaded_after(code, HEAVY_VALIDATE) == []


def test_the_cli_module_loads_nothing_heavy():
    watch = (*HEAVY_VALIDATE, "numpy", "pydantic", "strapdown_ros.config")
    assert _loaded_after("import strapdown_ros.cli", watch) == []


def test_config_constants_agree_with_the_core():
    """The constants the validators need without the core (standard gravity, the order of the
    six misalignment values) are the core's."""
    from strapdown_ros.config import imu_errors as config_imu
    from strapdown_ros.core import imu_errors as core_imu

    assert config_imu.G0 == core_imu.G0
    six = np.arange(1.0, 7.0)
    assert np.array_equal(config_imu._misalignment_matrix(six), core_imu.misalignment_matrix(six))
