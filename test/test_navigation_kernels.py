"""Compiled navigator kernel (``core/navigation/_kernels.py``) vs the pure-Python path."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.config import load_scenario
from strapdown_ros.core.navigation import (
    NavSolution,
    NavState,
    _kernels,
    fast_cycle,
    navigate_multirate,
    state_from_stream,
)
from strapdown_ros.core.rotations import dcm_from_euler, quat_from_dcm
from strapdown_ros.core.stream import Stream
from strapdown_ros.stages.trajectory import generate_reference

REPO_ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = REPO_ROOT / "config" / "scenarios"
needs_numba = pytest.mark.skipif(not _kernels.HAVE_NUMBA, reason="numba not importable")


@pytest.fixture(scope="module")
def default_ref() -> Stream:
    return generate_reference(load_scenario(SCENARIOS / "default.yaml", duration_s=60.0))


def _assert_agree(a: NavSolution, b: NavSolution, rtol: float = 1e-12) -> None:
    """Element-wise agreement to ``rtol`` relative to each output's magnitude."""
    np.testing.assert_array_equal(a.t, b.t)
    assert a.n == b.n
    for key in ("lat", "lon", "alt", "v_ned", "q_b_n"):
        x, y = getattr(a, key), getattr(b, key)
        assert x.shape == y.shape, key
        scale = max(float(np.abs(y).max()), 1.0 if key == "v_ned" else 0.0)
        np.testing.assert_allclose(x, y, rtol=0, atol=rtol * scale, err_msg=key)


def test_default_engine() -> None:
    st = NavState(0.0, 0.5, 0.1, 100.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    z = np.zeros((4, 3))
    with pytest.raises(ValueError, match="engine"):
        navigate_multirate(st, z, z, 0.005, 2, 1, engine="fortran")
    with pytest.raises(ValueError, match="gravity"):
        navigate_multirate(st, z, z, 0.005, 2, 1, gravity_model="egm96")
    assert _kernels.HAVE_NUMBA == (importlib.util.find_spec("numba") is not None)


@needs_numba
def test_fast_cycle_kernel_matches_python() -> None:
    rng = np.random.default_rng(7)
    dalpha = rng.normal(scale=1e-2, size=(23, 3))
    dv = rng.normal(scale=1e-1, size=(23, 3))
    dphi_l = rng.normal(scale=1e-5, size=3)
    q0 = quat_from_dcm(dcm_from_euler(0.3, -0.2, 2.0))
    for normalize in (False, True):
        q_py, v_py = fast_cycle(q0, dalpha[5:15], dv[5:15], dphi_l, normalize)
        q_nb, v_nb = np.empty(4), np.empty(3)
        lx, ly, lz = 0.5 * dphi_l
        _kernels.fast_cycle_kernel(q0, dalpha, dv, 5, 10, lx, ly, lz, normalize, q_nb, v_nb)
        np.testing.assert_array_equal(q_nb, q_py)
        np.testing.assert_array_equal(v_nb, v_py)


@needs_numba
@pytest.mark.parametrize(
    ("n", "p", "kwargs"),
    [
        (10, 2, {}),
        pytest.param(1, 1, {}, marks=pytest.mark.slow),  # ~4.6 s: 12 000 Python-engine cycles
        (20, 4, {}),
        (7, 3, {"normalize": False}),
        (10, 2, {"table1_radii": True}),
        (5, 1, {"gravity_model": "spherical"}),
    ],
)
def test_numba_agrees_with_python(default_ref: Stream, n: int, p: int, kwargs: dict) -> None:
    """Whole 60 s maneuvering run, both engines, agree to 1e-12 of each output's magnitude
    (measured: lat/lon identical, alt ~1e-14 relative, velocity ~1e-15)."""
    st = state_from_stream(default_ref)
    m = default_ref.dalpha.shape[0] - 3  # a partial last cycle is dropped by both
    args = (st, default_ref.dalpha[:m], default_ref.dv[:m], default_ref.period, n, p)
    nb = navigate_multirate(*args, engine="numba", **kwargs)
    py = navigate_multirate(*args, engine="python", **kwargs)
    assert nb.t.size == m // n + 1
    _assert_agree(nb, py)
    assert navigate_multirate(*args, **kwargs).v_ned.tobytes() == nb.v_ned.tobytes()


@needs_numba
def test_kernel_python_fallback_function_agrees(default_ref: Stream) -> None:
    """The kernel's source run as plain Python (what numba-less installs would execute if
    they called it) gives the compiled result."""
    st = state_from_stream(default_ref)
    m = 400
    nb = navigate_multirate(st, default_ref.dalpha[:m], default_ref.dv[:m], 0.005, 10, 2)
    pos, vel, quat = np.empty((41, 3)), np.empty((41, 3)), np.empty((41, 4))
    _kernels.multirate_kernel.py_func(
        st.lat, st.lon, st.alt, np.asarray(st.v_ned, float), np.asarray(st.q_b_n, float),
        default_ref.dalpha[:m], default_ref.dv[:m], 0.005, 10, 2, 0, True, False, pos, vel, quat,
        False, 0.0, 0.0, np.zeros(40),
    )  # fmt: skip
    np.testing.assert_allclose(vel, nb.v_ned, rtol=0, atol=1e-12)
    np.testing.assert_allclose(quat, nb.q_b_n, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pos[:, 2], nb.alt, rtol=0, atol=1e-9)


def test_core_imports_and_navigates_without_numba() -> None:
    """With numba unimportable the core imports, defaults to the Python engine, and an
    explicit ``engine='numba'`` raises ImportError."""
    code = textwrap.dedent(f"""
        import json, sys
        sys.path.insert(0, {str(REPO_ROOT)!r})
        sys.modules['numba'] = None
        import numpy as np
        from strapdown_ros.core.navigation import NavState, _kernels, navigate_multirate
        st = NavState(0.0, 0.5, 0.1, 100.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
        z = np.zeros((4, 3))
        sol = navigate_multirate(st, z, z, 0.005, 2, 1)
        try:
            navigate_multirate(st, z, z, 0.005, 2, 1, engine='numba')
            err = None
        except ImportError as e:
            err = str(e)
        print(json.dumps({{'have': _kernels.HAVE_NUMBA, 'k': sol.t.size, 'err': err}}))
    """)
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO_ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out == {"have": False, "k": 3, "err": "engine='numba' requires numba"}


@pytest.mark.slow
@needs_numba
def test_bench_script_runs(capsys: pytest.CaptureFixture[str]) -> None:
    spec = importlib.util.spec_from_file_location(
        "bench_navigator", REPO_ROOT / "bench" / "bench_navigator.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rate = mod.main(["--duration-s", "5", "--python-steps", "200", "--repeats", "1"])
    lines = capsys.readouterr().out.strip().splitlines()
    assert rate > 0
    assert lines[-1] == f"navigator_steps_per_s: {rate:.0f} steps/s"
    assert any(line.startswith("numba cold JIT compile") for line in lines)
