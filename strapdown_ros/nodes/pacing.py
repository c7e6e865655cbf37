"""Publishing at the pace of the stamps: stamp ``t`` is due at ``start + (t - t0) / rate``."""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["Pacer"]


class Pacer:
    """Maps stamps to wall-clock deadlines: stamp ``t`` is due at ``start + (t - t0) / rate``.

    ``rate_factor <= 0`` means as fast as possible (everything is due at once). Waiting is done
    by a caller-supplied ``spin(timeout_s)`` (which keeps rclpy responsive) until the deadline is
    close, then by :func:`time.sleep` for the last stretch.
    """

    #: Below this many seconds before a deadline, stop spinning and sleep precisely.
    FINE_S = 0.002

    def __init__(self, rate_factor: float, t0_ns: int, start: float | None = None) -> None:
        self.rate_factor = rate_factor
        self.t0_ns = t0_ns
        self.start = time.monotonic() if start is None else start
        self.max_lateness_s = 0.0

    def due(self, stamp_ns: int) -> float:
        """Monotonic time at which ``stamp_ns`` is due."""
        if self.rate_factor <= 0:
            return self.start
        return self.start + (stamp_ns - self.t0_ns) * 1e-9 / self.rate_factor

    def wait(self, stamp_ns: int, spin: Callable[[float], None]) -> None:
        """Return when ``stamp_ns`` is due; record the lateness (paced mode only)."""
        if self.rate_factor <= 0:
            return
        deadline = self.due(stamp_ns)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= self.FINE_S:
                break
            spin(min(remaining - self.FINE_S, 0.1))
        while remaining > 0:
            time.sleep(remaining)
            remaining = deadline - time.monotonic()
        self.max_lateness_s = max(self.max_lateness_s, -remaining)
