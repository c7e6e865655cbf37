"""When the aided filter's inputs are due: sensor epochs, outages, latency (integer ns).

A sensor's epochs are the multiples of its period P on the absolute time axis at or after the
start (docs/aiding.md); a GNSS epoch inside an outage window ``[a, b)`` has no message; a message
is published (bag log time) at ``epoch + latency``. A stream is *settled* up to a time τ when
every message due at or before τ has arrived or is lost — lost once a later message of the same
topic has arrived (messages of one topic arrive in order). :meth:`Schedule.settled_until` gives
the latest such τ from the latest arrival seen.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Schedule", "count_in"]

NEVER = 2**62


@dataclass(frozen=True)
class Schedule:
    """Messages due at ``k P + latency`` for epochs ``k P >= start`` outside ``outages``.

    Attributes
    ----------
    period_ns : int
    start_ns : int
        First time an epoch may have (inclusive).
    latency_ns : int
        Arrival minus epoch.
    outages : tuple of (int, int)
        Epoch windows ``[a, b)`` without messages.
    end_ns : int
        Last epoch time that can have a message (``NEVER``: open-ended).
    """

    period_ns: int
    start_ns: int
    latency_ns: int = 0
    outages: tuple[tuple[int, int], ...] = ()
    end_ns: int = NEVER

    def _first_epoch_at_or_after(self, t: int) -> int:
        p = self.period_ns
        e = max(-(-t // p) * p, -(-self.start_ns // p) * p)
        moved = True
        while moved:
            moved = False
            for a, b in self.outages:
                if a <= e < b:
                    e = -(-b // p) * p
                    moved = True
        return e

    def next_arrival_after(self, t: int) -> int:
        """Arrival time of the first message due strictly after ``t`` (``NEVER``: none)."""
        e = self._first_epoch_at_or_after(t - self.latency_ns + 1)
        return NEVER if e > self.end_ns else e + self.latency_ns

    def settled_until(self, latest_arrival: int | None) -> int:
        """Latest τ up to which every due message has arrived or is lost."""
        base = self.start_ns - 1 if latest_arrival is None else latest_arrival
        nxt = self.next_arrival_after(base)
        return NEVER if nxt >= NEVER else max(base, nxt - 1)

    def is_epoch(self, t: int) -> bool:
        """Whether ``t`` is an epoch with a message (on the grid, after the start, no outage)."""
        if t % self.period_ns or t < self.start_ns or t > self.end_ns:
            return False
        return not any(a <= t < b for a, b in self.outages)

    def count(self, last_arrival_ns: int) -> int:
        """Messages with an arrival at or before ``last_arrival_ns``."""
        p = self.period_ns
        first = -(-self.start_ns // p)
        last = min(last_arrival_ns - self.latency_ns, self.end_ns) // p
        n = max(0, last - first + 1)
        for a, b in self.outages:
            lo = max(first, -(-a // p))
            hi = min(last, (b - 1) // p)
            n -= max(0, hi - lo + 1)
        return n


def count_in(start_ns: int, stop_ns: int, period_ns: int) -> int:
    """Multiples of ``period_ns`` in ``[start_ns, stop_ns]``."""
    if stop_ns < start_ns:
        return 0
    return stop_ns // period_ns - (-(-start_ns // period_ns)) + 1


