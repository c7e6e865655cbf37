"""Signals that stop a node: SIGINT, SIGTERM and SIGHUP all end it the same way.

rclpy handles SIGINT and SIGTERM (the context shuts down, the node's ``run`` returns, its
summary is logged); :func:`hangup_as_terminate` makes SIGHUP (a closed terminal, ``systemctl
reload``-style supervisors) do the same. :class:`SignalStop` is for the nodes that must finish
their work first (the recorder closes its bag, the player its reader).
"""

from __future__ import annotations

import os
import signal

__all__ = ["STOP_SIGNALS", "SignalStop", "hangup_as_terminate"]

#: The signals that stop a node (or a command) like Ctrl-C.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _forward_to_terminate(signum: int, frame: object) -> None:
    os.kill(os.getpid(), signal.SIGTERM)


def hangup_as_terminate() -> None:
    """SIGHUP handled as SIGTERM (by whatever handles SIGTERM: rclpy's or the node's own)."""
    signal.signal(signal.SIGHUP, _forward_to_terminate)


class SignalStop:
    """Mixin of nodes that finish their work on SIGINT/SIGTERM/SIGHUP (the recorder, the
    player).

    After :meth:`take_stop_signals` a signal only sets ``_stop_reason`` (rclpy's handlers would
    shut the context down at once), so the node still drains its queues and closes its bag; a
    second signal sets ``drain_timeout_s`` to 0 (stop draining).
    """

    _stop_reason: str | None
    drain_timeout_s: float

    def take_stop_signals(self) -> None:
        """Replace rclpy's SIGINT/SIGTERM handlers (and SIGHUP's) by :meth:`_on_signal`."""
        from rclpy.signals import uninstall_signal_handlers

        uninstall_signal_handlers()
        for signum in STOP_SIGNALS:
            signal.signal(signum, self._on_signal)

    def _on_signal(self, signum: int, frame: object) -> None:
        if self._stop_reason is None:
            self._stop_reason = signal.Signals(signum).name
        else:  # a second signal: stop draining
            self.drain_timeout_s = 0.0
