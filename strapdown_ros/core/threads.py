"""Element-wise work on long arrays split over threads (same bits, less wall time).

numpy releases the GIL inside its ufunc loops, so an element-wise function of long arrays
(each output row depends only on the same input row) runs on two cores when the rows are cut in
two and the halves computed on two threads. The result is bit-identical to the single call:
nothing is summed across rows. Used where a user waits for one long array (the ``long double``
geodetic conversions of a samples trajectory: docs/benchmarks.md); the streaming generator's
pieces are shorter than :data:`MIN_ROWS` and stay on one thread, beside the bag writer.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import NDArray

__all__ = ["MIN_ROWS", "WORKERS", "rowwise"]

#: Rows below which one thread is used (the threads' start-up costs ~0.1 ms).
MIN_ROWS = 100_000
#: Threads used: at most two (the machines this runs on have two cores or more).
WORKERS = min(2, os.cpu_count() or 1)


def rowwise(
    fn: Callable[..., NDArray[np.float64]], *arrays: NDArray[np.generic]
) -> NDArray[np.float64]:
    """``fn(*arrays)`` for an element-wise ``fn`` of equally long 1-D or stacked arrays.

    ``fn`` must compute each output row from the same rows of the inputs only and return one
    array with the rows along axis 0. Below :data:`MIN_ROWS` rows, or with one core, this is
    ``fn(*arrays)`` itself.
    """
    n = len(arrays[0])
    if WORKERS < 2 or n < MIN_ROWS:
        return fn(*arrays)
    cuts = [n * k // WORKERS for k in range(WORKERS + 1)]
    parts = [tuple(a[lo:hi] for a in arrays) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]
    with ThreadPoolExecutor(WORKERS - 1) as pool:
        rest = [pool.submit(fn, *p) for p in parts[1:]]
        first = fn(*parts[0])
        return np.concatenate([first, *(f.result() for f in rest)])
