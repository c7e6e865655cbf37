#!/usr/bin/env python3
"""Print ``name==version`` pins of every distribution installed in the running environment.

Used to regenerate ``requirements/constraints.txt`` (see docs/development.md)::

    rm -rf /tmp/lockvenv && python3.11 -m venv /tmp/lockvenv
    /tmp/lockvenv/bin/pip install -U pip setuptools
    /tmp/lockvenv/bin/pip install -r requirements/dev.txt      # no -c: let pip choose
    /tmp/lockvenv/bin/python tools/freeze_constraints.py

Unlike ``pip freeze`` it skips the ``*.egg-info`` metadata that the ROS wheels carry inside
them (``rclpy-7.1.5``, ``std_msgs-5.3.6``, ...): those are not PyPI distributions, and pinning
them would be misleading.  It also skips the project itself.
"""

from __future__ import annotations

import re
import sys
from importlib import metadata

SKIP = {"strapdown-ros"}


def canonical(name: str) -> str:
    """Return the PEP 503 normalized form of a distribution name."""
    return re.sub(r"[-_.]+", "-", name).lower()


def pins() -> list[str]:
    """Return the sorted pins of the real (``*.dist-info``) distributions installed."""
    found: dict[str, str] = {}
    for dist in metadata.distributions():
        path = getattr(dist, "_path", None)
        if path is not None and str(path).endswith(".egg-info"):
            continue
        name = dist.metadata["Name"]
        if not name or canonical(name) in SKIP:
            continue
        found[canonical(name)] = dist.version
    return [f"{name}=={version}" for name, version in sorted(found.items())]


def main() -> int:
    """Print the pins, one a line."""
    version = ".".join(map(str, sys.version_info[:3]))
    print(f"# pins resolved on CPython {version}")
    for line in pins():
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
