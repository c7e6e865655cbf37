"""The numba decorator of the aided filter's compiled code (optional numba, as in the core).

``jit`` is ``numba.njit(cache=True, nogil=True)`` when numba imports, else the identity: the
functions then run as plain Python (correct, slow) and the core still imports.

**The cache follows every source the code is compiled from.** Numba keys a cached function on
its own file only (modification time and size), but a compiled function contains the code of the
compiled functions it calls and the module constants it reads — here from several modules of
this package and from ``core/navigation/_kernels.py`` (the exact kernel), ``core/series.py``,
``core/earth.py``, ``core/aiding/baro.py`` and ``core/aiding/magnetometer.py``. An edit of one
of those would leave a stale loop in the cache. So the cache stamp of every function decorated
here also holds the stamps of all those files (:data:`DEPENDENCIES`): an edit of any of them
recompiles.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["DEPENDENCIES", "HAVE_NUMBA", "jit"]

_CORE = Path(__file__).resolve().parents[1]
#: The source files whose code or constants the compiled functions of this package contain.
DEPENDENCIES = tuple(sorted(
    [*(_CORE / "aided").glob("*.py"), _CORE / "navigation" / "_kernels.py", _CORE / "series.py",
     _CORE / "earth.py", _CORE / "aiding" / "baro.py", _CORE / "aiding" / "magnetometer.py"]
))  # fmt: skip


def _stamp() -> tuple:
    out = []
    for path in DEPENDENCIES:
        try:
            st = os.stat(path)
            out.append((path.name, st.st_mtime, st.st_size))
        except OSError:  # an installed copy without one of them: its absence is the stamp
            out.append((path.name, None, None))
    return tuple(out)


try:  # numba is optional: the ROS-free core must import without it.
    import numba
    from numba.core.caching import CompileResultCacheImpl, FunctionCache

    HAVE_NUMBA = True
    _DEPENDENCY_STAMP = _stamp()

    class _DependencyCacheImpl(CompileResultCacheImpl):
        """A cache implementation whose source stamp includes :data:`DEPENDENCIES`."""

        def __init__(self, py_func):
            super().__init__(py_func)
            own = self._locator.get_source_stamp
            self._locator.get_source_stamp = lambda: (own(), _DEPENDENCY_STAMP)

    class _DependencyFunctionCache(FunctionCache):
        _impl_class = _DependencyCacheImpl

    def jit(fn):
        """``numba.njit(cache=True, nogil=True)`` with the dependency-aware cache."""
        dispatcher = numba.njit(cache=True, nogil=True)(fn)
        try:
            dispatcher._cache = _DependencyFunctionCache(fn)
        except Exception:  # noqa: BLE001 - no usable cache location: compile in memory
            dispatcher._cache = numba.core.caching.NullCache()
        return dispatcher

except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None
    HAVE_NUMBA = False

    def jit(fn):
        """Identity decorator (numba absent)."""
        return fn
