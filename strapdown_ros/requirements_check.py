"""The runtime libraries, their oldest supported versions, and the check run at start-up.

:data:`MINIMUM` is the one table of the oldest version of each runtime library the package
supports; ``setup.py`` (``install_requires``, ``extras_require``) reads it, and
``make test-minimum`` installs exactly these versions (``requirements/minimum.txt``, checked
equal to this table by ``test/test_requirements.py``) on Python 3.12 and runs the fast tests.

:func:`check_versions` runs when ``strapdown-sim`` or a node starts: a library that is
installed but older than its minimum is reported with the pip command that fixes it (the
distribution's pydantic 1.10 on Ubuntu 24.04 is the usual case). A *missing* core library is
reported the same way; the optional ones (:data:`EXTRAS`: the campaign engine, the
magnetometer's IGRF model) are checked where they are used, by :func:`require`, which raises
:class:`MissingDependencyError` (an ImportError) naming the feature and the command.

Versions are read from the installed distributions' metadata (``importlib.metadata``), so the
check imports none of the libraries and costs a few milliseconds.
"""

from __future__ import annotations

import importlib
import re
import sys
from dataclasses import dataclass
from importlib import metadata
from types import ModuleType

__all__ = [
    "CORE",
    "EXTRAS",
    "MINIMUM",
    "MINIMUM_PYTHON",
    "MissingDependencyError",
    "Problem",
    "check_versions",
    "exit_if_unsupported",
    "require",
    "require_extra",
]

#: Oldest supported Python (what ``make test-minimum`` runs on is 3.12, Ubuntu 24.04's).
MINIMUM_PYTHON = (3, 11)

#: Distribution name → oldest supported version (why each: requirements/minimum.txt and
#: docs/install.md, "Supported versions"; measured by ``make test-minimum``).
MINIMUM: dict[str, str] = {
    "numpy": "1.26.0",
    "scipy": "1.11.2",
    "numba": "0.59.0",
    "PyYAML": "6.0.1",
    "matplotlib": "3.6.3",
    "pydantic": "2.11.5",
    "rosbags": "0.11.0",
    "mcap": "1.5.0",
    "dask": "2023.9.0",
    "distributed": "2023.9.0",
    "pyarrow": "14.0.0",
    "pyIGRF14": "1.0.3",
}

#: Libraries every command and node needs.
CORE = ("numpy", "scipy", "numba", "PyYAML", "matplotlib", "pydantic", "rosbags", "mcap")

#: Optional features: extra name (``pip install strapdown_ros[NAME]``) → (what it is for, its
#: distributions).
EXTRAS: dict[str, tuple[str, tuple[str, ...]]] = {
    "campaign": (
        "Monte Carlo campaigns (strapdown-sim campaign)",
        ("dask", "distributed", "pyarrow"),
    ),
    "magnetometer": ("the magnetometer's IGRF-14 field (aiding.magnetometer)", ("pyIGRF14",)),
}

#: Import name of each distribution whose import name differs.
_MODULE = {"PyYAML": "yaml"}

#: The file that installs every library at its supported version over a ROS 2 Jazzy system
#: install (README, "Using it on a real ROS 2 Jazzy install").
OVERLAY = "requirements/ros-overlay.txt"


def _version_tuple(text: str) -> tuple[int, ...]:
    """Leading numeric release of a version string: '1.26.4+ds' → (1, 26, 4); '2.0b3' → (2, 0)."""
    match = re.match(r"\d+(?:\.\d+)*", text.strip())
    return tuple(int(p) for p in match.group(0).split(".")) if match else ()


def _installed(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def pip_command(*dists: str) -> str:
    """``pip install 'a>=x' 'b>=y'`` for the named distributions, at their minimums."""
    return "pip install " + " ".join(f"'{d}>={MINIMUM[d]}'" for d in dists)


@dataclass(frozen=True)
class Problem:
    """A library that is missing or older than its minimum."""

    dist: str
    installed: str | None
    minimum: str

    def __str__(self) -> str:
        have = "not installed" if self.installed is None else f"{self.installed} is installed"
        return f"{self.dist} >= {self.minimum} is required ({have})"


def check_versions(dists: tuple[str, ...] = CORE) -> list[Problem]:
    """The libraries of ``dists`` that are missing or older than :data:`MINIMUM`."""
    problems = []
    for dist in dists:
        have = _installed(dist)
        if have is None or _version_tuple(have) < _version_tuple(MINIMUM[dist]):
            problems.append(Problem(dist, have, MINIMUM[dist]))
    return problems


def describe(problems: list[Problem], program: str) -> str:
    """The message of :func:`exit_if_unsupported`: each problem and the one command fixing all."""
    lines = [f"{program}: unsupported Python libraries:"]
    lines += [f"  {p}" for p in problems]
    lines.append("fix: " + pip_command(*(p.dist for p in problems)))
    lines.append(
        f"(on a ROS 2 Jazzy system install: in a venv over the system Python, "
        f"pip install -r {OVERLAY}; README, 'Using it on a real ROS 2 Jazzy install')"
    )
    return "\n".join(lines)


def exit_if_unsupported(program: str) -> None:
    """Exit with status 1 and :func:`describe`'s message if Python or a core library is too old.

    Called at the start of ``strapdown-sim`` and of every node (before rclpy is imported).
    """
    if sys.version_info[:2] < MINIMUM_PYTHON:
        need = ".".join(map(str, MINIMUM_PYTHON))
        print(f"{program}: Python >= {need} is required, this is {sys.version.split()[0]}",
              file=sys.stderr)  # fmt: skip
        raise SystemExit(1)
    problems = check_versions()
    if problems:
        print(describe(problems, program), file=sys.stderr)
        raise SystemExit(1)


class MissingDependencyError(ImportError):
    """An optional library (:data:`EXTRAS`) is missing or too old for the feature used."""


def require(module: str, extra: str) -> ModuleType:
    """Import ``module`` (a module of one of ``EXTRAS[extra]``'s distributions) or raise
    :class:`MissingDependencyError` naming the feature and the command that installs it."""
    what, dists = EXTRAS[extra]
    require_extra(extra)
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # metadata present, the import broken (a partial install)
        fix = f"reinstall it with: {pip_command(*dists)}"
        message = f"{what}: import {module} failed ({exc}); {fix}"
        raise MissingDependencyError(message, name=module) from exc


def require_extra(extra: str) -> None:
    """Raise :class:`MissingDependencyError` unless every library of ``EXTRAS[extra]`` is installed
    at its minimum (checked before a feature starts its work)."""
    what, dists = EXTRAS[extra]
    problems = check_versions(dists)
    if problems:
        raise MissingDependencyError(
            f"{what} needs " + ", ".join(str(p) for p in problems)
            + f"; install it with: {pip_command(*dists)}  (or pip install -r {OVERLAY})",
            name=dists[0],
        )


def import_name(dist: str) -> str:
    """The top-level module of a distribution of :data:`MINIMUM`."""
    return _MODULE.get(dist, dist)
