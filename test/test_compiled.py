"""core/_compiled.py: the numba kernels give the numpy path's bits exactly (issue 18)."""

from __future__ import annotations

import numpy as np
import pytest

from strapdown_ros.core import _compiled
from strapdown_ros.core.gravity import gravitation
from strapdown_ros.core.method2 import method2, pair_displacement
from strapdown_ros.core.rotations import dcm_from_euler
from strapdown_ros.core.trajectory.giribet import DerivativeData, fit_spline

pytestmark = pytest.mark.skipif(not _compiled.HAVE_NUMBA, reason="numba not installed")


@pytest.fixture
def numpy_path(monkeypatch):
    """Run the block with the compiled kernels switched off (the numpy formulation)."""

    def run(fn):
        monkeypatch.setattr(_compiled, "HAVE_NUMBA", False)
        try:
            return fn()
        finally:
            monkeypatch.setattr(_compiled, "HAVE_NUMBA", True)

    return run


def _attitudes(n: int, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(n) * 0.01
    return dcm_from_euler(
        0.3 * np.sin(1.1 * t) + 1e-3 * rng.standard_normal(n),
        0.2 * np.cos(0.7 * t),
        2.0 * t + 0.1 * np.sin(3.0 * t),
    )


def test_matmul33_bits(numpy_path):
    rng = np.random.default_rng(7)
    a = rng.standard_normal((1001, 3, 3))
    b = rng.standard_normal((1001, 3, 3))
    assert np.array_equal(_compiled.matmul33(a, b), a @ b)
    assert np.array_equal(_compiled.matmul33(a, b, transpose_a=True), np.swapaxes(a, 1, 2) @ b)
    assert np.array_equal(_compiled.matmul33(a[0], b), a[0] @ b)
    assert np.array_equal(_compiled.matmul33(a, b[0]), a @ b[0])
    assert np.array_equal(numpy_path(lambda: _compiled.matmul33(a, b)), a @ b)


@pytest.mark.parametrize("cycles", [2, 3, 200, 201])
@pytest.mark.parametrize("with_displacement", [False, True])
def test_method2_compiled_equals_numpy(numpy_path, cycles, with_displacement):
    rng = np.random.default_rng(cycles)
    c = _attitudes(cycles + 1, rng)
    t = np.arange(cycles + 1) * 0.01
    v = np.stack([100.0 + 2.0 * np.sin(t), 5.0 * np.cos(t), 0.3 * t], axis=-1)
    r = np.array([4.0e6, 3.0e5, 4.9e6]) + np.cumsum(v, axis=0) * 0.01
    disp = pair_displacement(v, 0.01) if with_displacement else None

    def run():
        return method2(c, r, v, 0.01, lambda x: gravitation(x, "j2"), displacement=disp)

    fast, slow = run(), numpy_path(run)
    for name in ("dalpha", "dv", "v_e0", "r_e0", "g_e0"):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name


def test_fit_spline_compiled_equals_sparse(numpy_path):
    rng = np.random.default_rng(3)
    tau = np.sort(rng.uniform(0.0, 10.0, 400))
    tau[0], tau[-1] = 0.0, 10.0
    vals = np.stack([np.sin(tau), np.cos(2 * tau), tau**2], axis=-1)
    data = [
        DerivativeData(0, tau, vals, rng.uniform(0.5, 2.0, tau.size)),
        DerivativeData(1, tau, np.gradient(vals, tau, axis=0), np.full(tau.size, 0.3)),
    ]
    bp = np.linspace(0.0, 10.0, 21)

    def run():
        return fit_spline(bp, 5, 3, data).c

    assert np.array_equal(run(), numpy_path(run))
