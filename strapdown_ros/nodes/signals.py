"""SIGINT/SIGTERM that let a node finish its work (drain its queues, close its bag)."""

from __future__ import annotations

import signal

__all__ = ["SignalStop"]


class SignalStop:
    """Mixin of nodes that finish their work on SIGINT/SIGTERM (the recorder, the player).

    After :meth:`take_stop_signals` a signal only sets ``_stop_reason`` (rclpy's handlers would
    shut the context down at once), so the node still drains its queues and closes its bag; a
    second signal sets ``drain_timeout_s`` to 0 (stop draining).
    """

    _stop_reason: str | None
    drain_timeout_s: float

    def take_stop_signals(self) -> None:
        """Replace rclpy's SIGINT/SIGTERM handlers by :meth:`_on_signal`."""
        from rclpy.signals import uninstall_signal_handlers

        uninstall_signal_handlers()
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)

    def _on_signal(self, signum: int, frame: object) -> None:
        if self._stop_reason is None:
            self._stop_reason = signal.Signals(signum).name
        else:  # a second signal: stop draining
            self.drain_timeout_s = 0.0
