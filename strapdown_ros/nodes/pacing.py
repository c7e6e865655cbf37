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

    ``group_ns > 0`` releases the stamps in groups: stamp ``t`` waits for the end of its group,
    ``t0 + ceil((t - t0) / group_ns) * group_ns``, so a message is never published before its
    due time and at most ``group_ns`` of data time after it (one wake-up per group instead of
    one per message).
    """

    #: Below this many seconds before a deadline, stop spinning and sleep precisely.
    FINE_S = 0.002

    def __init__(
        self, rate_factor: float, t0_ns: int, start: float | None = None, group_ns: int = 0
    ) -> None:
        if group_ns < 0:
            raise ValueError(f"group_ns must be >= 0, got {group_ns}")
        self.rate_factor = rate_factor
        self.t0_ns = t0_ns
        self.group_ns = group_ns
        self.start = time.monotonic() if start is None else start
        self.max_lateness_s = 0.0

    def due(self, stamp_ns: int) -> float:
        """Monotonic time at which ``stamp_ns`` is due."""
        if self.rate_factor <= 0:
            return self.start
        return self.start + (stamp_ns - self.t0_ns) * 1e-9 / self.rate_factor

    def release(self, stamp_ns: int) -> float:
        """Monotonic time at which ``stamp_ns`` is published: the due time of its group's end."""
        g = self.group_ns
        if g <= 0:
            return self.due(stamp_ns)
        return self.due(self.t0_ns + -(-(stamp_ns - self.t0_ns) // g) * g)

    def wait(self, stamp_ns: int, spin: Callable[[float], None]) -> None:
        """Return when ``stamp_ns`` is released; record the lateness past the release time
        (paced mode only)."""
        if self.rate_factor <= 0:
            return
        deadline = self.release(stamp_ns)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= self.FINE_S:
                break
            spin(min(remaining - self.FINE_S, 0.1))
        while remaining > 0:
            time.sleep(remaining)
            remaining = deadline - time.monotonic()
        self.max_lateness_s = max(self.max_lateness_s, -remaining)
