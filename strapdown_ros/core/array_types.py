"""The array type aliases every module uses: float64 and int64 numpy arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["F64", "I64"]

#: A float64 array (any shape; the docstrings state shapes and units).
F64 = NDArray[np.float64]
#: An int64 array (stamps in ns, indices).
I64 = NDArray[np.int64]
