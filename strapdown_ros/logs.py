"""What the stages, nodes and commands say: the type of a log callback and the one that says
nothing.

A stage takes its ``info`` / ``warn`` / ``error`` callbacks from its caller (a node's logger,
the CLI's stderr, or :func:`quiet` offline and in tests), so the same object runs everywhere.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["Log", "quiet"]

#: A log callback: one message, no return value.
Log = Callable[[str], None]


def quiet(msg: str) -> None:
    """A :data:`Log` that drops the message (where nobody reads it)."""
