"""Loaded by every Dask worker process of an embedded cluster (``distributed.worker.preload``).

The worker processes share the terminal's process group with ``strapdown-sim campaign``, so
Ctrl-C reaches them too; they ignore it (no ``KeyboardInterrupt`` traceback from each of
them): the client, which gets it as well, cancels the runs and closes the cluster, which stops
them (docs/campaigns.md).
"""

from __future__ import annotations

import signal
import threading

__all__ = ["dask_setup", "ignore_terminal_interrupt"]


def ignore_terminal_interrupt() -> None:
    """SIGINT ignored in this process (only possible from the main thread)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


ignore_terminal_interrupt()  # at import: before the worker's first task


def dask_setup(worker: object) -> None:
    """Dask's preload hook (nothing more to do: the import did it)."""
    ignore_terminal_interrupt()
