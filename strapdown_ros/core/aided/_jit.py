"""The numba decorator of the aided filter's compiled code (optional numba, as in the core).

``jit`` is ``numba.njit(cache=True, nogil=True)`` when numba imports, else the identity: the
functions then run as plain Python (correct, slow) and the core still imports.
"""

from __future__ import annotations

try:  # numba is optional: the ROS-free core must import without it.
    import numba

    HAVE_NUMBA = True
    jit = numba.njit(cache=True, nogil=True)
except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None
    HAVE_NUMBA = False

    def jit(fn):
        """Identity decorator (numba absent)."""
        return fn


__all__ = ["HAVE_NUMBA", "jit"]
