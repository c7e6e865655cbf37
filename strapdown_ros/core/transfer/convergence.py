"""Alignment time: when an error series enters a band and stays in it.

Used by the transfer-alignment campaign and the report (docs/transfer_alignment.md §6).
"""

from __future__ import annotations

import numpy as np

__all__ = ["alignment_time"]


def alignment_time(t: np.ndarray, error: np.ndarray, threshold: float) -> float:
    """First time after which ``|error|`` stays below ``threshold`` (NaN: never)."""
    bad = np.flatnonzero(np.abs(error) >= threshold)
    if not bad.size:
        return float(t[0])
    if bad[-1] == len(t) - 1:
        return float("nan")
    return float(t[bad[-1] + 1])
